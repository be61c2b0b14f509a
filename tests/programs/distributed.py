#!/usr/bin/env python3
"""Multi-process integration tests of the distributed services (ctest runs one case per test).

Every case runs real processes (godhand-launch and the services it starts, real Fast DDS
participants on the shipped loopback profile) in its own DDS domain, bounds every wait, and checks
that nothing is left behind: no process of its domain, no new shared-memory segment.

usage: distributed.py CASE BIN_DIR DEPLOY_DIR DOMAIN [args]
cases: same-hash RECORDING | same-hash-after-loss RECORDING | same-hash-under-packet-loss RECORDING | live RECORDING | kill SERVICE RECORDING | rejects | loopback RECORDING |
       drills RECORDING | freeze SERVICE RECORDING | freeze-restart SERVICE RECORDING | launcher-paused RECORDING |
       startup-remote |
       lockstep-fail RECORDING | ingest-hangs-at-exit RECORDING | two-labs RECORDING | profiles-qos | hand-kill SERVICE RECORDING
"""
import re
import signal
import contextlib
import json
import os
import queue
import shutil
import subprocess
import sys
import tempfile
import threading
import time

import leftovers  # (this directory)

CASE, BIN, DEPLOY, DOMAIN = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
ARGS = sys.argv[5:]
TMP = tempfile.mkdtemp(prefix="godhand-test-")
failures = []


