#!/usr/bin/env python3
"""A lab over three hosts, for real: three network namespaces (each with its own /dev/shm, so
no shared memory crosses hosts) joined by veth pairs on a bridge, private test addresses
10.231.0.1-3, UDP only between them, discovery through a Fast DDS Discovery Server
(`fastdds discovery`) on the scene host. The lab is deployed as a lab admin would: its one
configuration rendered by `godhand-launch --render systemd` (per host: the lab file, identical
everywhere, and every host's profiles: godhand-multihost-ds.xml with that host's address), and
each host runs `godhand-launch --lab ITS-COPY --host NAME`:

    ingest   10.231.0.1   godhand-ingest (and the monitor that writes the report)
    solvers  10.231.0.2   godhand-solver per cluster
    scene    10.231.0.3   godhand-scene, godhand-resolver, fastdds discovery

Checks: the lock-step result_hash of the run across the namespaces equals godhand-bench's
in-process one (computed here, never hard-coded); a live run across the namespaces delivers
hand states with their end-to-end latency measured (a figure, printed with the delivery counts:
not --check, since a loaded machine loses live frames); every host's lab interface carried traffic
(UDP went between the namespaces) while each host's second interface ("uplink": default route
and multicast route, i.e. where anything addressed outside the lab would go) sent 0 packets,
with a positive control (a datagram addressed outside the lab moves that counter).

Everything runs inside a fresh user + network namespace (unshare -rnm), itself without any
route out: nothing can reach a real network. The test skips (77) where that cannot be made.

usage: multihost.py BIN_DIR DEPLOY_DIR DOMAIN RECORDING
       (re-executes itself inside the namespace as: multihost.py --inner ...)
       multihost.py --render-check BIN_DIR DEPLOY_DIR: godhand-launch --render systemd on the
       shipped two-machine lab, every unit through `systemd-analyze verify` (with controls)
"""
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HOSTS = [("ingest", "10.231.0.1"), ("solvers", "10.231.0.2"), ("scene", "10.231.0.3")]
SERVER_HOST = "scene"
failures = []


