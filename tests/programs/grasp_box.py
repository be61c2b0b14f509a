#!/usr/bin/env python3
"""Grasp a box between two hands, end to end (issue 11): godhand-bench (source, retargeting,
solver, sweeps, Bullet) on tests/data/synthetic/grasp_box.txt against grasp_box.pbtxt. Checks the
method's bounds (penetration within the contact margin, joint gap <= 1e-6 m, no solver failure),
that the script is deterministic (the same result hash twice), and what the box does, from the
report's dynamic_objects (Bullet's pose after every frame): the hands reach and push it, it is not
launched, and it is NOT lifted: God-hand contacts carry normal forces only (-lambda n, no
friction), so two palms squeezing vertical sides cannot hold it up while they rise 5 cm. That
last check documents the limitation: if a change makes the lift work, it fails, and the README's
figures and this check are to be updated. The report field itself is checked on a box dropped
5 cm onto the table (before the hands arrive): it falls 5 cm at sqrt(2 g h).

usage: grasp_box.py BENCH_BIN DATA_DIR"""
import json
import math
import os
import subprocess
import sys
import tempfile

BENCH, DATA = sys.argv[1], sys.argv[2]
SCRIPT, SCENE = os.path.join(DATA, "grasp_box.txt"), os.path.join(DATA, "grasp_box.pbtxt")
TMP = tempfile.mkdtemp(prefix="godhand-grasp-")
failures = []


def check(ok, what):
    print(("ok:     " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


def bench(name, scene, *extra):
    out = os.path.join(TMP, name + ".json")
    r = subprocess.run([BENCH, "--recording", SCRIPT, "--scene", scene, "--json", out, "--quiet", *extra],
                       capture_output=True, text=True, timeout=240)
    sys.stdout.write(r.stdout)
    check(r.returncode == 0, f"{name}: exit {r.returncode} {r.stderr.strip()}")
    return json.load(open(out))


def box_of(j):
    boxes = [o for o in j["dynamic_objects"] if o["id"] == "box"]
    check(len(boxes) == 1, "the report has the box's motion")
    return boxes[0]


j = bench("grasp", SCENE, "--check")  # --check: also no frozen hand (<= 5 % of moving windows)
b = box_of(j)
start, final = b["start_position_m"], b["final_position_m"]
print(f"grasp: penetration max {j['penetration_max_m'] * 1e3:.4f} mm, joint gap {j['joint_gap_max_m']:.2e} m, "
      f"box start {start} end {final}, rose at most {b['max_rise_m'] * 1e3:.2f} mm, farthest "
      f"{b['max_displacement_m'] * 1e3:.1f} mm, speed max {b['max_speed_mps']:.3f} m/s, "
      f"squeezed-object restores {j['scene_pushouts_restored']}")
check(j["hands"] == 2, "two hands (right and left)")
check(j["penetration_max_m"] <= j["margin_m"], f"penetration {j['penetration_max_m']:.3g} m within the margin {j['margin_m']} m")
check(j["joint_gap_max_m"] <= 1e-6, f"joint gap {j['joint_gap_max_m']:.3g} m <= 1e-6 m")
check(j["solver_failures"] == 0, "no solver failure")
check(b["simulated"], "the box is simulated")
# A box standing alone does not move at all; squeezed by two frictionless hands it is pushed, and
# how far depends on which side slips first: 12 mm at commit 64f38f5, 5-54 mm under small changes
# of the round rules on 2026-12-04, 6 mm with the rules adopted then. So: moved, by more than 2 mm.
check(b["max_displacement_m"] > 0.002, f"the hands reached the box and pushed it ({b['max_displacement_m'] * 1e3:.1f} mm > 2 mm)")
# Frictionless curling fingers squirt the box out along -Y (~10 cm; peak 0.84 m/s before the
# 2026-12-02 round-progress change, 1.24 m/s after it, when the hands stopped freezing on it and
# hold it harder). A launch is faster than that: the squeeze bug this guards against flew off at
# 1.5 m/s with the box inside a hand (caught by the penetration check too).
check(b["max_speed_mps"] < 1.45, f"the box is not launched (speed max {b['max_speed_mps']:.3f} < 1.45 m/s)")
check(abs(final[2] - start[2]) < 1e-3, "the box ends standing on the table (its height within 1 mm of the start)")
# The limitation, measured: the hands rise 5 cm with the box between them, the box does not.
# A squeeze may wedge it up a little; lifted would be following the hands: half their rise or more.
check(b["max_rise_m"] < 0.025, f"NOT lifted: the box rose {b['max_rise_m'] * 1e3:.2f} mm (< 25 mm, half the hands' 50 mm) "
      "(frictionless God contacts; see README)")
again = bench("grasp-again", SCENE)
check(again.get("result_hash") == j.get("result_hash") and again["dynamic_objects"] == j["dynamic_objects"],
      f"deterministic: result hash {j.get('result_hash')} and the box's motion twice")

# The report field on a known motion: the box 5 cm above the table falls onto it in the first
# second, while the hands turn and approach (still 3 cm off its sides at frame 100).
drop = open(SCENE).read().replace("position { x: 0 y: 0.03 z: 0.195 }", "position { x: 0 y: 0.03 z: 0.245 }")
check("z: 0.245" in drop, "drop scene written")
drop_scene = os.path.join(TMP, "drop.pbtxt")
open(drop_scene, "w").write(drop)
d = box_of(bench("drop", drop_scene, "--frames", "100"))
v = math.sqrt(2 * 9.81 * 0.05)
print(f"drop: fell {d['max_drop_m'] * 1e3:.2f} mm, ends at z {d['final_position_m'][2]:.4f} m, speed max {d['max_speed_mps']:.3f} m/s "
      f"(free fall from 5 cm: {v:.3f} m/s)")
check(abs(d["max_drop_m"] - 0.05) < 1e-3, "the dropped box falls 5 cm (within 1 mm)")
check(abs(d["final_position_m"][2] - 0.195) < 1e-3, "and rests on the table")
check(abs(d["max_speed_mps"] - v) < 0.1 * v, "at the free-fall speed (within 10 %)")
n = box_of(bench("no-physics", SCENE, "--no-physics"))
check(not n["simulated"] and n["max_displacement_m"] == 0.0 and n["final_position_m"] == n["start_position_m"],
      "--no-physics: the box is reported unmoved, not simulated")
print("PASSED" if not failures else f"FAILED: {len(failures)} check(s)")
sys.exit(1 if failures else 0)