def check(ok, what):
    print(("ok:     " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


def shm():
    return {n for n in os.listdir("/dev/shm") if "fastrtps" in n}


def run(cmd, timeout, **kw):
    print("$ " + " ".join(cmd), flush=True)
    return subprocess.run(cmd, timeout=timeout, capture_output=True, text=True, **kw)


def processes_of_domain():
    out = subprocess.run(["pgrep", "-af", "godhand-"], capture_output=True, text=True).stdout
    return [l for l in out.splitlines() if f"--domain {DOMAIN} " in l + " " and "distributed.py" not in l]


def launch(extra, timeout=240, env=None):
    report = os.path.join(TMP, "report.json")
    r = run([os.path.join(BIN, "godhand-launch"), "--domain", DOMAIN, "--json", report, "--log-dir",
             os.path.join(TMP, "logs"), "--quiet"] + extra, timeout, env=env)
    print(r.stdout)
    if r.returncode != 0:
        print(r.stderr)
        for f in sorted(os.listdir(os.path.join(TMP, "logs"))) if os.path.isdir(os.path.join(TMP, "logs")) else []:
            print(f"--- {f}\n" + open(os.path.join(TMP, "logs", f)).read()[-3000:])
    j = json.load(open(report)) if os.path.exists(report) else {}
    return r, j


def common_checks(j):
    check(j.get("shm_segments_left", -1) == 0, f"no shared-memory segment left behind ({j.get('shm_segments_left')})")
    check(j.get("clean_shutdown") is True, "every service exited cleanly on SIGTERM")
    lj = j.get("late_joiner", {})
    check(lj.get("hand_states") == j.get("hands") and lj.get("scene_description") is True,
          f"a late-joining subscriber got every cluster's HandState and the SceneDescription ({lj})")


def delivery_checks(j):
    """Delivery is counted per cluster; the counts add up and the summary's frames are counts."""
    d = j.get("delivery", {})
    check(len(d) == j.get("hands"), f"delivery counted for every cluster ({sorted(d)})")
    for name, c in d.items():
        check(c["fresh"] + c["stale"] + c["lost"] + c["unobserved"] == c["expected"] and c["expected"] > 0,
              f"{name}: expected {c['expected']} = fresh {c['fresh']} + stale {c['stale']} + lost {c['lost']} + not observed "
              f"{c['unobserved']}")
    if d:
        check(j.get("frames") == min(c["fresh"] for c in d.values()),
              f"'frames' is the count of frames delivered fresh in every cluster ({j.get('frames')})")


def case_same_hash(recording, env=None):
    bench_json = os.path.join(TMP, "bench.json")
    r = run([os.path.join(BIN, "godhand-bench"), "--recording", recording, "--quiet", "--json", bench_json], 300)
    check(r.returncode == 0, "godhand-bench ran")
    b = json.load(open(bench_json))
    t0 = time.monotonic()
    r, j = launch(["--lockstep", "--recording", recording, "--check"], env=env)
    print(f"[figure] lock-step run of {b['frames']} frames: {time.monotonic() - t0:.1f} s", flush=True)
    check(r.returncode == 0, "godhand-launch --lockstep --check exited 0")
    check(j.get("frames") == b["frames"], f"every frame came back ({j.get('frames')} of {b['frames']})")
    check(j.get("result_hash") == b["result_hash"],
          f"distributed result_hash {j.get('result_hash')} == in-process {b['result_hash']}")
    check(j.get("penetration_max_m", 1) == b["penetration_max_m"], "same penetration figure as in-process")
    check(j.get("clipped_steps") == b["clipped_steps"], f"same clipped steps ({j.get('clipped_steps')} vs {b['clipped_steps']})")
    for name, c in j.get("delivery", {}).items():
        check(c == {"expected": b["frames"], "fresh": b["frames"], "stale": 0, "lost": 0, "unobserved": 0},
              f"lock-step {name}: every frame delivered fresh ({c})")
    delivery_checks(j)
    common_checks(j)


def case_same_hash_after_loss(recording):
    """The right hand of a two-hand Leap recording is cut out of 30 frames (0.6 s): tracked again, it
    starts anew (PipelineParams::reacquire_after); the distributed lock-step run must make the same
    new start, with the jump swept by the resolver, and give the in-process hash."""
    rec = json.load(open(recording))
    cut = 0
    for f in rec["frames"][100:130]:
        right = {h["id"] for h in f.get("hands", []) if h.get("type") == "right"}
        cut += len(right)
        f["hands"] = [h for h in f.get("hands", []) if h["id"] not in right]
        f["pointables"] = [q for q in f.get("pointables", []) if q.get("handId") not in right]
    check(cut == 30, f"the right hand was cut out of 30 frames ({cut})")
    path = os.path.join(TMP, "lost-right.json")
    json.dump(rec, open(path, "w"))
    bench_json = os.path.join(TMP, "bench-loss.json")
    r = run([os.path.join(BIN, "godhand-bench"), "--recording", path, "--quiet", "--json", bench_json], 300)
    check(r.returncode == 0, "godhand-bench ran")
    check(json.load(open(bench_json)).get("reacquisitions", 0) >= 1, "the bench run started the right hand anew")
    case_same_hash(path)


def case_same_hash_under_packet_loss(recording):
    """Every process's UDP transport drops 10 % of the DATA messages it sends (Fast DDS's test
    transport, GODHAND_DDS_DROP_DATA_PERCENT; shared memory left out): Fast DDS repairs each loss
    (the profiles' 50 ms heartbeats), and the lock-step run gives the in-process hash, every frame
    delivered fresh, within its deadlines."""
    case_same_hash(recording, env=dict(os.environ, GODHAND_DDS_DROP_DATA_PERCENT="10"))


def case_lab_tracker(recording):
    """Lab.tracker calibrates the ingest: a lock-step run of a lab whose tracker sits elsewhere gives
    the in-process result_hash of godhand-bench --tracker-pose with that pose (and not the hash
    without it); a bad tracker field in the lab is a one-line start-up error naming it."""
    pose = "0.01,-0.02,0.03,0,0,20"
    def lab_with(tracker):
        text = open(os.path.join(DEPLOY, "lab", "local.pbtxt")).read().replace('"../', '"' + DEPLOY + "/")
        path = os.path.join(TMP, f"lab-{abs(hash(tracker))}.pbtxt")
        open(path, "w").write(text + "\ntracker { " + tracker + " }\n")
        return path
    hashes = {}
    for name, extra in (("calibrated", ["--tracker-pose", pose]), ("plain", [])):
        out = os.path.join(TMP, f"bench-{name}.json")
        r = run([os.path.join(BIN, "godhand-bench"), "--recording", recording, "--quiet", "--json", out] + extra, 300)
        check(r.returncode == 0, f"godhand-bench ({name}) ran")
        hashes[name] = json.load(open(out)).get("result_hash") if r.returncode == 0 else None
    check(hashes["calibrated"] != hashes["plain"], f"the tracker pose moves the hands ({hashes})")
    r, j = launch(["--lab", lab_with(f'pose: "{pose}"'), "--lockstep", "--recording", recording, "--check"])
    check(r.returncode == 0, "godhand-launch --lockstep with the lab's tracker exited 0")
    check(j.get("result_hash") == hashes["calibrated"],
          f"lab tracker pose: distributed result_hash {j.get('result_hash')} == godhand-bench --tracker-pose {hashes['calibrated']}")
    r, j = launch(["--lab", lab_with('pose: "1,2"'), "--lockstep", "--recording", recording])
    text = r.stdout + r.stderr
    check(r.returncode != 0 and "tracker:" in text and "result hash" not in text,
          f"a bad lab tracker pose fails the start-up, saying so (exit {r.returncode})")


def case_live(recording):
    # Loss budget 50 %: on a loaded 2-core CI machine the live pipeline was seen to lose 25 % of the
    # frames (the resolver resolves the newest); the counts themselves are checked below.
    r, j = launch(["--recording", recording, "--check", "--loss-budget", "0.5"])
    check(r.returncode == 0, "godhand-launch (live) --check exited 0")
    s = j.get("services", {})
    for name in ["ingest", "scene", "resolver"] + [k for k in s if k.startswith("solver/")]:
        check(s.get(name, {}).get("samples_in", 0) > 0 or name == "ingest" and s.get(name, {}).get("samples_out", 0) > 0,
              f"{name} received samples ({s.get(name)})")
    check(len([k for k in s if k.startswith("solver/")]) == j.get("hands"), "one solver per cluster reported")
    lat = j.get("latency_us", {})
    check(lat.get("samples", 0) > 0 and lat.get("median", 0) > 0,
          f"end-to-end latency measured: median {lat.get('median', 0):.0f} us, p99 {lat.get('p99', 0):.0f} us over {lat.get('samples')} states")
    check(j.get("penetration_max_m", 1) <= j.get("margin_m", 0),
          f"nothing penetrates ({j.get('penetration_max_m')} m; deepest state {j.get('penetration_worst')})")
    check(j.get("joint_gap_max_m", 1) <= 1e-6, f"every hand state a closed hand (joint gap max {j.get('joint_gap_max_m')} m)")
    check(j.get("contacts_max", 0) > 0, f"contacts counted live ({j.get('contacts_max')})")
    check(j.get("check", {}).get("ok") is True and j.get("dead_at_end") == [], f"check passed, nothing dead ({j.get('check')})")
    delivery_checks(j)
    common_checks(j)


def launch_bg(extra):
    """Starts godhand-launch (per-second lines on) and returns (process, report path). A thread
    reads its output line by line into p.lines (None at the end), so that every wait below has a
    deadline of its own, even when the launcher goes silent."""
    report = os.path.join(TMP, "report.json")
    cmd = [os.path.join(BIN, "godhand-launch"), "--domain", DOMAIN, "--json", report, "--log-dir",
           os.path.join(TMP, "logs")] + extra
    print("$ " + " ".join(cmd), flush=True)
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    p.lines = queue.Queue()

    def pump():
        for l in p.stdout:
            p.lines.put(l)
        p.lines.put(None)

    threading.Thread(target=pump, daemon=True).start()
    return p, report


@contextlib.contextmanager
def killed_on_error(p):
    """A launcher driven by the block is killed (and reaped) if the block raises: none is left
    running behind a failed step."""
    try:
        yield
    except Exception:
        p.kill()
        p.wait(10)
        raise


def next_line(p, timeout):
    """p's next output line, or None at its end or after timeout seconds."""
    try:
        return p.lines.get(timeout=max(0.0, timeout))
    except queue.Empty:
        return None


def rest_of(p, timeout):
    """The rest of p's output once it ends (within timeout, else it is killed)."""
    try:
        p.wait(timeout)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait(10)
    out = []
    while True:
        l = next_line(p, 10)
        if l is None:
            break
        out.append(l)
    return "".join(out)


def wait_line(p, pattern, timeout, lines):
    deadline = time.time() + timeout
    while time.time() < deadline:
        l = next_line(p, deadline - time.time())
        if not l:
            return None
        lines.append(l)
        print(l, end="")
        if re.search(pattern, l):
            return l
    return None


def pid_of(service):
    """pid of the domain's process of a service ("resolver", "solver/right", ...)."""
    prog, _, cluster = service.partition("/")
    for l in processes_of_domain():
        if f"godhand-{prog} " in l + " " and (not cluster or f"--cluster {cluster} " in l + " "):
            return int(l.split()[0])
    return None


def case_freeze(service, recording, restart):
    """SIGSTOP a service for 2 s (or for good, with --restart): the watchdog must see it silent,
    the live lines must not show it running meanwhile, the states it lets out late are stale, the
    frames lost are counted, and --check fails on them (without --restart). Without --restart the
    freeze lasts until a per-second line has followed the watchdog's (at most 8 s): a fixed 2 s
    left a window shorter than a line's period once the watchdog fired late on a busy machine
    (CI: silent at 2.97 s, resumed at 3.89 s, lines at 2.9 and 3.9 s)."""
    extra = ["--recording", recording, "--speed", "0.5"] + (["--restart"] if restart else ["--check"])
    p, report = launch_bg(extra)
    lines = []
    with killed_on_error(p):
        ok = wait_line(p, r"launch: t +[1-9]\.\d s \|.*resolver \d+ Hz running", 120, lines)
        check(ok is not None, "the replay is running")
        pid = pid_of(service)
        check(pid is not None, f"{service} found ({pid})")
        frozen = []  # live lines printed once the watchdog's limit (1.2 s) has passed in the freeze
        if pid:
            os.kill(pid, signal.SIGSTOP)
            t0 = time.time()
            limit = 6.0 if restart else 8.0
            watchdog_seen = line_after_watchdog = False
            try:
                while time.time() - t0 < limit:
                    if not restart and time.time() - t0 >= 2.0 and line_after_watchdog:
                        break
                    l = next_line(p, t0 + limit - time.time())
                    if not l:
                        break
                    lines.append(l)
                    print(l, end="")
                    if time.time() - t0 > 1.4 and l.startswith("launch: t "):
                        frozen.append(l)
                    if watchdog_seen and l.startswith("launch: t "):
                        line_after_watchdog = True
                    if f"watchdog: {service} silent" in l:
                        watchdog_seen = True
                    if restart and f"{service} restarted" in l:
                        break
            finally:
                # Never left stopped (a stopped process keeps its segments and ignores SIGTERM);
                # with --restart the watchdog killed it already.
                try:
                    os.kill(pid, signal.SIGCONT)
                except ProcessLookupError:
                    pass
            if restart:
                check(any(f"{service} restarted" in l for l in lines), f"{service} restarted by the watchdog")
        out = rest_of(p, 240)
    print(out)
    lines += out.splitlines(True)
    j = json.load(open(report)) if os.path.exists(report) else {}
    text = "".join(lines)
    prog = service.replace("/", r"\/")
    check(re.search(rf"watchdog: {service} silent", text) is not None, f"the launcher reported {service} silent")
    eps = [e for e in j.get("watchdog", {}).get("silent", []) if e["service"] == service]
    check(len(eps) >= 1, f"a watchdog episode of {service} ({eps})")
    dead_lines = [l for l in lines if l.startswith("launch: t ") and (f"{service} DEAD" in l or f"{service} DOWN" in l)]
    if not restart:  # with --restart it may be killed and back between two per-second lines
        check(len(dead_lines) >= 1, f"live lines showed {service} DEAD or DOWN ({len(dead_lines)} lines)")
        check(not [l for l in frozen if re.search(rf"{prog} \d+ Hz running", l)],
              f"no live line past the watchdog's limit in the freeze showed {service} running ({len(frozen)} lines)")
        if service == "resolver":
            # The scene steps on its own clock and publishes a state every step, forces or not: its
            # figure is the states it published (it showed the forces it took: 0 Hz).
            scene_rates = [int(m.group(1)) for l in frozen for m in [re.search(r"scene (\d+) states/s", l)] if m]
            check(scene_rates and max(scene_rates) > 0,
                  f"live lines in the freeze showed the scene's states per second, not the forces it took ({scene_rates})")
    # A stale state's age is not a latency: every state in the latency figures was fresh, i.e. at
    # most the stale limit old (the freeze's late states had made the p99 of their second).
    lat, stale_age = j.get("latency_us", {}), j.get("stale_state_age_us", {})
    print(f"latency_us {lat}, stale_state_age_us {stale_age}, stale_states {j.get('stale_states')}", flush=True)
    check(j.get("stale_after_s") is not None and lat.get("samples", 0) > 0 and lat.get("max", 1e12) <= j["stale_after_s"] * 1e6,
          f"latency max {lat.get('max')} us <= the stale limit {j.get('stale_after_s')} s: stale states are not in it")
    check(stale_age.get("samples", 0) <= j.get("stale_states", 0) and (j.get("stale_states", 0) == 0 or stale_age.get("samples", 0) > 0),
          f"the stale states' ages reported apart ({stale_age.get('samples')} of {j.get('stale_states')} stale states)")
    check(j.get("old_unmarked_states", 1) == 0, f"no state older than the stale limit arrived unmarked ({j.get('old_unmarked_states')})")
    d = j.get("delivery", {})
    lost = sum(c["lost"] + c["stale"] for c in d.values())
    check(lost > 0, f"the frames missed while {service} was frozen are counted (lost + stale {lost}: {d})")
    delivery_checks(j)
    if restart:
        check(service in j.get("watchdog", {}).get("restarted", []), f"{service} restarted by the watchdog ({j.get('watchdog')})")
        check(j.get("dead_at_end") == [], f"nothing dead at the end ({j.get('dead_at_end')})")
        check(p.returncode == 0, f"exit 0 ({p.returncode})")
    else:
        budget_fail = [r for r in j.get("check", {}).get("reasons", []) if "frames lost" in r]
        check(p.returncode == 1 and j.get("check", {}).get("ok") is False and budget_fail,
              f"--check failed (exit {p.returncode}) on the lost frames: {j.get('check')}")
        check("result_hash" not in j, "no result hash from a failed run")
    common_checks(j)


def case_launcher_paused(recording):
    """SIGSTOP the launcher itself for 2.5 s with --restart (a starved launcher, a stalled
    machine): its watchdog must not take its own pause for five silent services (seen in a soak:
    all five healthy services killed and restarted). The pause is said and reported, nothing is
    restarted, the run ends cleanly."""
    p, report = launch_bg(["--recording", recording, "--speed", "0.5", "--restart"])
    lines = []
    with killed_on_error(p):
        ok = wait_line(p, r"launch: t +[1-9]\.\d s \|.*resolver \d+ Hz running", 120, lines)
        check(ok is not None, "the replay is running")
        os.kill(p.pid, signal.SIGSTOP)
        try:
            time.sleep(2.5)
        finally:
            os.kill(p.pid, signal.SIGCONT)
        out = rest_of(p, 240)
    print(out)
    text = "".join(lines) + out
    j = json.load(open(report)) if os.path.exists(report) else {}
    check(re.search(r"launch: this launcher did not watch for [2-9]\.\d s", text) is not None, "the launcher said it was paused")
    pauses = j.get("watchdog", {}).get("launcher_pauses", [])
    check(any(q["duration_s"] >= 2.0 for q in pauses), f"the pause is in the report ({pauses})")
    check("killing it for a restart" not in text and j.get("watchdog", {}).get("restarted") == [],
          f"no service killed for the launcher's own pause ({j.get('watchdog', {}).get('restarted')})")
    check(j.get("dead_at_end") == [], f"nothing dead at the end ({j.get('dead_at_end')})")
    # The frames published during the pause (2.5 s at 24 Hz) were superseded in the launcher's own
    # keep-newest readers: not observed, not lost (they were counted lost).
    for name, c in j.get("delivery", {}).items():
        check(c.get("unobserved", 0) >= 20 and c.get("lost", 0) < c.get("unobserved", 0),
              f"{name}: frames of the pause not observed, not lost ({c})")
    check(p.returncode == 0, f"exit 0 ({p.returncode})")
    common_checks(j)
    # The same pause while the resolver is killed in it: the frames of the pause were published by
    # nobody. They are lost, not "not observed" (seen in a soak: 57 such frames a hand excused).
    p, report = launch_bg(["--recording", recording, "--speed", "0.5", "--restart"])
    lines = []
    with killed_on_error(p):
        ok = wait_line(p, r"launch: t +[1-9]\.\d s \|.*resolver \d+ Hz running", 120, lines)
        check(ok is not None, "the replay is running (second run)")
        resolver = pid_of("resolver")
        os.kill(p.pid, signal.SIGSTOP)
        try:
            time.sleep(0.5)
            if resolver:
                os.kill(resolver, signal.SIGKILL)
            time.sleep(2.0)
        finally:
            os.kill(p.pid, signal.SIGCONT)
        out = rest_of(p, 240)
    print(out)
    j = json.load(open(report)) if os.path.exists(report) else {}
    check(resolver is not None and "resolver restarted" in out, f"the resolver killed in the pause was restarted ({resolver})")
    for name, c in j.get("delivery", {}).items():
        check(c.get("unobserved", -1) == 0 and c.get("lost", 0) >= 20,
              f"{name}: the frames of a pause in which the resolver died are lost, not 'not observed' ({c})")
    common_checks(j)


def case_drills(recording):
    """Several drills in one run, every kind of service, timed from the replay (frames and seconds)."""
    r, j = launch(["--recording", recording, "--kill", "ingest@f40", "--kill", "resolver@1s", "--kill", "scene@2.5s",
                   "--kill", "solver/left@f100", "--restart-delay", "0.3"])
    check(r.returncode == 0, f"godhand-launch with four drills exited 0 ({r.returncode})")
    ds = {d["service"]: d for d in j.get("fault_drills", [])}
    check(sorted(ds) == ["ingest", "resolver", "scene", "solver/left"], f"every drill reported ({sorted(ds)})")
    for name, d in ds.items():
        check(d["killed_s"] is not None and d["restarted_s"] is not None and d["restarted_s"] > d["killed_s"],
              f"{name}: killed at {d['killed_s']} s, restarted at {d['restarted_s']} s (from the replay start)")
    check(ds.get("ingest", {}).get("killed_frame", 0) >= 40, f"ingest killed at frame >= 40 ({ds.get('ingest')})")
    # Each restart's own recovery (the solver's, with about 1.5 s of replay left, is reported but not
    # asserted here: distributed_restarted_solver_recovers_before_the_replay_ends does that).
    rs = {x["service"]: x for x in j.get("restarts", [])}
    for name in ("ingest", "resolver", "scene"):
        x = rs.get(name, {})
        check(x.get("recovery_s") is not None and x.get("up_s") is not None,
              f"{name}: every hand fresh again {x.get('recovery_s')} s after its restart (first heartbeat at {x.get('up_s')} s)")
    check(rs.get("scene", {}).get("scene_back_s") is not None, f"the restarted scene's first state seen ({rs.get('scene')})")
    check(ds.get("resolver", {}).get("killed_s") is not None and ds["resolver"]["killed_s"] >= 1.0, "resolver killed >= 1 s into the replay")
    check(j.get("ingest_runs") == 2, f"the restarted ingest replayed again: 2 ingest runs ({j.get('ingest_runs')})")
    # The source's counts are summed over the ingest runs: the restarted run played the whole
    # recording, the killed one adds what its last heartbeat had counted (0 when it had sent none).
    # The killed run's unplayed rest is not received: it is not played (it was counted received,
    # neither accepted nor rejected).
    src = j.get("source") or {}
    print("report source block:", src, flush=True)
    m = re.search(r"source \S+ \((\d+) frames at", r.stdout)
    n = int(m.group(1)) if m else None
    check(n is not None and src.get("ingest_runs") in (1, 2) and src.get("accepted", 0) >= n,
          f"source counts summed over the ingest runs: accepted {src.get('accepted')} >= the restarted run's {n} ({src})")
    check(src.get("received") is not None and src.get("received") == src.get("accepted", -1) + src.get("rejected_total", -1),
          f"received {src.get('received')} == accepted {src.get('accepted')} + rejected {src.get('rejected_total')}")
    check(n is not None and src.get("received", 0) + src.get("not_played_total", 0) == src.get("ingest_runs", 0) * n,
          f"each run's recording received or not played: {src.get('received')} + {src.get('not_played_total')} == "
          f"{src.get('ingest_runs')} x {n}")
    if src.get("ingest_runs") == 2:
        check("over 2 ingest runs (summed)" in r.stdout, "the summary says the source counts are summed over 2 ingest runs")
        killed = (src.get("not_played") or {}).get("by the run's last heartbeat, no final count (killed, or still running)", 0)
        check(n is not None and 0 < killed < n and killed == src.get("not_played_total"),
              f"the killed run's rest of the {n} frames is not played, saying why ({src.get('not_played')})")
        check(re.search(r"^  source: received \d+, accepted \d+, rejected \d+ \(none\); not played \d+ \(", r.stdout, re.M)
              is not None, "the summary's source line says what was not played")
    # The restarted scene said it was starting before its resume wait (a scene killed in that wait
    # had left no line at all).
    scene_log = open(os.path.join(TMP, "logs", "scene.log"), errors="replace").read() if os.path.exists(
        os.path.join(TMP, "logs", "scene.log")) else ""
    check(re.search(r"scene: resuming: waiting up to [\d.]+ s .*\n(.*\n)*scene: (not )?resumed", scene_log) is not None,
          "the restarted scene's log: its start and resume-wait lines before the wait's outcome")
    # (A time, "-1.00 s"; not a figure: an excess lag median of -1.00 mm is a measurement.)
    check(re.search(r"-1\.00 s\b", r.stdout) is None, "no unset time printed as -1.00 s")
    check(j.get("shm_segments_left", -1) == 0 and j.get("shm_segments_removed", 0) >= 1,
          f"the killed processes' segments were removed by the launcher ({j.get('shm_segments_removed')}), none left")
    delivery_checks(j)
    common_checks(j)


def case_restart_recovers(recording):
    """A solver killed with 4.6 s of the replay left (half speed) and restarted 0.3 s later: its
    hand is fresh again before the replay ends, in each of two runs. With Fast DDS's default
    participant announcements (every 3 s) the restarted solver's endpoints were often matched
    only after the replay had ended (8 of 10 runs; in 5 it received no HandTarget at all), which
    the report showed as one "resumed" time of the first restart and nothing else. At full speed
    (2.3 s left) the test failed once in CI (2026-12-07, run serially, on a shared machine): the
    restarted solver received no HandTarget before the replay ended. Reproduced with the
    distributed tests running beside it on 2 cores: the restarted solver's own start-up (loading
    the scene, building its BVH) took 0.6-2.4 s to its first heartbeat (14 runs; 0.4-0.7 s on a
    quiet machine) and in 3 of 14 it came after the replay's end, while the hand was fresh again
    0.00-0.51 s after that heartbeat in every run."""
    for attempt in (1, 2):
        r, j = launch(["--recording", recording, "--speed", "0.5", "--kill", "solver/left@f60", "--restart-delay", "0.3"])
        check(r.returncode == 0, f"run {attempt}: godhand-launch with the fault drill exited 0 ({r.returncode})")
        rs = [x for x in j.get("restarts", []) if x.get("service") == "solver/left"]
        check(len(rs) == 1, f"run {attempt}: one restart of solver/left reported ({j.get('restarts')})")
        x = rs[0] if rs else {}
        check(x.get("recovery_s") is not None,
              f"run {attempt}: every hand fresh again {x.get('recovery_s')} s after the restart (first heartbeat "
              f"{x.get('up_s')} s, restarted {x.get('restarted_s')} s, {x.get('stale_states')} stale states meanwhile)")
        check(j.get("restarts_unrecovered") == 0, f"run {attempt}: no restart left unrecovered ({j.get('restarts_unrecovered')})")
        common_checks(j)


def case_hand_kill(service, recording):
    """kill -9 of a service by hand (not by the launcher) under --restart: restarted, and the
    segments the dead process left in /dev/shm removed by its own launcher, by name."""
    p, report = launch_bg(["--recording", recording, "--speed", "0.5", "--restart", "--quiet"])
    with killed_on_error(p):
        deadline = time.time() + 120
        pid = None
        while time.time() < deadline and pid is None:
            time.sleep(0.2)
            pid = pid_of(service) if any("--source" in l for l in processes_of_domain()) else None  # the ingest runs
        check(pid is not None, f"{service} found ({pid})")
        time.sleep(1.0)
        if pid:
            os.kill(pid, signal.SIGKILL)
        out = rest_of(p, 240)
    print(out)
    j = json.load(open(report)) if os.path.exists(report) else {}
    check(p.returncode == 0 and f"{service} restarted" in out, f"{service} restarted after a kill -9 by hand (exit {p.returncode})")
    check(j.get("shm_segments_removed", 0) >= 1 and j.get("shm_segments_left", -1) == 0,
          f"its segments removed by the launcher ({j.get('shm_segments_removed')}), none left ({j.get('shm_segments_left')})")
    delivery_checks(j)


def case_startup_remote():
    """A lab whose services all run on another host: start-up fails with exit 3 and names them."""
    text = open(os.path.join(DEPLOY, "lab", "local.pbtxt")).read()
    lab_dir = os.path.abspath(os.path.join(DEPLOY, "lab"))
    lines = []
    for l in text.splitlines():
        st = l.strip()
        if st.startswith("host:"):
            l = '  host: "lab-pc-remote"'
        for key in ("scene:", "recording:", "model:", "profiles:"):
            if st.startswith(key) and '"' in st:
                path = st.split('"')[1]
                l = l.replace(path, os.path.normpath(os.path.join(lab_dir, path)))
        lines.append(l)
    lab = os.path.join(TMP, "remote.pbtxt")
    open(lab, "w").write("\n".join(lines) + "\n")
    r = run([os.path.join(BIN, "godhand-launch"), "--lab", lab, "--domain", DOMAIN, "--start-timeout", "2", "--quiet"], 60)
    print(r.stdout, r.stderr)
    check(r.returncode == 3, f"start-up failure exits 3 ({r.returncode})")
    for name in ["scene", "resolver", "solver/right", "solver/left"]:
        check(f"{name} (on lab-pc-remote" in r.stderr, f"the failure names {name} and its host")
    check("another host" in r.stderr, "says every service runs on another host")


def case_lockstep_fail(recording):
    """A lock-step run that fails writes and prints no hash. The failure: a 1 us input deadline,
    which no stage can meet once it waits for another process (the ingest gives up at frame 2)."""
    r, j = launch(["--lockstep", "--recording", recording, "--deadline", "0.000001", "--check"])
    check(r.returncode == 1, f"the failed lock-step run exits 1 ({r.returncode})")
    check("result_hash" not in j and "result hash" not in r.stdout, "no result hash printed or written")
    check(bool(j.get("failure")), f"the failure is reported ({j.get('failure', '')[:100]})")
    check(j.get("check", {}).get("ok") is False, f"--check failed ({j.get('check')})")


def case_duration(recording):
    """--duration stops the ingest before the end of a recording on purpose: the frames expected are
    those it published (none lost, --check ok), the rest is reported as not played by that reason;
    lock-step waits for those frames only. Before: every frame never played counted lost and
    --check failed (live 192 of 307; lock-step 169 of 171, and a 5 s wait for frames that never
    came)."""
    # Long enough that a lock-step run (as fast as the machine goes: 171 frames took under 0.5 s in
    # CI) is cut: the recording forwards, backwards, ... (timestamps and ids going on), ~1,700 frames.
    d = json.load(open(recording))
    frames = d["frames"]
    dt = (frames[-1]["timestamp"] - frames[0]["timestamp"]) / max(1, len(frames) - 1)
    looped, t, fid = [], frames[0]["timestamp"], frames[0]["id"]
    for lap in range(10):
        for f in (frames if lap % 2 == 0 else frames[::-1]):
            g = dict(f)
            g["timestamp"], g["id"] = int(t), fid
            looped.append(g)
            t += dt
            fid += 1
    d["frames"] = looped
    if "metadata" in d and isinstance(d["metadata"], dict):
        d["metadata"]["frames"] = len(looped)
    recording = os.path.join(TMP, "looped.json")
    json.dump(d, open(recording, "w"))
    n = len(looped)
    for mode in (["--speed", "1"], ["--lockstep"]):
        r, j = launch(mode + ["--recording", recording, "--duration", "0.5", "--check"])
        d = j.get("delivery", {})
        src = j.get("source", {})
        print(f"{mode}: delivery {d}, source {src}", flush=True)
        expected = [c.get("expected", 0) for c in d.values()]
        check(r.returncode == 0 and j.get("check", {}).get("ok") is True, f"{mode}: --check ok ({j.get('check')})")
        check(expected and all(0 < e < n for e in expected),
              f"{mode}: expected the frames published, fewer than the recording's {n} ({expected})")
        check(all(c.get("lost", 1) == 0 for c in d.values()), f"{mode}: none lost ({d})")
        np = src.get("not_played", {})
        check(any(k.startswith("--duration") for k in np) and src.get("accepted", 0) + src.get("not_played_total", 0) == n,
              f"{mode}: the rest not played, by --duration ({np})")


def case_ingest_hangs_at_exit(recording):
    """An ingest that finishes its run (its last heartbeat says "stopping") but never exits
    (GODHAND_FAULT_HANG_AFTER_FINISH=ingest): the launcher kills it 10 s later and fails the run,
    naming it, instead of waiting for it for good (seen once in a secured multi-host run)."""
    t0 = time.monotonic()
    r, j = launch(["--lockstep", "--recording", recording, "--check"], timeout=120,
                  env=dict(os.environ, GODHAND_FAULT_HANG_AFTER_FINISH="ingest"))
    took = time.monotonic() - t0
    print(f"[figure] the launcher gave up on the hung ingest after {took:.1f} s", flush=True)
    check(r.returncode == 1, f"the run fails ({r.returncode})")
    check("had not exited 10 s later" in j.get("failure", ""), f"the failure names the hang ({j.get('failure', '')[:120]})")
    check("result_hash" not in j and "result hash" not in r.stdout, "no result hash printed or written")
    check(took < 60, f"the launcher ended within a minute ({took:.1f} s)")
    # Where it hung, printed before the kill: the fault's endless sleep in Service::finish.
    check("the ingest's threads" in r.stdout, "the launcher prints the hung ingest's threads")
    if shutil.which("gdb") and "ptrace:" not in r.stdout:
        check("Service::finish" in r.stdout, "its backtrace shows the hang in Service::finish (gdb)")


def case_two_labs(recording):
    """Two launches on one DDS domain at the same time. With a partition each, each counts only its
    own states (one ingest run, the recording's frames) and sees no other lab; without, each says
    that another lab shares the domain and --check fails."""
    n = None
    for partitioned in (True, False):
        procs = []
        for tag in ("a", "b"):
            report = os.path.join(TMP, f"two-{tag}-{partitioned}.json")
            cmd = [os.path.join(BIN, "godhand-launch"), "--domain", DOMAIN, "--recording", recording, "--quiet", "--check",
                   "--loss-budget", "0.5", "--json", report, "--log-dir", os.path.join(TMP, f"logs-{tag}")]
            if partitioned:
                cmd += ["--partition", f"lab-{tag}"]
            print("$ " + " ".join(cmd), flush=True)
            procs.append((tag, subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True), report))
        for tag, p, report in procs:
            try:
                out, _ = p.communicate(timeout=240)
            except subprocess.TimeoutExpired:
                p.kill()
                out, _ = p.communicate()
            print(out)
            j = json.load(open(report)) if os.path.exists(report) else {}
            d = j.get("delivery", {})
            what = "partitioned" if partitioned else "same partition"
            if partitioned:
                check(p.returncode == 0 and j.get("foreign_services") == [], f"{what} {tag}: exit 0, no other lab seen ({p.returncode}, {j.get('foreign_services')})")
                check(j.get("ingest_runs") == 1, f"{what} {tag}: only its own ingest's run counted ({j.get('ingest_runs')})")
                check(d and all(c["expected"] == d[next(iter(d))]["expected"] for c in d.values()), f"{what} {tag}: delivery {d}")
                n = n or (d and next(iter(d.values()))["expected"])
                check(d and all(c["expected"] == n for c in d.values()), f"{what} {tag}: the recording's {n} frames expected, not twice")
                check(j.get("hand_states", 10**9) <= 1.5 * n * j.get("hands", 0), f"{what} {tag}: {j.get('hand_states')} hand states, its own only")
                delivery_checks(j)
            else:
                check(len(j.get("foreign_services", [])) >= 1 and "another lab on domain" in out,
                      f"{what} {tag}: said another lab shares the domain ({j.get('foreign_services')})")
                check(p.returncode == 1 and any("another lab" in r for r in j.get("check", {}).get("reasons", [])),
                      f"{what} {tag}: --check failed on it (exit {p.returncode})")


def case_profiles_qos():
    """Liveliness on every stream and a deadline on every live writer, from the shipped profiles,
    with values under which each profile's writer and reader match (writer lease <= reader lease;
    a reader deadline, if any, >= the writer's). The runs of the other cases use these profiles."""
    import xml.etree.ElementTree as ET
    ns = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    root = ET.parse(os.path.join(DEPLOY, "dds", "godhand-local.xml")).getroot()

    def seconds(e):
        return float(e.findtext("f:sec", "0", ns)) + float(e.findtext("f:nanosec", "0", ns)) * 1e-9 if e is not None else None

    profiles = {}
    for kind in ("data_writer", "data_reader"):
        for e in root.findall(f"f:{kind}", ns):
            name = e.get("profile_name")
            q = e.find("f:qos", ns)
            lv = q.find("f:liveliness", ns)
            profiles[(kind, name)] = {
                "liveliness": lv.findtext("f:kind", None, ns) if lv is not None else None,
                "lease": seconds(lv.find("f:lease_duration", ns)) if lv is not None else None,
                "deadline": seconds(q.find("f:deadline/f:period", ns))}
    names = {n for _, n in profiles}
    check(len(names) >= 4, f"profiles found ({sorted(names)})")
    for n in sorted(names):
        w, r = profiles.get(("data_writer", n)), profiles.get(("data_reader", n))
        check(w and r, f"{n}: writer and reader profiles")
        if not (w and r):
            continue
        check(w["liveliness"] == "AUTOMATIC" and r["liveliness"] == "AUTOMATIC", f"{n}: AUTOMATIC liveliness on both")
        check(w["lease"] and r["lease"] and w["lease"] <= r["lease"] <= 2.0, f"{n}: leases {w['lease']} <= {r['lease']} <= 2 s")
        if n != "godhand.lockstep":
            check(w["deadline"] is not None and 0 < w["deadline"] <= 2.0, f"{n}: writer deadline {w['deadline']} s")
        check(r["deadline"] is None or (w["deadline"] is not None and r["deadline"] >= w["deadline"]),
              f"{n}: reader deadline {r['deadline']} compatible with the writer's {w['deadline']}")
    # Every shipped file is well-formed XML (tinyxml2, Fast DDS's parser, accepts a double hyphen
    # in a comment; strict parsers, e.g. a lab's configuration tools, do not).
    for f in sorted(os.listdir(os.path.join(DEPLOY, "dds"))):
        if f.endswith(".xml"):
            try:
                ET.parse(os.path.join(DEPLOY, "dds", f))
                check(True, f"{f}: well-formed XML")
            except ET.ParseError as e:
                check(False, f"{f}: well-formed XML ({e})")
    # Reliable writers heartbeat within 0.1 s in every shipped file: a lost DATA waits for the next
    # heartbeat (Fast DDS's default 3 s stalled lock-step 3-6 s per loss, services/dds/README.md).
    for f in ("godhand-local.xml", "godhand-multihost.xml", "godhand-multihost-ds.xml"):
        for e in ET.parse(os.path.join(DEPLOY, "dds", f)).getroot().findall("f:data_writer", ns):
            if e.findtext("f:qos/f:reliability/f:kind", None, ns) != "RELIABLE":
                continue
            hb = seconds(e.find("f:times/f:heartbeatPeriod", ns))
            check(hb is not None and 0 < hb <= 0.1, f"{f} {e.get('profile_name')}: heartbeat period {hb} s (<= 0.1 s)")


@contextlib.contextmanager
def foreign_segment():
    """Another program's unheld segment appears in /dev/shm during a launch (a parallel lab's killed
    process), once the launcher has started its services (after it listed what was there before:
    their logs exist then). Yields a dict whose "planted" says it was there; removed at the end.
    Used by a RUN_SERIAL test only: a parallel test would count it as its own leftover."""
    fake = f"/dev/shm/fastrtps_godhandtest_{os.getpid()}_{DOMAIN}"
    state = {"planted": False}
    stop = threading.Event()

    def plant():
        deadline = time.time() + 120
        while not stop.is_set() and time.time() < deadline:
            if os.path.exists(os.path.join(TMP, "logs", "resolver.log")):
                for path in (fake, fake + "_el"):
                    with open(path, "wb") as f:
                        f.write(b"\0" * 64)
                state["planted"] = True
                return
            time.sleep(0.05)
    t = threading.Thread(target=plant, daemon=True)
    t.start()
    try:
        yield state
    finally:
        stop.set()
        t.join(5)
        for path in (fake, fake + "_el"):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)