def check(ok, what):
    print(("ok:     " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


def run(cmd, timeout, **kw):
    print("$ " + " ".join(cmd), flush=True)
    return subprocess.run(cmd, timeout=timeout, capture_output=True, text=True, **kw)


def sh(cmd):
    r = subprocess.run(["sh", "-c", cmd], capture_output=True, text=True, timeout=30)
    if r.returncode != 0:
        raise RuntimeError(f"{cmd}: {r.stderr.strip()}")
    return r.stdout


def write_lab(tmp, deploy, server=True, security=""):
    """The lab's one configuration: three hosts with their addresses, the discovery server (or,
    secured, the lab PKI's directory)."""
    dep = os.path.abspath(deploy)
    hosts = "".join(f'hosts {{ name: "{n}" address: "{a}" }}\n' for n, a in HOSTS)
    text = f"""name: "multihost-test"
domain_id: 0
scene: "{dep}/scenes/default.pbtxt"
recording: "{dep}/recordings/pinch.json"
{hosts}{f'discovery_server: "{SERVER_HOST}"' if server else ""}
{f'security: "{security}"' if security else ""}
clusters {{ name: "right" model: "{dep}/models/hand16_right.pbtxt" side: "right" }}
clusters {{ name: "left" model: "{dep}/models/hand16_left.pbtxt" side: "left" }}
services {{ kind: INGEST host: "ingest" }}
services {{ kind: SCENE host: "scene" }}
services {{ kind: RESOLVER host: "scene" }}
services {{ kind: SOLVER cluster: "right" host: "solvers" }}
services {{ kind: SOLVER cluster: "left" host: "solvers" }}
"""
    path = os.path.join(tmp, "lab.pbtxt")
    open(path, "w").write(text)
    return path


def render_lab(tmp, bin_dir, deploy, server=True, extra=None, security=""):
    """Deploys the lab as a lab admin would: `godhand-launch --render systemd OUT` from the one lab
    file, then each host uses its own rendered directory OUT/HOST/ (its lab.pbtxt, identical on
    every host, pointed at that directory instead of /etc/godhand/LAB/, where an installation
    copies it). `extra(name, xml)` may rewrite a host's own profiles (name "server" for the
    discovery server's). Returns ({host: lab file}, {host: its profiles}, server profile or None)."""
    src = write_lab(tmp, deploy, server, security)
    out = os.path.join(tmp, "rendered")
    r = run([os.path.join(bin_dir, "godhand-launch"), "--lab", src, "--render", "systemd", out], 60)
    print(r.stdout + r.stderr)
    check(r.returncode == 0, f"godhand-launch --render systemd wrote every host's files (exit {r.returncode})")
    labs, profiles = {}, {}
    for name, _ in HOSTS:
        d = os.path.join(out, name)
        text = open(os.path.join(d, "lab.pbtxt")).read()
        check("/etc/godhand/multihost-test/profiles-" in text, f"{name}: rendered lab file names the installed profiles")
        labs[name] = os.path.join(d, "lab-here.pbtxt")
        open(labs[name], "w").write(text.replace("/etc/godhand/multihost-test/", d + "/"))
        profiles[name] = os.path.join(d, f"profiles-{name}.xml")
        if extra:
            text = extra(name, open(profiles[name]).read())
            open(profiles[name], "w").write(text)
    server_xml = os.path.join(out, SERVER_HOST, "discovery-server.xml") if server else None
    if server_xml and extra:
        text = extra("server", open(server_xml).read())
        open(server_xml, "w").write(text)
    return labs, profiles, server_xml


def dump_stacks(pattern):
    """Every thread's backtrace of the processes whose command line matches `pattern`, where gdb
    is installed: what a process that missed its deadline was waiting for (printed, best effort)."""
    if not shutil.which("gdb"):
        print(f"(no gdb: no backtrace of {pattern!r})")
        return
    pids = subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True).stdout.split()
    for pid in pids:
        try:
            r = subprocess.run(["gdb", "-p", pid, "-batch", "-nx", "-ex", "thread apply all bt 25"],
                               capture_output=True, text=True, timeout=60)
            lines = [l for l in r.stdout.splitlines() if l.startswith(("#", "Thread"))]
            print(f"--- backtrace of {pattern!r} pid {pid}:\n" + "\n".join(lines[:400]))
        except subprocess.TimeoutExpired:
            print(f"(gdb on pid {pid} timed out)")


def stop(p, sig):
    """Signals the process group of `p` (started with its own session), if it still runs."""
    try:
        os.killpg(p.pid, sig)
    except ProcessLookupError:
        pass


class Lab:
    """The namespaces: one holder process per host (own netns + mount ns with a private /dev/shm)."""

    def __init__(self):
        self.holders = {}
        self.procs = []
        self.probe_out = {}

    def build(self):
        for k in ("all", "default"):
            sh(f"echo 1 > /proc/sys/net/ipv6/conf/{k}/disable_ipv6 || true")
        sh("ip link set lo up && ip link add br0 type bridge && ip link set br0 up")
        for i, (name, addr) in enumerate(HOSTS, 1):
            p = subprocess.Popen(["unshare", "-mn", "sh", "-c",
                                  "mount -t tmpfs -o size=256m tmpfs /dev/shm && "
                                  "for k in all default; do echo 1 > /proc/sys/net/ipv6/conf/$k/disable_ipv6; done; "
                                  "echo ready; exec sleep 100000"],
                                 stdout=subprocess.PIPE, text=True)
            self.holders[name] = p
            if p.stdout.readline().strip() != "ready":
                raise RuntimeError(f"namespace of {name} not ready")
            pid = p.pid
            # lab link: h<i> in the host, h<i>b on the bridge
            sh(f"ip link add h{i} type veth peer name h{i}b && ip link set h{i} netns {pid} && "
               f"ip link set h{i}b master br0 && ip link set h{i}b up")
            # uplink: where anything addressed outside the lab (default route, multicast) goes
            sh(f"ip link add u{i} type veth peer name u{i}b && ip link set u{i} netns {pid} && ip link set u{i}b up")
            self.ns(name, f"ip link set lo up && ip addr add {addr}/24 dev h{i} && ip link set h{i} up && "
                          f"ip addr add 10.231.9.{i}/24 dev u{i} && ip link set u{i} up multicast on && "
                          f"ip route add default via 10.231.9.254 dev u{i} && ip route add 224.0.0.0/4 dev u{i}")

    def enter(self, name):
        return ["nsenter", "-t", str(self.holders[name].pid), "-n", "-m", "--preserve-credentials"]

    def ns(self, name, cmd):
        r = subprocess.run(self.enter(name) + ["sh", "-c", cmd], capture_output=True, text=True, timeout=30)
        if r.returncode != 0:
            raise RuntimeError(f"[{name}] {cmd}: {r.stderr.strip()}")
        return r.stdout

    def counters(self):
        """(lab tx, uplink tx) packets per host."""
        out = {}
        for i, (name, _) in enumerate(HOSTS, 1):
            dev = {}
            for l in self.ns(name, "cat /proc/net/dev").splitlines()[2:]:
                iface, rest = l.split(":", 1)
                dev[iface.strip()] = int(rest.split()[9])
            out[name] = (dev[f"h{i}"], dev[f"u{i}"])
        return out

    def start(self, name, cmd, log):
        # own process group: a stop reaches the tool's children too (fastdds is a wrapper script)
        p = subprocess.Popen(self.enter(name) + cmd, stdout=open(log, "w"), stderr=subprocess.STDOUT, text=True,
                             start_new_session=True)
        self.procs.append(p)
        return p

    def close(self):
        for p in self.procs:
            stop(p, signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                stop(p, signal.SIGKILL)
                p.wait()
        for p in self.holders.values():
            p.kill()
            p.wait()


def lab_run(lab, tmp, bin_dir, lab_files, domain, server_xml, mode_args, tag, timeout=180, probes=(), probes_ready=None,
            check_run=True):
    """One run across the namespaces. `probes`: (name, host, argv) started once the other hosts'
    launches run, before the ingest host's, and stopped (SIGTERM) after it; their output goes to
    lab.probe_out[name]; `probes_ready(logs)` (bounded) is awaited before the ingest host starts. Returns (ingest launch rc, its report, other hosts' rcs)."""
    logs = os.path.join(tmp, f"logs-{tag}")
    os.makedirs(logs, exist_ok=True)
    server = None
    if server_xml:
        tool = ["fast-discovery-server"] if shutil.which("fast-discovery-server") else ["fastdds", "discovery"]
        server = lab.start(SERVER_HOST, tool + ["-x", f"godhand_discovery_server@{server_xml}"],
                           os.path.join(logs, "discovery-server.out"))
        time.sleep(0.5)
        check(server.poll() is None, f"[{tag}] discovery server runs on {SERVER_HOST}")
    def base(host):
        return [os.path.join(bin_dir, "godhand-launch"), "--lab", lab_files[host], "--domain", str(domain), "--quiet"] + mode_args
    others = {}
    for name in ("scene", "solvers"):
        others[name] = lab.start(name, base(name) + ["--host", name, "--log-dir", os.path.join(logs, name),
                                               "--json", os.path.join(tmp, f"{tag}-{name}.json")],
                                 os.path.join(logs, f"launch-{name}.out"))
    running = []
    for pname, phost, argv in [p for p in probes if not p[0].endswith("-late")]:
        running.append((pname, lab.start(phost, argv, os.path.join(logs, f"probe-{pname}.out"))))
    if probes_ready:
        t0 = time.time()
        ok = False
        while time.time() - t0 < 60 and not ok:
            time.sleep(0.2)
            ok = probes_ready(logs)
        check(ok, f"[{tag}] probes ready before the ingest starts ({time.time() - t0:.1f} s)")
    report = os.path.join(tmp, f"{tag}-ingest.json")
    ingest = lab.start("ingest", base("ingest") + ["--host", "ingest", "--log-dir", os.path.join(logs, "ingest"), "--json", report] +
                       (["--check"] if check_run else []), os.path.join(logs, "launch-ingest.out"))
    # Injecting probes stop as soon as the ingest is done: the ingest host's late-joiner check
    # (which follows) must see the lab's hands only.
    t_end = time.time() + timeout
    injectors_stopped = False
    while ingest.poll() is None and time.time() < t_end:
        time.sleep(0.05)
        if not injectors_stopped and running:
            try:
                done = "finished" in open(os.path.join(logs, "ingest", "ingest.log")).read()
            except OSError:
                done = False
            if done:
                for pname, p in running:
                    if "injector" in pname:
                        stop(p, signal.SIGTERM)
                injectors_stopped = True
    if ingest.poll() is None:
        print(f"[{tag}] the ingest host's launch is still running at its deadline ({timeout} s): its stacks")
        dump_stacks(f"godhand-launch .*--host ingest .*--log-dir {os.path.join(logs, 'ingest')}")
        dump_stacks(f"godhand-ingest .*--domain {domain} ")  # a child it may be waiting for
        stop(ingest, signal.SIGKILL)
    rc = ingest.wait()
    if running:  # the other hosts still publish (held states): let late handshakes complete
        time.sleep(2)
    for pname, p in running:
        stop(p, signal.SIGTERM)
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            stop(p, signal.SIGKILL)
            p.wait()
        lab.probe_out[pname] = open(os.path.join(logs, f"probe-{pname}.out")).read()
        print(f"--- probe {pname}:\n" + lab.probe_out[pname][-1500:])
    rcs = {}
    for name, p in others.items():
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
        try:
            rcs[name] = p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            stop(p, signal.SIGKILL)
            rcs[name] = "killed"
    if server:
        stop(server, signal.SIGTERM)
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            stop(server, signal.SIGKILL)
            server.wait()
    out = open(os.path.join(logs, "launch-ingest.out")).read()
    print(f"--- [{tag}] ingest host launch (exit {rc}):\n" + out[-2500:])
    # The backtraces the launcher takes of an ingest stuck at exit (before it kills it) are far
    # above the tail: printed whole, or the hang they were taken for stays unexplained (CI of
    # 5659fff: the stuck ingest's stacks were cut off with the rest of the log).
    marker = out.find("the ingest's threads")
    if marker >= 0:
        end = out.find("\nlaunch: ", marker)
        print(f"--- [{tag}] the launcher's backtraces of the stuck ingest:\n" + out[marker:end if end >= 0 else None][:60000])
    if rc != 0 or any(v != 0 for v in rcs.values()):
        for f in sorted(os.listdir(logs)):
            p = os.path.join(logs, f)
            if os.path.isfile(p):
                print(f"--- {f}\n" + open(p).read()[-2000:])
            elif os.path.isdir(p):
                for g in sorted(os.listdir(p)):
                    print(f"--- {f}/{g}\n" + open(os.path.join(p, g)).read()[-2000:])
    j = json.load(open(report)) if os.path.exists(report) else {}
    return rc, j, rcs


def inner(bin_dir, deploy, domain, recording, tmp, profile_hook=None, tag_prefix="", probes=None, server=True, probes_ready=None,
          security=""):
    """The three-host runs; `profile_hook(name, xml)` rewrites each host's (and the server's)
    profiles, `probes(profiles)` gives the probes of the lock-step run (the live run, which
    measures latency, has none); server=False: discovery
    through unicast initial peers instead of the discovery server. Returns (lock-step report,
    live report, probe outputs)."""
    lab = Lab()
    try:
        lab.build()
        lab_files, profiles, server_xml = render_lab(tmp, bin_dir, deploy, server, profile_hook, security)
        # The lab works as a network: each host reaches the others over its lab link.
        r = subprocess.run(lab.enter("ingest") + ["ping", "-c", "1", "-W", "2", "10.231.0.3"], capture_output=True, text=True) \
            if shutil.which("ping") else None
        if r is not None:
            check(r.returncode == 0, "ingest host reaches the scene host over the bridge (ping)")
        before = lab.counters()

        # Lock-step: the hash across the namespaces equals the in-process one.
        bench_json = os.path.join(tmp, "bench.json")
        rb = run([os.path.join(bin_dir, "godhand-bench"), "--recording", recording, "--quiet", "--json", bench_json], 300)
        check(rb.returncode == 0, "godhand-bench ran")
        b = json.load(open(bench_json)) if rb.returncode == 0 else {}
        t0 = time.time()
        # No --check: it also fails a lock-step run whose states arrive older than stale_after_s
        # (0.25 s), which a loaded machine produces across namespaces; what matters here is
        # checked below: every frame, none lost, the same poses as in-process (the hash).
        rc, j, rcs = lab_run(lab, tmp, bin_dir, lab_files, domain, server_xml, ["--lockstep", "--recording", recording],
                             tag_prefix + "lockstep", probes=probes(profiles) if probes else (), probes_ready=probes_ready,
                             check_run=False)
        check(rc == 0 and not j.get("failure"),
              f"lock-step run across three namespaces: ingest host's launch exited {rc} ({time.time() - t0:.1f} s) {j.get('failure') or ''}")
        d = j.get("delivery", {})
        check(len(d) == j.get("hands") and all(v.get("lost", -1) == 0 and v.get("expected") == b.get("frames") for v in d.values()),
              f"no frame lost in any cluster ({d})")
        check(j.get("penetration_max_m", 1) <= j.get("margin_m", 0), f"nothing penetrates ({j.get('penetration_max_m')} m)")
        check(all(v == 0 for v in rcs.values()), f"the other hosts' launches stopped cleanly on SIGTERM ({rcs})")
        check(b.get("frames", -1) == j.get("frames"), f"every frame came back ({j.get('frames')} of {b.get('frames')})")
        check(b.get("result_hash") is not None and j.get("result_hash") == b.get("result_hash"),
              f"result_hash across namespaces {j.get('result_hash')} == in-process {b.get('result_hash')}")
        s = j.get("services", {})
        check(all(k in s for k in ("scene", "resolver", "solver/right", "solver/left")),
              f"the ingest host's monitor heard every remote service's heartbeat ({sorted(s)})")
        lj = j.get("late_joiner", {})
        # (with probes, injected hand indices >= the lab's count among the late joiner's hands)
        check((lj.get("hand_states") == j.get("hands") or probes and lj.get("hand_states", 0) >= j.get("hands", 1))
              and lj.get("scene_description") is True,
              f"a late joiner on the ingest host got every HandState and the SceneDescription across hosts ({lj})")

        # Live: latency across the namespaces.
        # (no --check: on a loaded machine the live run may lose frames, which is a figure here, not a failure)
        rc, jl, rcs = lab_run(lab, tmp, bin_dir, lab_files, domain, server_xml, ["--recording", recording], tag_prefix + "live",
                              check_run=False)
        check(rc == 0, "live run across three namespaces: ingest host's launch exited 0")
        print(f"FIGURE {tag_prefix}multihost_live_delivery {json.dumps(jl.get('delivery'))} states {jl.get('hand_states')}", flush=True)
        check(all(v == 0 for v in rcs.values()), f"the other hosts' launches stopped cleanly on SIGTERM ({rcs})")
        lat = jl.get("latency_us", {})
        check(lat.get("samples", 0) > 0 and lat.get("median", 0) > 0,
              f"latency across namespaces (tracker sample on 'ingest' -> HandState back on 'ingest' via solvers and resolver): "
              f"median {lat.get('median', 0):.0f} us, p99 {lat.get('p99', 0):.0f} us over {lat.get('samples')} states")
        print(f"FIGURE {tag_prefix}multihost_latency_us median {lat.get('median', 0):.0f} p99 {lat.get('p99', 0):.0f} "
              f"samples {lat.get('samples')}", flush=True)

        after = lab.counters()
        for name, _ in HOSTS:
            lab_tx = after[name][0] - before[name][0]
            up_tx = after[name][1] - before[name][1]
            check(lab_tx > 0, f"{name}: {lab_tx} packets sent on the lab link (UDP between the namespaces)")
            check(up_tx == 0, f"{name}: {up_tx} packets sent on the uplink (nothing addressed outside the lab)")
        # Positive control: a datagram addressed outside the lab does move an uplink counter.
        # (multicast, as DDS's default discovery would send: no ARP, the packets leave at once)
        lab.ns("ingest", "python3 -c \"import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); "
                         "[s.sendto(b'x', ('239.255.0.1', 7400)) for _ in range(3)]\"")
        ctl = lab.counters()["ingest"][1] - after["ingest"][1]
        check(ctl >= 3, f"control: 3 datagrams addressed outside the lab moved the ingest uplink counter by {ctl}")
        return j, jl, lab.probe_out
    finally:
        lab.close()


def outer(args, script):
    """Skips (77) where the namespaces cannot be made; else re-executes `script --inner ARGS TMP
    ...` inside a fresh user + network + mount namespace and checks nothing of the domain is left."""
    args = [a if i == 2 else os.path.abspath(a) for i, a in enumerate(args)]
    domain = args[2]
    for tool in ("unshare", "nsenter", "ip", "fastdds"):
        if not shutil.which(tool):
            print(f"SKIP: needs {tool}")
            sys.exit(77)
    probe = subprocess.run(["unshare", "-rnm", "sh", "-c",
                            "ip link add br0 type bridge && ip link add v0 type veth peer name v1 && "
                            "unshare -mn sh -c 'mount -t tmpfs tmpfs /dev/shm' && ip link set v1 master br0"],
                           capture_output=True, text=True)
    if probe.returncode != 0:
        print("SKIP: cannot create network namespaces joined by a bridge here: " + probe.stderr.strip())
        sys.exit(77)
    tmp = tempfile.mkdtemp(prefix="godhand-multihost-")
    rc = 1
    try:
        r = subprocess.run(["unshare", "-rnm", sys.executable, os.path.abspath(script), "--inner"] + args[:4] + [tmp] + args[4:],
                           timeout=600)
        rc = r.returncode
    finally:
        # nothing of this domain may survive (the namespaces die with their holder processes)
        deadline = time.time() + 5
        left = []
        while time.time() < deadline:
            out = subprocess.run(["pgrep", "-af", "godhand-"], capture_output=True, text=True).stdout
            left = [l for l in out.splitlines() if f"--domain {domain} " in l + " " and ".py" not in l]
            if not left:
                break
            time.sleep(0.2)
        if left:
            print(f"FAILED: processes of domain {domain} left: {left}")
            rc = 1
        # GODHAND_KEEP_LOGS=1 (a hunt for a rare failure): the run's directory is left, named.
        if os.environ.get("GODHAND_KEEP_LOGS") == "1":
            print(f"logs kept in {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    sys.exit(rc)


def render_check(bin_dir, deploy):
    """`godhand-launch --render systemd OUTDIR` on the shipped two-machine lab: every host's files
    are written, and every unit passes `systemd-analyze verify` without a warning (when that
    tool is there; controls: a unit with a missing program fails, an unknown key warns)."""
    tmp = tempfile.mkdtemp(prefix="godhand-render-")
    try:
        out = os.path.join(tmp, "out")
        r = run([os.path.join(bin_dir, "godhand-launch"), "--lab", os.path.join(deploy, "lab", "two-machines.pbtxt"),
                 "--render", "systemd", out], 60)
        print(r.stdout + r.stderr)
        check(r.returncode == 0, f"godhand-launch --render systemd exited {r.returncode}")
        units = []
        for host in ("tracker-pc", "compute-pc"):
            for f in ("godhand-two-machines.service", "godhand-two-machines.env", "lab.pbtxt", "INSTALL",
                      "profiles-tracker-pc.xml", "profiles-compute-pc.xml"):
                check(os.path.isfile(os.path.join(out, host, f)), f"{host}/{f} written")
            units += [os.path.join(out, host, f) for f in sorted(os.listdir(os.path.join(out, host))) if f.endswith(".service")]
        check(os.path.isfile(os.path.join(out, "compute-pc", "godhand-two-machines-discovery.service")),
              "the discovery server's unit on its host")
        r = run([os.path.join(bin_dir, "godhand-launch"), "--lab", os.path.join(deploy, "lab", "local.pbtxt"), "--render", "systemd",
                 os.path.join(tmp, "local")], 60)
        check(r.returncode == 2 and "names no hosts" in r.stderr and len(r.stderr.strip().splitlines()) == 1,
              f"a lab without hosts: exit 2, one line ({r.returncode}, {r.stderr.strip()})")
        if not shutil.which("systemd-analyze"):
            print("note: systemd-analyze not found: units not verified")
            return
        for u in units:
            v = run(["systemd-analyze", "verify", u], 60)
            msg = (v.stdout + v.stderr).strip()
            check(v.returncode == 0 and not msg, f"systemd-analyze verify {os.path.relpath(u, out)}: exit {v.returncode} {msg}")
        bad = os.path.join(tmp, "bad-missing.service")
        open(bad, "w").write(re.sub(r"ExecStart=\S+", "ExecStart=/nonexistent/godhand-launch", open(units[0]).read()))
        v = run(["systemd-analyze", "verify", bad], 60)
        check(v.returncode != 0, f"control: a unit whose program is missing fails verify (exit {v.returncode})")
        bad = os.path.join(tmp, "bad-key.service")
        open(bad, "w").write(open(units[0]).read().replace("[Service]\n", "[Service]\nNoSuchKey=1\n"))
        v = run(["systemd-analyze", "verify", bad], 60)
        check("NoSuchKey" in v.stdout + v.stderr, "control: an unknown key is reported by verify")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--render-check":
        render_check(os.path.abspath(sys.argv[2]), os.path.abspath(sys.argv[3]))
        print("PASSED" if not failures else f"{len(failures)} check(s) FAILED")
        sys.exit(0 if not failures else 1)
    if len(sys.argv) > 1 and sys.argv[1] == "--inner":
        bin_dir, deploy, domain, recording, tmp = sys.argv[2:7]
        inner(bin_dir, deploy, int(domain), recording, tmp)
        print("PASSED" if not failures else f"{len(failures)} check(s) FAILED")
        sys.exit(0 if not failures else 1)
    outer(sys.argv[1:5], __file__)


if __name__ == "__main__":
    main()
