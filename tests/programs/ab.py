#!/usr/bin/env python3
"""Before and after in the same run: two builds of godhand-bench, alternated over the acceptance
cases, on the same (shared, noisy) machine.

    python3 tests/programs/ab.py [--rounds N] [--frames N] [--case NAME]... [--check-same-hash]
                                 [--instructions] A B

A and B are godhand-bench binaries or directories holding one (e.g. a copy of build/bin made
before a change, and build/bin). Each round runs every case with A, then with B, so that a load
that comes and goes falls on both. Per run it prints the median rate, p99, result hash,
penetration and the plausibility figures (excess lag p95 and frames above 5 mm, stuck frames,
frozen windows, jitter) from the bench's own JSON report; then per case the speed ranges over the
rounds and each side's plausibility. The figures are the bench's, defined once in core/pipeline/run_metrics (nothing is
recomputed here). --check-same-hash: exit 1 unless every case gave the same hash with A and B (a
change meant to leave the results alone). A failed run is reported and makes the exit status 1.

--instructions: also the instructions each side executes in its frames (valgrind's callgrind,
counting only inside Pipeline::step, one thread: the same binary and input give the same count,
whatever the load), once per case and side, with B's change against A: the figure that tells a
few per cent apart on this shared machine, where the rates cannot. Slow (about 20x a run). With
--rounds 0, only these.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
DEPLOY = os.path.normpath(os.path.join(HERE, "..", "..", "deploy"))
REC = os.path.join(DEPLOY, "recordings")
MESH = os.path.join(DEPLOY, "meshes")

# The acceptance cases (../shared/tools/acceptance.sh) and one and two hands on the default scene.
CASES = {
    "pinch-bunny": ["--recording", os.path.join(REC, "pinch.json"), "--mesh", os.path.join(MESH, "stanford-bunny.obj") + ":0.15"],
    "splay-fandisk": ["--recording", os.path.join(REC, "HandSplay-110fps.json"), "--mesh", os.path.join(MESH, "fandisk.obj") + ":0.2"],
    "twohands-bunny": ["--recording", os.path.join(REC, "confidence2-49fps.json"), "--mesh", os.path.join(MESH, "stanford-bunny.obj") + ":0.25"],
    "pinch-default": ["--recording", os.path.join(REC, "pinch.json")],
    "c2-default": ["--recording", os.path.join(REC, "confidence2-49fps.json")],
}


def fail(message, program="ab.py"):
    print(f"{program}: {message}", file=sys.stderr)
    sys.exit(2)


def bench_path(arg, program="ab.py"):
    """godhand-bench itself or the directory holding it (a one-line error, exit 2, otherwise)."""
    path = os.path.join(arg, "godhand-bench") if os.path.isdir(arg) else arg
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        fail(f"{arg}: no executable godhand-bench there", program)
    return path


def run(bench, case, frames, extra):
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "report.json")
        cmd = [bench, *CASES[case], "--quiet", "--json", out, *extra]
        if frames:
            cmd += ["--frames", str(frames)]
        proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if proc.returncode != 0 or not os.path.exists(out):
            last = proc.stderr.strip().splitlines()[-1:] or ["no output"]
            return {"error": f"exit {proc.returncode}: {last[0]}"}
        with open(out) as f:
            j = json.load(f)
    return {
        "hz": j["hz_median"],
        "p99_ms": j["step_us"]["p99"] / 1000.0,
        "hash": j["result_hash"],
        "pen_mm": j["penetration_max_m"] * 1000.0,
        "frozen": f'{j["frozen_windows"]}/{j["moving_windows"]}',
        "lag_p95_mm": j["excess_lag_m"]["p95"] * 1000.0,
        "lag_above": j["excess_lag_above_5mm"],
        "stuck": j["stuck_frames"],
        "jitter": j["jitter_body_frames"],
    }


def instructions(bench, case, frames, extra):
    """Instructions inside Pipeline::step under callgrind, one thread; or {"error": ...}."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = ["valgrind", "--tool=callgrind", "--callgrind-out-file=" + os.path.join(tmp, "cg.out"),
               "--toggle-collect=godhand::Pipeline::step(*", bench, *CASES[case], "--quiet", "--threads", "1", *extra]
        if frames:
            cmd += ["--frames", str(frames)]
        proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    m = re.search(r"Collected : (\d+)", proc.stderr)
    if proc.returncode != 0 or not m:
        last = proc.stderr.strip().splitlines()[-1:] or ["no output"]
        return {"error": f"exit {proc.returncode}: {last[0]}"}
    return {"ir": int(m.group(1))}