def case_kill(service, recording):
    # Half speed: the replay (7 s) outlasts a restart on a loaded machine (a scene was seen taking
    # 3.5 s to come back with a load average of 10 on 2 cores).
    with foreign_segment() as seg:
        r, j = launch(["--recording", recording, "--speed", "0.5", "--kill", service + "@1.5", "--restart-delay", "0.5"])
    # Another program's unheld segment that appeared during the run is not this lab's: reported
    # apart and not removed (it used to count as this lab's).
    check(seg["planted"] and j.get("shm_segments_left") == 0 and j.get("shm_segments_left_other", 0) >= 1,
          f"another program's segment not counted as this lab's: planted {seg['planted']}, left {j.get('shm_segments_left')}, "
          f"others' {j.get('shm_segments_left_other')}")
    check(r.returncode == 0, "godhand-launch with the fault drill exited 0")
    d = {k: (-1 if v is None else v) for k, v in j.get("fault_drill", {}).items()}
    check(d.get("killed_s", -1) >= 1.5 and d.get("restarted_s", -1) > d.get("killed_s", 0),
          f"{service} killed 1.5 s after the replay started, then restarted ({d})")
    check(j.get("stale_states", 0) > 0, f"hands were marked stale while {service} was gone ({j.get('stale_states')})")
    check(d.get("resumed_s", -1) > d.get("restarted_s", 0),
          f"fresh states again after the restart: {d.get('resume_after_restart_s', -1):.2f} s after it")
    delivery_checks(j)
    check(j.get("penetration_max_m", 1) <= j.get("margin_m", 0),
          f"penetration-free against the last scene throughout ({j.get('penetration_max_m')} m; deepest state {j.get('penetration_worst')})")
    check(j.get("joint_gap_max_m", 1) <= 1e-6, f"every hand state a closed hand (joint gap max {j.get('joint_gap_max_m')} m)")
    if service == "scene":
        log = os.path.join(TMP, "logs", "scene.log")
        text = open(log).read() if os.path.exists(log) else ""
        m = re.search(r"resumed (\d+) dynamic object pose\(s\) from the held scene state \(step (\d+)", text)
        check(m is not None and int(m.group(1)) > 0 and int(m.group(2)) > 0,
              "the restarted scene resumed its objects from the scene state the resolver held (a step of the dead scene, "
              f"not the scene file): {m.group(0) if m else [l for l in text.splitlines() if 'resume' in l]}")
        # Reported, not asserted: objects at rest in the dead scene's last state and in the new
        # one's first state seen were found up to 9 mm apart (the hands act on them meanwhile), and
        # in this scene resting objects mostly lie at their scene-file poses, so a jump back to the
        # file would not be told apart from that here.
        print(f"note: largest move of an object at rest across the restart: {d.get('scene_restart_jump_m')} m")
        check(j.get("penetration_unscored_states", 0) > 0, "penetration not scored against the dead scene's poses")
    common_checks(j)


