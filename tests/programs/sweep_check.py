#!/usr/bin/env python3
"""godhand-sweep (services/bench/sweep.py) on a short real run: every point of a small grid is
measured by godhand-bench, the Pareto front equals a brute-force recomputation here, --target
picks the fastest point within its bounds (checked against every point), a failing point is a
failure (exit 1) with its reason, and a bad grid is a one-line error (exit 2).
usage: sweep_check.py SWEEP BENCH RECORDING"""
import json
import os
import subprocess
import sys
import tempfile

SWEEP, BENCH, REC = sys.argv[1:4]
TMP = tempfile.mkdtemp(prefix="godhand-sweep-test-")
failures = []


def check(ok, what):
    print(("ok:     " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


def sweep(grid, extra):
    path = os.path.join(TMP, "grid.json")
    open(path, "w").write(grid if isinstance(grid, str) else json.dumps(grid))
    out = os.path.join(TMP, "out.json")
    if os.path.exists(out):
        os.remove(out)
    cmd = [sys.executable, SWEEP, "--bench", BENCH, "--recording", REC, "--frames", "60", "--grid", path, "--json", out] + extra
    print("$ " + " ".join(cmd), flush=True)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    print(r.stdout + r.stderr)
    return r, (json.load(open(out)) if os.path.exists(out) else {})


grid = {"mode": "product", "knobs": {"--substeps": ["1", "2"], "--contact-rotation": ["0.05", "0.25"]}}
r, j = sweep(grid, ["--target", "penetration_max_m<=1e-4,frozen_windows<=100"])
check(r.returncode == 0, f"the sweep ran (exit {r.returncode})")
pts = j.get("points", [])
check(len(pts) == 4, f"4 points for a 2 x 2 product ({len(pts)})")
need = ["hz_median", "step_median_us", "step_p99_us", "penetration_max_m", "excess_lag_p95_m", "joint_gap_max_m", "frozen_windows"]
check(all(all(isinstance(p.get(k), (int, float)) for k in need) for p in pts), "every point has its figures")
check(len({tuple(sorted(p["knobs"].items())) for p in pts}) == 4, "the 4 points have different knobs")
check(len({p.get("result_hash") for p in pts}) >= 2, "the knobs change the result (result hashes differ)")
F = j.get("pareto_figures", [])
check(F == ["step_median_us", "penetration_max_m", "excess_lag_p95_m"], f"the front is over time, depth, lag ({F})")
front = [i for i, p in enumerate(pts)
         if not any(all(q[f] <= p[f] for f in F) and any(q[f] < p[f] for f in F) for k, q in enumerate(pts) if k != i)]
check(sorted(j.get("pareto", [])) == front and front, f"the Pareto front {j.get('pareto')} is the brute-force one {front}")
within = [i for i, p in enumerate(pts) if p["penetration_max_m"] <= 1e-4 and p["frozen_windows"] <= 100]
best = min(within, key=lambda i: pts[i]["step_median_us"]) if within else None
check(j.get("target_point") == best, f"--target picked point {j.get('target_point')}, the fastest within the bounds is {best}")
check("target: point" in r.stdout, "the target's point is printed with its options")

r, j = sweep({"mode": "each", "knobs": {"--stop-distance": ["1e-3"]}}, [])
check(r.returncode == 1 and "failed" in r.stdout and "stop_distance" in r.stdout,
      f"a point godhand-bench refuses is a failed point with its reason, exit 1 ({r.returncode})")
check(len(j.get("points", [])) == 2 and "error" in j["points"][1], "the failed point is in the JSON with its error")

r, _ = sweep('{"mode": "each", "knobs": {"substeps": ["1"]}}', [])
err = r.stderr.strip().splitlines()
check(r.returncode == 2 and len(err) == 1 and "not a godhand-bench option" in err[0], f"a bad grid is one line, exit 2 ({err})")
r, _ = sweep('{"mode": "each", "knobs": {', [])
check(r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, "a grid that is not JSON is one line, exit 2")
r, _ = sweep(grid, ["--target", "speed>=3"])
check(r.returncode == 2 and "unknown figure" in r.stderr, "an unknown --target figure is refused")

print("PASSED" if not failures else f"{len(failures)} check(s) FAILED")
sys.exit(1 if failures else 0)
