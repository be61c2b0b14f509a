#!/usr/bin/env python3
"""godhand-sweep: the speed/accuracy trade of the method, measured (issue 14, a sibling of
godhand-bench). Runs godhand-bench over a grid of knobs on one recording and scene, one point
after another in the same run, and reports for every point what it costs (frames/s median, step
p99) and what it buys (penetration against the full meshes, excess lag, frozen windows, joint
gap, KKT residual); marks the Pareto front (no other point is at least as fast, as deep and as
laggy and better in one); with --target, names the fastest point within the stated bounds.

usage: godhand-bench --sweep GRID.pbtxt --recording FILE [--mesh FILE[:SIZE] ... | --scene FILE|none] ...
       sweep.py --recording FILE [--mesh FILE[:SIZE] ... | --scene FILE|none] [--grid GRID.pbtxt|GRID.json]
                [--bench build/bin/godhand-bench] [--frames N] [--repeat N] [--json OUT] [--plot OUT.png]
                [--target "penetration_max_m<=1e-4,excess_lag_p95_m<=3e-3"]

--repeat N runs every point N times (one after the other) and takes the median of each timing
figure (frames/s, step and stage times); the other figures are the run's own, and every repeat
must give the same result hash (else the point fails: not deterministic).

GRID.pbtxt (idl/sweep.proto): `mode: EACH | PRODUCT` and `knobs { option: "--substeps" values: "1"
values: "3" }`; or GRID.json: {"mode": "each" | "product", "knobs": {"--substeps": ["1", "2"], ...}}.
"each" varies one knob at a time from godhand-bench's defaults (the first point is the defaults);
"product" runs every combination. The shipped grid is deploy/sweeps/default.pbtxt. Each value is passed as
godhand-bench's option value; a value with spaces is split into several arguments
("pgs --pgs-iterations 100" under "--solver"; the 6-body hands under "--hand-model" also set
--left-hand-model; paths are relative to the current directory, the project root). Points of
"--god-fidelity" (full, hull, decimated:N, auto:MM; penetration still against the full mesh) apply
to the --mesh objects or to the scene file's mesh objects; they are left out with --scene none.

Exit status: 0 ok (also when no point meets --target: it says so), 1 a point's run failed,
2 bad arguments. Progress on stderr."""
import argparse
import itertools
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))

# What a point buys and costs: (name in the output, path in godhand-bench's JSON, smaller is better).
FIGURES = [
    ("hz_median", ("hz_median",), False),
    ("step_median_us", ("step_us", "median"), True),
    ("step_p99_us", ("step_us", "p99"), True),
    ("penetration_max_m", ("penetration_max_m",), True),
    ("excess_lag_median_m", ("plausibility", "all", "excess_lag_m", "median"), True),
    ("excess_lag_p95_m", ("plausibility", "all", "excess_lag_m", "p95"), True),
    ("excess_lag_above_5mm", ("plausibility", "all", "excess_lag_above_5mm"), True),
    ("frozen_windows", ("plausibility", "all", "frozen_windows"), True),
    ("moving_windows", ("plausibility", "all", "moving_windows"), False),
    ("stuck_frames", ("plausibility", "all", "stuck_frames"), True),
    ("joint_gap_max_m", ("joint_gap_max_m",), True),
    ("kkt_residual_max", ("kkt_residual_max",), True),
    # The God hand's distance to the full-resolution surface while it touches the God side (what a
    # coarser God mesh costs in accuracy; ~the contact margin with full meshes).
    ("contact_gap_median_m", ("contact_gap_m", "median"), True),
    ("contact_gap_p95_m", ("contact_gap_m", "p95"), True),
    ("contact_gap_max_m", ("contact_gap_m", "max"), True),
    ("god_triangles", ("triangles",), False),
    ("stage_contacts_us", ("stages_us", "contacts"), False),
    ("stage_solve_us", ("stages_us", "solve"), False),
    ("stage_integrate_us", ("stages_us", "integrate"), False),
    ("stage_ccd_us", ("stages_us", "ccd"), False),
    ("stage_scene_us", ("stages_us", "scene"), False),
]
# Per-point step-time breakdown (median us per stage, godhand-bench's stages_us) for the plot.
STAGES = (("stage_contacts_us", "contacts"), ("stage_solve_us", "solve"), ("stage_integrate_us", "integrate + projection"),
          ("stage_ccd_us", "sweeps (CCD)"), ("stage_scene_us", "scene"))