def case_rejects():
    lab = os.path.join(DEPLOY, "lab", "local.pbtxt")
    bad_profile = os.path.join(TMP, "bad.xml")
    open(bad_profile, "w").write("<profiles><participant profile_name=")
    cases = [
        (["godhand-solver", "--lab", lab, "--cluster", "thumb"], "no such cluster"),
        (["godhand-solver", "--lab", lab], "--cluster NAME is required"),
        (["godhand-solver", "--lab", "/nonexistent/lab.pbtxt", "--cluster", "right"], "/nonexistent/lab.pbtxt"),
        (["godhand-scene", "--lab", lab, "--domain", "999"], "--domain"),
        (["godhand-scene", "--lab", lab, "--frame-rate", "abc"], "--frame-rate"),
        (["godhand-scene", "--lab", lab, "--scene", "/nonexistent/scene.pbtxt"], "/nonexistent/scene.pbtxt"),
        (["godhand-resolver", "--lab", lab, "--profiles", bad_profile], "bad.xml"),
        (["godhand-resolver", "--lab", lab, "--profiles", "/nonexistent/p.xml"], "/nonexistent/p.xml"),
        (["godhand-ingest", "--lab", lab, "--source", "dtrack:5000"], "5000"),
        (["godhand-ingest", "--lab", lab, "--source", "/nonexistent/rec.json"], "/nonexistent/rec.json"),
        (["godhand-launch", "--lab", lab, "--kill", "scene"], "--kill"),
        (["godhand-launch", "--lab", lab, "--kill", "@2"], "--kill '@2'"),
        (["godhand-launch", "--lab", lab, "--kill", "scene@"], "--kill 'scene@'"),
        (["godhand-launch", "--lab", lab, "--kill", "scene@2", "--kill", "bogus@1"], "no service 'bogus'"),
        (["godhand-launch", "--lab", lab, "--kill", "scene@f0"], "--kill 'scene@f0'"),
        (["godhand-launch", "--lab", os.path.join(TMP, "missing.pbtxt")], "missing.pbtxt"),
        (["godhand-launch", "--lab", lab, "--bogus"], "--bogus"),
    ]
    for cmd, expect in cases:
        r = run([os.path.join(BIN, cmd[0])] + cmd[1:] + ["--domain", DOMAIN] * ("--domain" not in cmd), 60)
        lines = [l for l in r.stderr.splitlines() if l.strip() and not l.startswith("try ")]
        check(r.returncode == 2 and len(lines) == 1 and expect in lines[0],
              f"{cmd[0]} {' '.join(cmd[1:])}: exit {r.returncode}, one line naming '{expect}': {lines}")
    for prog in ["godhand-ingest", "godhand-solver", "godhand-scene", "godhand-resolver", "godhand-launch"]:
        r = run([os.path.join(BIN, prog), "--help"], 30)
        check(r.returncode == 0 and "usage" in r.stdout.lower() and "--lab" in r.stdout, f"{prog} --help")