def measure_all(cases, benches, measure, label, describe):
    """measure(bench, case) for every case and side, each printed as it comes (or its failure):
    ({(case, side): result}, whether any failed)."""
    got, failed = {}, False
    for case in cases:
        for side, bench in benches.items():
            res = measure(bench, case)
            if "error" in res:
                failed = True
                print(f"{label} {side} {case}: FAILED ({res['error']})", flush=True)
                continue
            got[(case, side)] = res
            print(f"{label} {side} {case}: {describe(res)}", flush=True)
    return got, failed


def plausibility(res):
    return (f"excess lag p95 {res['lag_p95_mm']:.2f} mm, {res['lag_above']} frames > 5 mm, stuck {res['stuck']}, "
            f"frozen {res['frozen']}, jitter {res['jitter']} body-frames")


def span(values, fmt):
    lo, hi = min(values), max(values)
    return fmt.format(lo) if lo == hi else (fmt + "–" + fmt).format(lo, hi)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a", help="the build before (godhand-bench or its directory)")
    ap.add_argument("b", help="the build after")
    ap.add_argument("--rounds", type=int, default=3, help="alternations (default 3)")
    ap.add_argument("--frames", type=int, default=0, help="only the first N frames of each recording")
    ap.add_argument("--case", action="append", choices=sorted(CASES), help="a case (repeatable; default: all five)")
    ap.add_argument("--bench-arg", action="append", default=[], help="one more argument for both benches (repeatable)")
    ap.add_argument("--check-same-hash", action="store_true", help="exit 1 unless A and B give the same hashes")
    ap.add_argument("--instructions", action="store_true",
                    help="also each side's instructions in its frames (callgrind, one thread; slow)")
    args = ap.parse_args()
    if args.rounds < 0 or (args.rounds == 0 and not args.instructions):
        fail("--rounds must be >= 1 (0 only with --instructions)")
    if args.instructions and not shutil.which("valgrind"):
        fail("--instructions needs valgrind (Debian: apt install valgrind; deploy/install-deps.sh installs it)")
    if args.frames < 0:
        fail("--frames must be >= 0")
    benches = {"A": bench_path(args.a), "B": bench_path(args.b)}
    cases = args.case or list(CASES)
    results = {(c, s): [] for c in cases for s in benches}
    failed = False
    for r in range(1, args.rounds + 1):
        got, bad = measure_all(cases, benches, lambda b, c: run(b, c, args.frames, args.bench_arg), f"round {r}",
                               lambda res: f"{res['hz']:.0f} Hz, p99 {res['p99_ms']:.2f} ms, hash {res['hash']}, "
                                           f"penetration {res['pen_mm']:.3f} mm, {plausibility(res)}")
        failed = failed or bad
        for key, res in got.items():
            results[key].append(res)
    counts = {}
    if args.instructions:
        got, bad = measure_all(cases, benches, lambda b, c: instructions(b, c, args.frames, args.bench_arg),
                               "instructions", lambda res: f"{res['ir']:,}")
        failed = failed or bad
        counts = {key: res["ir"] for key, res in got.items()}
        print("\ncase | A instructions | B instructions | B against A")
        for case in cases:
            a, b = counts.get((case, "A")), counts.get((case, "B"))
            if a is None or b is None:
                print(f"{case} | no count on both sides")
                continue
            print(f"{case} | {a:,} | {b:,} | {100.0 * (b - a) / a:+.1f} %")
    if args.rounds == 0:
        return 1 if failed else 0
    print("\ncase | A Hz | B Hz | A p99 ms | B p99 ms | hashes")
    differ = False
    for case in cases:
        a, b = results[(case, "A")], results[(case, "B")]
        if not a or not b:
            print(f"{case} | no complete run on both sides")
            continue
        ha, hb = {x["hash"] for x in a}, {x["hash"] for x in b}
        same = ha == hb and len(ha) == 1
        differ = differ or not same
        hashes = f"same ({next(iter(ha))})" if same else f"A {' '.join(sorted(ha))} / B {' '.join(sorted(hb))}"
        print(f"{case} | {span([x['hz'] for x in a], '{:,.0f}')} | {span([x['hz'] for x in b], '{:,.0f}')} | "
              f"{span([x['p99_ms'] for x in a], '{:.2f}')} | {span([x['p99_ms'] for x in b], '{:.2f}')} | {hashes}")
    # Beside the speed, the plausibility of each side (the same for every round of a deterministic
    # build: its first run's figures; see the run lines for every round).
    print("\ncase | A plausibility | B plausibility")
    for case in cases:
        a, b = results[(case, "A")], results[(case, "B")]
        if a and b:
            print(f"{case} | {plausibility(a[0])} | {plausibility(b[0])}")
    if failed:
        print("ab: some runs failed")
        return 1
    if args.check_same_hash:
        print("ab: hashes differ" if differ else "ab: same hashes")
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