# Figures measured by the clock (the median of --repeat runs); the others are deterministic.
TIMINGS = {"hz_median", "step_median_us", "step_p99_us", "stage_contacts_us", "stage_solve_us", "stage_integrate_us",
           "stage_ccd_us", "stage_scene_us"}
# The Pareto front is over these (all minimised): time, depth, lag.
PARETO = ("step_median_us", "penetration_max_m", "excess_lag_p95_m")


def fail(msg):
    print(f"godhand-sweep: {msg}", file=sys.stderr)
    sys.exit(2)


def dig(d, path):
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def points_of(grid):
    knobs = grid.get("knobs", {})
    if not isinstance(knobs, dict) or not all(isinstance(v, list) and v for v in knobs.values()):
        fail("grid: 'knobs' must map option names to non-empty lists of values")
    for k, vs in knobs.items():
        if not k.startswith("--"):
            fail(f"grid: knob {k!r} is not a godhand-bench option (--...)")
        for v in vs:
            if not isinstance(v, (str, int, float)):
                fail(f"grid: {k}: value {v!r} is not a string or number")
    mode = grid.get("mode", "each")
    if mode == "each":
        pts = [{}]
        for k, vs in knobs.items():
            pts += [{k: str(v)} for v in vs]
        return pts
    if mode == "product":
        names = list(knobs)
        return [dict(zip(names, map(str, combo))) for combo in itertools.product(*(knobs[n] for n in names))]
    fail(f"grid: mode must be 'each' or 'product', got {mode!r}")


def dominates(a, b):
    """a is at least as good as b in every Pareto figure and better in one."""
    va = [a[f] for f in PARETO]
    vb = [b[f] for f in PARETO]
    return all(x <= y for x, y in zip(va, vb)) and any(x < y for x, y in zip(va, vb))


def pareto(points):
    ok = [i for i, p in enumerate(points) if all(p.get(f) is not None for f in PARETO)]
    return [i for i in ok if not any(dominates(points[j], points[i]) for j in ok if j != i)]


def parse_target(text):
    bounds = []
    for part in [p.strip() for p in text.split(",") if p.strip()]:
        m = re.fullmatch(r"([a-z0-9_]+)\s*(<=|>=)\s*([-+0-9.eE]+)", part)
        if not m:
            fail(f"--target: expected FIGURE<=VALUE or FIGURE>=VALUE, got {part!r}")
        name, op, value = m.group(1), m.group(2), float(m.group(3))
        if name not in [f[0] for f in FIGURES]:
            fail(f"--target: unknown figure {name!r} (known: {', '.join(f[0] for f in FIGURES)})")
        bounds.append((name, op, value))
    if not bounds:
        fail("--target: no bounds")
    return bounds


def meets(p, bounds):
    for name, op, value in bounds:
        v = p.get(name)
        if v is None or (op == "<=" and not v <= value) or (op == ">=" and not v >= value):
            return False
    return True


def gap_text(p):
    g = [p.get(f"contact_gap_{k}_m") for k in ("median", "p95", "max")]
    return "-" if any(v is None for v in g) else "/".join(f"{v * 1e3:.2f}" for v in g)


def knob_text(knobs):
    return " ".join(f"{k} {v}" for k, v in knobs.items()) or "(defaults)"