def case_loopback(recording):
    """The shipped profile sends nothing off loopback: run the live demo inside a fresh network
    namespace with a second interface (veth, with an address and a multicast route) and read its
    transmit counter. The positive control runs the same with a profile that uses Fast DDS's
    built-in transports (multicast discovery on every interface): the counter must move."""
    if not shutil.which("unshare") or not shutil.which("ip"):
        print("SKIP: needs unshare and ip (iproute2)")
        sys.exit(77)
    probe = subprocess.run(["unshare", "-rn", "sh", "-c", "ip link add v0 type veth peer name v1"], capture_output=True)
    if probe.returncode != 0:
        print("SKIP: cannot create a network namespace with a veth pair here: " + probe.stderr.decode().strip())
        sys.exit(77)
    # The control profile: the shipped one with its participant replaced by one that uses Fast
    # DDS's built-in transports (the topic profiles stay, so every entity is created as usual).
    import re
    shipped_xml = open(os.path.join(DEPLOY, "dds", "godhand-local.xml")).read()
    builtin = os.path.join(TMP, "builtin.xml")
    control_xml, n = re.subn(r"<participant\b.*?</participant>",
                             '<participant profile_name="godhand_participant" is_default_profile="true">'
                             "<rtps><useBuiltinTransports>true</useBuiltinTransports></rtps></participant>",
                             shipped_xml, count=1, flags=re.S)
    check(n == 1, "control profile derived from the shipped one")
    open(builtin, "w").write(control_xml)
    # The control lab: the shipped one with the built-in-transports profile.
    text = open(os.path.join(DEPLOY, "lab", "local.pbtxt")).read()
    lab_dir = os.path.join(DEPLOY, "lab")
    control = os.path.join(TMP, "control.pbtxt")
    lines = []
    for l in text.splitlines():
        s = l.strip()
        if s.startswith("profiles:"):
            l = f'profiles: "{builtin}"'
        for key in ("scene:", "recording:", "model:"):
            if s.startswith(key) and '"' in s:
                path = s.split('"')[1]
                l = l.replace(path, os.path.normpath(os.path.join(lab_dir, path)))
        lines.append(l)
    open(control, "w").write("\n".join(lines) + "\n")

    def in_netns(lab):
        script = f"""
set -e
ip link set lo up
ip link add v0 type veth peer name v1
# No IPv6 on the test link: its autoconfiguration traffic (DAD, router solicitations, MLD) would
# show in the counter without any DDS involved.
sysctl -qw net.ipv6.conf.v0.disable_ipv6=1 net.ipv6.conf.v1.disable_ipv6=1 2>/dev/null || echo 1 > /proc/sys/net/ipv6/conf/v0/disable_ipv6
ip addr add 10.77.0.1/24 dev v0
ip link set v1 up
ip link set v0 up multicast on
ip route add 224.0.0.0/4 dev v0
tx() {{ sed 's/:/ /' /proc/net/dev | awk '$1 == "v0" {{ print $11 }}'; }}
before=$(tx)
'{BIN}/godhand-launch' --lab '{lab}' --domain {DOMAIN} --recording '{recording}' --frames 60 --quiet --log-dir '{TMP}/ns-logs' >'{TMP}/ns.out' 2>&1 || {{ cat '{TMP}/ns.out'; exit 1; }}
after=$(tx)
echo "tx_packets $before $after"
"""
        r = run(["unshare", "-rn", "bash", "-c", script], 240)
        print(r.stdout[-2000:], r.stderr[-2000:])
        for l in r.stdout.splitlines():
            if l.startswith("tx_packets"):
                _, a, b = l.split()
                return int(b) - int(a)
        return None

    shipped = in_netns(os.path.join(DEPLOY, "lab", "local.pbtxt"))
    check(shipped == 0, f"shipped profile: the demo sent {shipped} packets on the non-loopback interface (expect 0)")
    leaked = in_netns(control)
    check(leaked is not None and leaked > 0,
          f"control (built-in transports): {leaked} packets on the non-loopback interface (expect > 0: the counter sees DDS traffic)")


