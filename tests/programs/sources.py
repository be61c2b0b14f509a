#!/usr/bin/env python3
"""Multi-process tests of the tracker sources (bridges/, godhand-ingest --source).

usage: sources.py CASE BIN_DIR DEPLOY_DIR DOMAIN [args]
cases:
  live-dtrack DTRACK_FILE SENDER   godhand-launch with the ingest on dtrack://127.0.0.1:PORT, fed
                                   over UDP loopback by SENDER (dtrack-send.py) with every fault;
                                   --check passes (no penetration, frames not lost), the ingest's
                                   rejection counts equal the sender's fault counts, --record's file
                                   replays in lock-step to the same accepted frames; the report's
                                   `source` block equals the ingest's counts
  record-replay DTRACK_FILE SENDER godhand-ingest --record alone, its raw file replayed twice in
                                   lock-step: the live counts again (report `source`), the same
                                   result hash twice and equal to godhand-bench --recording's
  rejects                          godhand-ingest's bad configurations: one line, exit 2
  formats DATA_DIR                 lock-step runs through the lab with --check of a .dtrack file, the
                                   Aria CSV sample, OpenXR and MediaPipe JSON Lines and a synthetic
                                   script (detected by content)
  tool-openxr LAB                  a tool cluster driven by an OpenXR 6-DOF body (JSON Lines), lock-step and live
  tool LAB DTRACK_FILE SENDER      a tool cluster driven by a DTrack 6d body (tracker_body) beside a
                                   right hand: in lock-step from the file and live over UDP with
                                   every fault; the tool is tracked, follows its body exactly when
                                   free (a rigid model: no model error), penetration-free

Every wait has a deadline; nothing is left behind (no process of the domain, no shared-memory
segment of the run). Only loopback traffic: the sender refuses any other address.
"""
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time

import leftovers  # (this directory)

CASE, BIN, DEPLOY, DOMAIN = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
ARGS = sys.argv[5:]
TMP = tempfile.mkdtemp(prefix="godhand-sources-test-")
failures = []
# Live HandStates travel best-effort: on a loaded 2-core CI machine a few percent of the frames
# may miss the launcher's subscriber (that is the DDS layer's figure, not the source's). What this
# test asserts about the source is exact: every fault counted, every clean datagram accepted.
LOSS = 0.25