def plot(points, front, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        fail("--plot needs matplotlib (Debian: apt install python3-matplotlib, for /usr/bin/python3)")
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    for ax, (fig_name, label) in zip(axes, (("excess_lag_p95_m", "excess lag p95 (mm)"), ("penetration_max_m", "penetration max (mm)"))):
        for i, p in enumerate(points):
            y = p.get(fig_name)
            if y is None:
                continue
            ax.scatter(p["hz_median"], y * 1e3, c="C3" if i in front else "C0", s=40 if i in front else 18, zorder=3)
            ax.annotate(str(i), (p["hz_median"], y * 1e3), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.set_xlabel("frames/s (median)")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].set_title("red: Pareto front (time, penetration, lag)", fontsize=9)
    # Step-time breakdown per point: the stages' medians stacked (their sum is not the step's
    # median, which is of the sums).
    ax = axes[2]
    bottom = [0.0] * len(points)
    for k, (name, label) in enumerate(STAGES):
        vals = [(p.get(name) or 0.0) / 1e3 for p in points]
        ax.bar(range(len(points)), vals, bottom=bottom, label=label, color=f"C{k}")
        bottom = [b + v for b, v in zip(bottom, vals)]
    ax.set_xticks(range(len(points)))
    ax.set_xlabel("point")
    ax.set_ylabel("median per stage (ms)")
    ax.set_title("step-time breakdown per point", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(prog="godhand-sweep", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--recording", required=True, help="tracker recording (any format godhand-bench reads)")
    ap.add_argument("--mesh", action="append", default=[], help="FILE[:SIZE_M], as godhand-bench --mesh (repeatable)")
    ap.add_argument("--scene", help="scene file or none, as godhand-bench --scene")
    ap.add_argument("--grid", default=os.path.join(ROOT, "deploy", "sweeps", "default.pbtxt"),
                    help="the grid: protobuf text (idl/sweep.proto, read through godhand-bench) or JSON; default deploy/sweeps/default.pbtxt")
    ap.add_argument("--bench", default=os.path.join(ROOT, "build", "bin", "godhand-bench"), help="godhand-bench to run")
    ap.add_argument("--frames", type=int, default=0, help="only the first N frames of the recording")
    ap.add_argument("--repeat", type=int, default=1, help="runs per point; timing figures are their medians (default 1)")
    ap.add_argument("--json", help="write the points and the Pareto front here")
    ap.add_argument("--plot", help="draw frames/s against lag and penetration (PNG/SVG; needs matplotlib)")
    ap.add_argument("--target", help="bounds, e.g. penetration_max_m<=1e-4,excess_lag_p95_m<=3e-3: the fastest point within them")
    a = ap.parse_args()
    if a.mesh and a.scene:
        fail("--mesh and --scene exclude each other")
    if not os.access(a.bench, os.X_OK):
        fail(f"no godhand-bench at {a.bench} (build first, or --bench PATH)")
    if a.frames < 0:
        fail("--frames must be >= 0")
    if not 1 <= a.repeat <= 100:
        fail("--repeat must be in [1, 100]")
    bounds = parse_target(a.target) if a.target else None
    if a.grid.endswith(".pbtxt"):
        # The grid's text format (idl/sweep.proto) is parsed and checked by godhand-bench itself.
        r = subprocess.run([a.bench, "--print-sweep-grid", a.grid], capture_output=True, text=True)
        if r.returncode != 0:
            fail((r.stderr.strip().splitlines() or [f"godhand-bench --print-sweep-grid exit {r.returncode}"])[-1])
        grid = json.loads(r.stdout)
    else:
        try:
            grid = json.load(open(a.grid))
        except (OSError, ValueError) as e:
            fail(f"{a.grid}: {e}".replace("\n", " "))
    pts = points_of(grid)
    if not a.mesh and a.scene == "none":  # --god-fidelity changes meshes: none there
        kept = [k for k in pts if "--god-fidelity" not in k]
        if len(kept) < len(pts):
            print(f"godhand-sweep: {len(pts) - len(kept)} --god-fidelity point(s) left out: --scene none has no meshes", file=sys.stderr)
        pts = kept

    base = [a.bench, "--recording", a.recording, "--quiet"] + [x for m in a.mesh for x in ("--mesh", m)]
    if a.scene:
        base += ["--scene", a.scene]
    if a.frames:
        base += ["--frames", str(a.frames)]
    points, failed = [], 0
    with tempfile.TemporaryDirectory(prefix="godhand-sweep-") as tmp:
        for i, knobs in enumerate(pts):
            out = os.path.join(tmp, f"{i}.json")
            args = [x for k, v in knobs.items() for x in [k] + v.split()]
            t0 = time.time()
            p = {"knobs": knobs, "args": args}
            runs = []
            for _ in range(a.repeat):
                if os.path.exists(out):
                    os.remove(out)
                r = subprocess.run(base + args + ["--json", out], capture_output=True, text=True)
                if r.returncode != 0 or not os.path.exists(out):
                    last = (r.stderr.strip() or r.stdout.strip()).splitlines()[-1:] or ["no output"]
                    p["error"] = f"exit {r.returncode}: {last[0]}"
                    break
                runs.append(json.load(open(out)))
            if "error" not in p and len({j.get("result_hash") for j in runs}) != 1:
                p["error"] = f"not deterministic: result hashes {sorted({str(j.get('result_hash')) for j in runs})} over {a.repeat} runs"
            if "error" in p:
                failed += 1
            else:
                j = runs[0]
                for name, path, _ in FIGURES:
                    p[name] = dig(j, path)
                    if name in TIMINGS and len(runs) > 1 and p[name] is not None:
                        p[name] = statistics.median(dig(x, path) for x in runs)
                p["result_hash"] = j.get("result_hash")
                p["repeats"] = len(runs)
            points.append(p)
            print(f"godhand-sweep: point {i + 1}/{len(pts)} {knob_text(knobs)}: "
                  + (p["error"] if "error" in p else f"{p['hz_median']:.0f} Hz, penetration {p['penetration_max_m'] * 1e3:.3f} mm, "
                     f"excess lag p95 {p['excess_lag_p95_m'] * 1e3:.2f} mm") + f" ({time.time() - t0:.1f} s)", file=sys.stderr)
    front = pareto(points)

    print(f"{'#':>2} {'Hz':>6} {'p99 ms':>7} {'pen mm':>7} {'lag p95 mm':>10} {'>5mm':>5} {'frozen':>9} {'stuck':>5} {'gap m':>8} "
          f"{'God tris':>9} {'touch gap mm (med/p95/max)':>26}  knobs")
    for i, p in enumerate(points):
        if "error" in p:
            print(f"{i:>2} failed: {p['error']}  {knob_text(p['knobs'])}")
            continue
        print(f"{i:>2} {p['hz_median']:6.0f} {p['step_p99_us'] / 1e3:7.2f} {p['penetration_max_m'] * 1e3:7.3f} "
              f"{p['excess_lag_p95_m'] * 1e3:10.2f} {p['excess_lag_above_5mm']:5d} {p['frozen_windows']:4d}/{p['moving_windows']:<4d} "
              f"{p['stuck_frames']:5d} {p['joint_gap_max_m']:8.1e} {p['god_triangles']:9d} {gap_text(p):>26}  "
              f"{knob_text(p['knobs'])}{'  *' if i in front else ''}")
    print("* Pareto front (time, penetration, excess lag p95: no other point is at least as good in all three and better in one)")
    chosen = None
    if bounds:
        within = [i for i, p in enumerate(points) if "error" not in p and meets(p, bounds)]
        if within:
            chosen = min(within, key=lambda i: points[i]["step_median_us"])
            print(f"target: point {chosen} is the fastest within {a.target}: godhand-bench options "
                  f"{' '.join(points[chosen]['args']) or '(the defaults)'}")
        else:
            print(f"target: no measured point meets {a.target}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"recording": a.recording, "mesh": a.mesh, "scene": a.scene, "frames": a.frames, "repeat": a.repeat, "grid": grid,
                       "points": points, "pareto": front, "pareto_figures": list(PARETO),
                       "target": a.target, "target_point": chosen}, f, indent=2)
    if a.plot:
        plot(points, front, a.plot)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