shm_before = shm()
try:
    if CASE == "same-hash":
        case_same_hash(ARGS[0])
    elif CASE == "same-hash-after-loss":
        case_same_hash_after_loss(ARGS[0])
    elif CASE == "duration":
        case_duration(ARGS[0])
    elif CASE == "ingest-hangs-at-exit":
        case_ingest_hangs_at_exit(ARGS[0])
    elif CASE == "same-hash-under-packet-loss":
        case_same_hash_under_packet_loss(ARGS[0])
    elif CASE == "live":
        case_live(ARGS[0])
    elif CASE == "kill":
        case_kill(ARGS[0], ARGS[1])
    elif CASE == "rejects":
        case_rejects()
    elif CASE == "loopback":
        case_loopback(ARGS[0])
    elif CASE == "drills":
        case_drills(ARGS[0])
    elif CASE == "freeze":
        case_freeze(ARGS[0], ARGS[1], False)
    elif CASE == "freeze-restart":
        case_freeze(ARGS[0], ARGS[1], True)
    elif CASE == "launcher-paused":
        case_launcher_paused(ARGS[0])
    elif CASE == "startup-remote":
        case_startup_remote()
    elif CASE == "profiles-qos":
        case_profiles_qos()
    elif CASE == "restart-recovers":
        case_restart_recovers(ARGS[0])
    elif CASE == "hand-kill":
        case_hand_kill(ARGS[0], ARGS[1])
    elif CASE == "two-labs":
        case_two_labs(ARGS[0])
    elif CASE == "lab-tracker":
        case_lab_tracker(ARGS[0])
    elif CASE == "lockstep-fail":
        case_lockstep_fail(ARGS[0])
    else:
        print(f"unknown case {CASE}")
        sys.exit(2)
finally:
    deadline = time.time() + 5
    while processes_of_domain() and time.time() < deadline:
        time.sleep(0.1)
    left = processes_of_domain()
    check(not left, f"no process of domain {DOMAIN} left ({left})")
    leftovers.kill_domain(DOMAIN, "distributed.py")
    # Entries new since the start that nobody holds (parallel tests hold theirs).
    orphans = leftovers.orphaned_since(shm_before)
    check(not orphans, f"no shared-memory entry left behind ({orphans})")
    shutil.rmtree(TMP, ignore_errors=True)

print("PASSED" if not failures else f"{len(failures)} check(s) FAILED")
sys.exit(0 if not failures else 1)
