#!/usr/bin/env python3
"""Soak benchmark of the distributed component (not a CI test): a live lab of N clusters (default
8, the 6-body hand models, half right and half left) runs for M minutes on a looped recording;
the RSS of every service and the launcher's per-second end-to-end latency are sampled; at the end
it prints (and writes, with --json) the growth: RSS first-minute vs last-minute per service and
latency median/p99 of the first vs the last minute, plus the run's delivery counts.

usage: soak.py [--bin-dir build/bin] [--minutes 10] [--clusters 8] [--domain 168]
               [--recording deploy/recordings/confidence2-49fps.json] [--json OUT]

The loop is made by playing the recording forwards then backwards (timestamps continuing), so the
hands never jump. Everything runs on this machine over the shipped loopback profile."""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
DEPLOY = os.path.join(ROOT, "deploy")


def looped_recording(src, seconds, out):
    d = json.load(open(src))
    frames = d["frames"]
    ts = [f["timestamp"] for f in frames]
    dt = (ts[-1] - ts[0]) / max(1, len(ts) - 1)
    result, t, fid, forward = [], ts[0], frames[0]["id"], True
    while (t - ts[0]) * 1e-6 < seconds:
        seq = frames if forward else frames[::-1]
        for f in seq:
            g = dict(f)
            g["timestamp"] = int(t)
            g["id"] = fid
            result.append(g)
            t += dt
            fid += 1
        forward = not forward
    d["frames"] = result
    d["metadata"]["frames"] = len(result)
    json.dump(d, open(out, "w"))
    return len(result)


def lab_file(path, clusters, recording):
    lines = ['name: "soak"', "domain_id: 0", f'profiles: "{DEPLOY}/dds/godhand-local.xml"',
             f'scene: "{DEPLOY}/scenes/default.pbtxt"', f'recording: "{recording}"']
    names = []
    for i in range(clusters):
        side = "right" if i % 2 == 0 else "left"
        name = f"{side}{i // 2}"
        names.append(name)
        lines.append(f'clusters {{ name: "{name}" model: "{DEPLOY}/models/hand6_{side}.pbtxt" side: "{side}" }}')
    for kind in ("INGEST", "SCENE", "RESOLVER"):
        lines.append(f"services {{ kind: {kind} }}")
    for n in names:
        lines.append(f'services {{ kind: SOLVER cluster: "{n}" }}')
    open(path, "w").write("\n".join(lines) + "\n")


def children(pid):
    out = {}
    for p in os.listdir("/proc"):
        if not p.isdigit():
            continue
        try:
            st = open(f"/proc/{p}/status").read()
            ppid = int(re.search(r"PPid:\s+(\d+)", st).group(1))
            if ppid != pid:
                continue
            cmd = open(f"/proc/{p}/cmdline").read().split("\0")
            name = os.path.basename(cmd[0]).replace("godhand-", "")
            if "--cluster" in cmd:
                name += "/" + cmd[cmd.index("--cluster") + 1]
            rss = int(re.search(r"VmRSS:\s+(\d+)", st).group(1))
            out[name] = rss
        except (OSError, AttributeError, ValueError):
            pass
    return out


def live_time(line):
    """The replay time (s) of one of the launcher's per-second lines, None for any other line."""
    m = re.match(r"launch: t +([\d.]+) s \|", line)
    return float(m.group(1)) if m else None


def live_latency(line):
    """(median, p99) in us of a per-second line's end-to-end latency, None when it has none (no
    fresh state that second)."""
    m = re.search(r"\| latency[^|]*? median (\d+) us p99 (\d+) us", line)
    return (int(m.group(1)), int(m.group(2))) if m else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin-dir", default=os.path.join(ROOT, "build", "bin"))
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--clusters", type=int, default=8)
    ap.add_argument("--domain", type=int, default=168)
    ap.add_argument("--recording", default=os.path.join(DEPLOY, "recordings", "confidence2-49fps.json"))
    ap.add_argument("--json")
    a = ap.parse_args()
    if not (0.2 <= a.minutes <= 600) or not (1 <= a.clusters <= 16):
        print("soak.py: --minutes in [0.2, 600], --clusters in [1, 16]", file=sys.stderr)
        sys.exit(2)
    tmp = tempfile.mkdtemp(prefix="godhand-soak-")
    try:
        rec = os.path.join(tmp, "looped.json")
        n = looped_recording(a.recording, a.minutes * 60, rec)
        lab = os.path.join(tmp, "soak.pbtxt")
        lab_file(lab, a.clusters, rec)
        report = os.path.join(tmp, "report.json")
        cmd = [os.path.join(a.bin_dir, "godhand-launch"), "--lab", lab, "--domain", str(a.domain), "--json", report,
               "--log-dir", os.path.join(tmp, "logs"), "--start-timeout", "120"]
        print(f"soak: {a.clusters} clusters, {a.minutes:g} min ({n} frames), $ {' '.join(cmd)}", flush=True)
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
        rss, lat, last_sample, lines_seen = [], [], -10.0, 0
        for line in p.stdout:
            t = live_time(line)
            if t is None:
                print(line, end="", flush=True)
                continue
            lines_seen += 1
            m = live_latency(line)
            if m and t > 0:
                lat.append((t, m[0], m[1]))
            if t > 0 and t - last_sample >= 10:
                last_sample = t
                rss.append((t, children(p.pid)))
                print(f"soak: t {t:6.0f} s rss(kB) {rss[-1][1]} latency median {m[0] if m else 'none'} us", flush=True)
        p.wait(timeout=120)
        j = json.load(open(report)) if os.path.exists(report) else {}
        end = lat[-1][0] if lat else 0

        def window(lo, hi):
            return [x for x in lat if lo <= x[0] < hi]

        first, last = window(60, 120) if end > 180 else window(0, end / 3), window(end - 60, end + 1) if end > 180 else window(2 * end / 3, end + 1)
        res = {"clusters": a.clusters, "minutes": a.minutes, "frames": n, "exit": p.returncode, "delivery": j.get("delivery"),
               "latency_us": {"first": {"median": statistics.median([x[1] for x in first]) if first else None,
                                        "p99_max": max([x[2] for x in first]) if first else None},
                              "last": {"median": statistics.median([x[1] for x in last]) if last else None,
                                       "p99_max": max([x[2] for x in last]) if last else None}},
               "rss_kb": {}}
        if len(rss) >= 2:
            a0 = rss[1][1] if len(rss) > 2 else rss[0][1]  # skip the first sample (start-up)
            for name in sorted(rss[-1][1]):
                if name in a0:
                    res["rss_kb"][name] = {"start": a0[name], "end": rss[-1][1][name], "growth": rss[-1][1][name] - a0[name]}
        res["per_second_lines"] = lines_seen
        res["latency_samples"] = len(lat)
        res["rss_samples"] = len([x for x in rss if x[1]])  # a sample that found no service is none
        print(json.dumps(res, indent=2))
        if a.json:
            json.dump(res, open(a.json, "w"), indent=2)
        # A soak that sampled nothing measured nothing: say so and fail (the line's format changed
        # once and the soak went on printing nulls).
        missing = [what for what, n in (("per-second lines", lines_seen), ("latency", len(lat)), ("RSS", res["rss_samples"])) if n == 0]
        if missing:
            print(f"soak.py: no {', no '.join(missing)} sampled from the launcher's output", file=sys.stderr)
        sys.exit(0 if p.returncode == 0 and not missing else 1)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