def check(ok, what):
    print(("ok:     " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


def shm():
    return {n for n in os.listdir("/dev/shm") if "fastrtps" in n}


def free_udp_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def processes_of_domain():
    out = subprocess.run(["pgrep", "-af", "godhand-"], capture_output=True, text=True).stdout
    return [l for l in out.splitlines() if f"--domain {DOMAIN} " in l + " " and "sources.py" not in l]


def ingest_source_line(log):
    m = re.search(r"ingest: source (\S+): received (\d+), accepted (\d+), rejected (\d+) \((.*)\), superseded", log)
    if not m:
        return None
    reasons = {}
    if m.group(5) != "none":
        for part in m.group(5).split(", "):
            name, n = part.rsplit(" ", 1)
            reasons[name] = int(n)
    return dict(received=int(m.group(2)), accepted=int(m.group(3)), rejected=int(m.group(4)), reasons=reasons)


def source_block_equals(src, st):
    """The report's `source` block equals the ingest's printed counts (ingest_source_line)."""
    return (src.get("received") == st["received"] and src.get("accepted") == st["accepted"]
            and src.get("rejected") == st["reasons"] and src.get("rejected_total") == st["rejected"])


def run_launch(cmd, timeout, logs):
    """godhand-launch to its end, or, past `timeout` s, stopped by SIGTERM (it stops its services)
    and reported with the tail of every service's log, so that a hung run says where it hung."""
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = p.communicate(timeout=timeout)
        return subprocess.CompletedProcess(cmd, p.returncode, out, err)
    except subprocess.TimeoutExpired:
        p.terminate()
        try:
            out, err = p.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            out, err = p.communicate()
        print(f"TIMEOUT: godhand-launch still running after {timeout} s, stopped with SIGTERM; its services' logs:", flush=True)
        for name in sorted(os.listdir(logs)) if os.path.isdir(logs) else []:
            lines = open(os.path.join(logs, name), errors="replace").read().splitlines()
            print(f"--- {name} (last 25 of {len(lines)} lines)\n" + "\n".join(lines[-25:]), flush=True)
        return subprocess.CompletedProcess(cmd, 124, out, err)


def live_with_faults(launch_args, dtrack_file, sender, seed, duration, report, logs, send_log):
    """godhand-launch on dtrack://127.0.0.1:PORT (launch_args added) fed by SENDER with every fault
    once the ingest is past its start barrier (it prints "receiving"); returns (exit code, output)."""
    port = free_udp_port()
    cmd = [os.path.join(BIN, "godhand-launch")] + launch_args + ["--domain", DOMAIN, "--source", f"dtrack://127.0.0.1:{port}",
           "--duration", str(duration), "--json", report, "--log-dir", logs, "--quiet", "--check", "--loss-budget", str(LOSS)]
    print("$ " + " ".join(cmd), flush=True)
    launch = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out = ""
    try:
        ingest_log = os.path.join(logs, "ingest.log")
        deadline = time.time() + 60
        while time.time() < deadline and launch.poll() is None:
            if os.path.exists(ingest_log) and "receiving" in open(ingest_log, errors="replace").read():
                break
            time.sleep(0.1)
        check(launch.poll() is None, "the launcher and its services came up")
        s = subprocess.run([sys.executable, sender, dtrack_file, "--port", str(port), "--seed", str(seed), "--drop", "0.05",
                            "--garbage", "0.05", "--truncate", "0.05", "--nan", "0.05", "--huge", "0.05", "--reorder", "0.05",
                            "--log", send_log], capture_output=True, text=True, timeout=60)
        print(s.stdout + s.stderr, flush=True)
        check(s.returncode == 0, "dtrack-send ran")
        out, _ = launch.communicate(timeout=120)
    finally:
        if launch.poll() is None:
            launch.kill()
            launch.wait()
    print(out, flush=True)
    return launch.returncode, out


def case_live_dtrack(dtrack_file, sender):
    logs = os.path.join(TMP, "logs")
    report = os.path.join(TMP, "live.json")
    send_log = os.path.join(TMP, "send.jsonl")
    code, launch_out = live_with_faults([], dtrack_file, sender, 11, 9, report, logs, send_log)
    check(code == 0, f"godhand-launch --check exited 0 (was {code})")
    j = json.load(open(report)) if os.path.exists(report) else {}
    check(j.get("penetration_max_m", 1) <= j.get("margin_m", 0), f"penetration-free ({j.get('penetration_max_m')} m)")
    check(j.get("shm_segments_left", -1) == 0, "no shared-memory segment left behind")
    check(j.get("clean_shutdown") is True, "every service exited cleanly")
    check(sorted(j.get("delivery", {})) == ["left", "right"], "both clusters reported")
    for name, d in j.get("delivery", {}).items():
        check(d.get("expected", 0) > 50 and d.get("lost", 1) <= d["expected"] * LOSS, f"cluster {name}: frames lost within {LOSS:.0%} ({d})")
    actions = [json.loads(l)["action"] for l in open(send_log)]
    n = {a: actions.count(a) for a in ("send", "drop", "garbage", "truncate", "nan", "huge", "reorder")}
    print("sender actions:", n, flush=True)
    check(all(n[a] > 0 for a in n), "every fault happened at least once")
    log = open(os.path.join(logs, "ingest.log"), errors="replace").read()
    st = ingest_source_line(log)
    check(st is not None, "the ingest printed its source counts")
    if st:
        r = st["reasons"]
        print("ingest source counts:", st, flush=True)
        check(st["received"] == len(actions) - n["drop"], f"received {st['received']} == datagrams sent {len(actions) - n['drop']}")
        check(r.get("parse error", 0) == n["garbage"], f"garbage {n['garbage']} counted as parse errors ({r.get('parse error', 0)})")
        check(r.get("NaN/Inf", 0) == n["nan"], f"nan {n['nan']} counted ({r.get('NaN/Inf', 0)})")
        check(r.get("oversized", 0) == n["huge"], f"huge {n['huge']} counted as oversized ({r.get('oversized', 0)})")
        check(r.get("incomplete (truncated)", 0) == n["truncate"], f"truncate {n['truncate']} counted ({r.get('incomplete (truncated)', 0)})")
        stale = r.get("stale/duplicate frame", 0)
        check(1 <= stale <= n["reorder"], f"reordered {n['reorder']}: {stale} arrived stale, counted")
        check(st["accepted"] + stale == n["send"] + n["reorder"],
              f"every clean datagram accepted: accepted {st['accepted']} + stale {stale} == clean {n['send']} + reordered {n['reorder']}")
        check(st["accepted"] + st["rejected"] == st["received"], "accepted + rejected == received")
        # The launch report's `source` block (the ingest's heartbeats over DDS): the same counts.
        src = j.get("source") or {}
        print("report source block:", src, flush=True)
        check(source_block_equals(src, st), f"report source == the ingest's counts ({src} vs {st})")
        check(src.get("rejected", {}).get("parse error") == n["garbage"] and src.get("rejected", {}).get("NaN/Inf") == n["nan"]
              and src.get("rejected", {}).get("oversized") == n["huge"]
              and src.get("rejected", {}).get("incomplete (truncated)") == n["truncate"],
              "report source: every fault of the sender counted by reason")
        check(src.get("ingest_runs") == 1, "report source: one ingest run")
    check("silent for" in log, "the silence after the stream ended was reported")
    check(re.search(r"^  source: received \d+, accepted \d+, rejected \d+ \(.*parse error \d+", launch_out, re.M) is not None,
          "the launch summary prints the source line")


def case_record_replay(dtrack_file, sender):
    """godhand-ingest --record alone (no other service: live mode starts without them), then the
    raw file replayed in lock-step through the whole lab."""
    port = free_udp_port()
    raw = os.path.join(TMP, "live.raw")
    cmd = [os.path.join(BIN, "godhand-ingest"), "--domain", DOMAIN, "--source", f"dtrack://127.0.0.1:{port}", "--duration", "6",
           "--record", raw, "--start-timeout", "0.5"]
    print("$ " + " ".join(cmd), flush=True)
    ing = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(1.5)
        s = subprocess.run([sys.executable, sender, dtrack_file, "--port", str(port), "--seed", "5", "--speed", "2",
                            "--garbage", "0.1", "--nan", "0.1", "--reorder", "0.1"], capture_output=True, text=True, timeout=60)
        print(s.stdout + s.stderr, flush=True)
        _, err = ing.communicate(timeout=60)
    finally:
        if ing.poll() is None:
            ing.kill()
            ing.wait()
    print(err[-3000:], flush=True)
    check(ing.returncode == 0, f"godhand-ingest --record exited 0 ({ing.returncode})")
    st = ingest_source_line(err)
    check(st is not None and st["received"] > 0, "datagrams came in")
    m = re.search(r"recorded (\d+) datagrams", err)
    check(m is not None and st is not None and int(m.group(1)) == st["received"], "every received datagram was recorded")
    hashes = []
    for i in (1, 2):  # two lock-step replays of the same file: the same hands, bit for bit
        report = os.path.join(TMP, f"replay{i}.json")
        r = subprocess.run([os.path.join(BIN, "godhand-launch"), "--domain", DOMAIN, "--lockstep", "--recording", raw, "--check",
                            "--quiet", "--json", report], capture_output=True, text=True, timeout=200)
        print(r.stdout[-2500:] + r.stderr[-1500:], flush=True)
        check(r.returncode == 0, f"replay {i}: the raw recording replays in lock-step through the lab with --check")
        j = json.load(open(report)) if os.path.exists(report) else {}
        check(st is not None and j.get("frames") == st["accepted"], f"replay {i}: frames {j.get('frames')} == live accepted {st and st['accepted']}")
        check(j.get("shm_segments_left", -1) == 0, f"replay {i}: no shared-memory segment left behind")
        # The replay's source sees the datagrams in their recorded order: the live run's counts again.
        src = j.get("source") or {}
        check(st is not None and source_block_equals(src, st), f"replay {i}: report source {src} == the live ingest's counts {st}")
        check(st is not None and j.get("services", {}).get("ingest", {}).get("rejected") == st["rejected"],
              f"replay {i}: services.ingest.rejected {j.get('services', {}).get('ingest', {}).get('rejected')} == {st and st['rejected']}")
        check(re.search(r"^  source: received \d+, accepted \d+, rejected \d+ ", r.stdout, re.M) is not None,
              f"replay {i}: the summary prints the source line")
        hashes.append(j.get("result_hash"))
    bench_json = os.path.join(TMP, "replay-bench.json")
    b = subprocess.run([os.path.join(BIN, "godhand-bench"), "--recording", raw, "--quiet", "--json", bench_json],
                       capture_output=True, text=True, timeout=200)
    print(b.stdout[-1000:] + b.stderr[-1000:], flush=True)
    h = json.load(open(bench_json)).get("result_hash") if b.returncode == 0 and os.path.exists(bench_json) else None
    print("result hashes: replays", hashes, "godhand-bench", h, flush=True)
    check(hashes[0] is not None and hashes[0] == hashes[1], f"two lock-step replays: the same result hash ({hashes})")
    check(h is not None and hashes[0] == h, f"lock-step replay result hash {hashes[0]} == godhand-bench --recording's {h}")


def case_rejects():
    ingest = os.path.join(BIN, "godhand-ingest")
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    busy_port = busy.getsockname()[1]
    junk = os.path.join(TMP, "junk.txt")
    open(junk, "w").write("hello\n")
    rec = os.path.join(DEPLOY, "recordings", "pinch.json")
    cases = [
        (["--source", "dtrack://localhost:5000"], "IPv4"),
        (["--source", "dtrack://127.0.0.1:0"], "port"),
        (["--source", f"dtrack://127.0.0.1:{busy_port}"], "cannot bind"),
        (["--source", "dtrack://127.0.0.1:5000", "--lockstep"], "needs a recording"),
        (["--source", rec, "--record", os.path.join(TMP, "x.raw")], "needs a live source"),
        (["--source", junk], "unknown recording format"),
        (["--source", rec, "--tracker-units", "inch"], "units"),
        (["--source", rec, "--tracker-pose", "1,2"], "pose"),
        (["--source", rec, "--hand-map", "0:middle"], "hand map"),
        (["--source", rec, "--duration", "-1"], "--duration"),
    ]
    for extra, want in cases:
        r = subprocess.run([ingest, "--domain", DOMAIN] + extra, capture_output=True, text=True, timeout=30)
        # One line (and the usual "try --help" hint), exit 2.
        lines = [l for l in r.stderr.splitlines() if l.strip() and not l.startswith("try ")]
        first = lines[0] if lines else ""
        check(r.returncode == 2 and len(lines) == 1 and want in first,
              f"{' '.join(extra)}: exit {r.returncode}, one line naming '{want}': {lines}")
    busy.close()
    r = subprocess.run([ingest, "--help"], capture_output=True, text=True, timeout=30)
    check(r.returncode == 0 and "dtrack://" in r.stdout and "--duration" in r.stdout, "--help documents the sources")


def case_formats(data):
    cases = [(os.path.join(data, "dtrack", "pinch.dtrack"), None, 307),
             (os.path.join(data, "aria", "pinch_head_v2.csv"), None, 8),
             (os.path.join(data, "skeleton", "pinch_openxr.jsonl"), None, 80),
             (os.path.join(data, "skeleton", "pinch_mediapipe.jsonl"), None, 80),
             (os.path.join(data, "synthetic", "press_slide_lift.txt"), os.path.join(data, "synthetic", "table.pbtxt"), 340)]
    for rec, scene, frames in cases:
        report = os.path.join(TMP, "fmt.json")
        cmd = [os.path.join(BIN, "godhand-launch"), "--domain", DOMAIN, "--lockstep", "--recording", rec, "--check", "--quiet",
               "--json", report] + (["--scene", scene] if scene else [])
        print("$ " + " ".join(cmd), flush=True)
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=200)
        print(r.stdout[-1500:] + r.stderr[-1000:], flush=True)
        j = json.load(open(report)) if os.path.exists(report) else {}
        name = os.path.basename(rec)
        check(r.returncode == 0, f"{name}: lock-step --check passed")
        check(j.get("frames") == frames, f"{name}: {j.get('frames')} frames == {frames}")
        check(j.get("penetration_max_m", 1) <= 1e-4, f"{name}: penetration {j.get('penetration_max_m')} m")
        check(j.get("shm_segments_left", -1) == 0, f"{name}: no shared-memory segment left behind")
        # The same file in-process (godhand-bench): the lock-step lab computes the same hands.
        bench_json = os.path.join(TMP, "fmt-bench.json")
        b = subprocess.run([os.path.join(BIN, "godhand-bench"), "--recording", rec, "--quiet", "--json", bench_json] +
                           (["--scene", scene] if scene else []), capture_output=True, text=True, timeout=200)
        h = json.load(open(bench_json)).get("result_hash") if b.returncode == 0 and os.path.exists(bench_json) else None
        check(h is not None and h == j.get("result_hash"), f"{name}: result hash {j.get('result_hash')} == godhand-bench's {h}")


def tool_checks(j, what, lossy, frames=307):
    d = j.get("delivery", {}).get("tool", {})
    hand = j.get("plausibility", {}).get("per_hand", {}).get("tool", {})
    print(f"{what}: tool delivery {d}; tool figures: tracked {hand.get('tracked')}, model error {hand.get('model_error_m')}, "
          f"free tracking error {hand.get('free_tracking_error_m')}", flush=True)
    check(sorted(j.get("delivery", {})) == ["right", "tool"], f"{what}: both clusters reported")
    if lossy:
        check(d.get("expected", 0) > 50 and d.get("lost", 1) <= d["expected"] * LOSS, f"{what}: tool frames lost within {LOSS:.0%}")
    else:
        check(d.get("expected") == frames and d.get("fresh") == frames, f"{what}: every one of {frames} frames delivered fresh for the tool")
    # Tracked in every frame that carried its body (every accepted datagram does), started once tracked.
    check(hand.get("tracked", 0) >= 0.95 * d.get("fresh", 1e9) and hand.get("started", 0) >= hand.get("tracked", 1),
          f"{what}: the tool tracked in the frames delivered ({hand.get('tracked')} of {d.get('fresh')}) and started")
    check(hand.get("model_error_m", {}).get("max", 1) <= 1e-9, f"{what}: the free twin reproduces the tracked body exactly (a rigid model)")
    check(hand.get("free_tracking_error_m", {}).get("count", 0) > 0 and hand.get("free_tracking_error_m", {}).get("max", 1) <= 1e-6,
          f"{what}: the tool on its tracked body wherever no contact loads it")
    check(j.get("penetration_max_m", 1) <= j.get("margin_m", 0), f"{what}: penetration-free ({j.get('penetration_max_m')} m)")
    check(j.get("shm_segments_left", -1) == 0, f"{what}: no shared-memory segment left behind")


def case_tool_openxr(lab):
    """A tool cluster driven by an OpenXR 6-DOF body from a JSON Lines recording, through every
    service: lock-step (every frame fresh, the tool exactly on its body where nothing loads it) and
    live (the replay at its own rate, losses within the budget)."""
    logs = os.path.join(TMP, "logs")
    for mode, lossy in (("lock-step", False), ("live", True)):
        report = os.path.join(TMP, f"tool-openxr-{mode}.json")
        shutil.rmtree(logs, ignore_errors=True)
        cmd = [os.path.join(BIN, "godhand-launch"), "--lab", lab, "--domain", DOMAIN, "--check", "--json", report,
               "--log-dir", logs, "--quiet"] + (["--lockstep"] if not lossy else ["--loss-budget", str(LOSS)])
        print("$ " + " ".join(cmd), flush=True)
        r = run_launch(cmd, 180, logs)
        print(r.stdout[-3000:] + r.stderr[-2000:], flush=True)
        check(r.returncode == 0, f"{mode} run of the OpenXR tool lab with --check exited 0 (was {r.returncode})")
        tool_checks(json.load(open(report)) if os.path.exists(report) else {}, f"openxr {mode}", lossy, frames=80)


def case_tool(lab, dtrack_file, sender):
    logs = os.path.join(TMP, "logs")
    report = os.path.join(TMP, "tool.json")
    cmd = [os.path.join(BIN, "godhand-launch"), "--lab", lab, "--domain", DOMAIN, "--lockstep", "--check", "--json", report,
           "--log-dir", logs, "--quiet"]
    print("$ " + " ".join(cmd), flush=True)
    r = run_launch(cmd, 120, logs)
    print(r.stdout + r.stderr, flush=True)
    check(r.returncode == 0, f"lock-step run of the tool lab with --check exited 0 (was {r.returncode})")
    tool_checks(json.load(open(report)) if os.path.exists(report) else {}, "lock-step", False)

    # Live over UDP with every fault of the sender.
    report = os.path.join(TMP, "tool-live.json")
    send_log = os.path.join(TMP, "send.jsonl")
    shutil.rmtree(logs, ignore_errors=True)
    code, _ = live_with_faults(["--lab", lab], dtrack_file, sender, 5, 7, report, logs, send_log)
    check(code == 0, f"godhand-launch (live, faults) --check exited 0 (was {code})")
    tool_checks(json.load(open(report)) if os.path.exists(report) else {}, "live", True)
    st = ingest_source_line(open(os.path.join(logs, "ingest.log"), errors="replace").read()) if os.path.exists(os.path.join(logs, "ingest.log")) else None
    actions = [json.loads(l)["action"] for l in open(send_log)] if os.path.exists(send_log) else []
    check(st is not None and st["accepted"] + st["rejected"] == st["received"] and st["rejected"] > 0,
          f"the faults were counted by the ingest ({st})")
    print("sender actions:", {a: actions.count(a) for a in set(actions)}, flush=True)


before = shm()
try:
    if CASE == "live-dtrack":
        case_live_dtrack(*ARGS)
    elif CASE == "record-replay":
        case_record_replay(*ARGS)
    elif CASE == "rejects":
        case_rejects()
    elif CASE == "formats":
        case_formats(*ARGS)
    elif CASE == "tool":
        case_tool(*ARGS)
    elif CASE == "tool-openxr":
        case_tool_openxr(*ARGS)
    else:
        print("unknown case " + CASE)
        sys.exit(2)
finally:
    deadline = time.time() + 10
    while processes_of_domain() and time.time() < deadline:
        time.sleep(0.2)
    left = processes_of_domain()
    check(not left, f"no process of domain {DOMAIN} left ({left})")
    leftovers.kill_domain(DOMAIN, "sources.py")
    # Entries new since the start that nobody holds (parallel tests hold theirs): the
    # launcher's services' and a standalone godhand-ingest's alike.
    orphans = leftovers.orphaned_since(before)
    check(not orphans, f"no shared-memory entry left behind ({orphans})")
    shutil.rmtree(TMP, ignore_errors=True)
print("FAILED" if failures else "PASSED", flush=True)
sys.exit(1 if failures else 0)
