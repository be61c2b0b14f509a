#!/usr/bin/env python3
"""godhand-bench's jitter figure, re-measured from its --poses file, and bounded.

  jitter.py BENCH RECORDING MESH[:SIZE] MAX_PERCENT

Jitter (run_metrics.h): a body whose motion from one frame to the next (> 0.1 mm) turns back by
more than 120 degrees against its motion of the frame before (also > 0.1 mm). Counted here over
every hand and body with three consecutive frames in the --poses file; the bench's own counts
(JSON jitter_body_frames / jitter_checked) must equal them, and the turning body-frames must be
at most MAX_PERCENT % of the checked ones. (Before the rotation trust region, a palm pressed onto
the bunny rocked about one contact and back every frame: 2418 of 4880 body-frames of pinch,
its fingertips 1-3 mm apart from frame to frame.) Exit 0 when both hold."""
import collections, csv, json, math, os, subprocess, sys, tempfile

if len(sys.argv) != 5:
    sys.exit(__doc__.strip().split("\n\n")[1])
bench, recording, mesh, max_percent = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
d = tempfile.mkdtemp(prefix="godhand-jitter-")
poses, report = os.path.join(d, "god.csv"), os.path.join(d, "god.json")
r = subprocess.run([bench, "--recording", recording, "--mesh", mesh, "--quiet", "--poses", poses, "--json", report],
                   capture_output=True, text=True, timeout=600)
if r.returncode != 0:
    sys.exit(f"jitter: bench failed: {r.stdout.strip().splitlines()[-1:]} {r.stderr.strip()}")

P = collections.defaultdict(dict)  # (hand, frame) -> body -> position
for row in csv.DictReader(open(poses)):
    P[(row["hand"], int(row["frame"]))][row["body"]] = [float(row[c]) for c in ("px", "py", "pz")]
checked = turned = 0
for (h, k), bodies in P.items():
    a, b = P.get((h, k - 2)), P.get((h, k - 1))
    if a is None or b is None:
        continue
    for name, c in bodies.items():
        if name not in a or name not in b:
            continue
        e = [b[name][i] - a[name][i] for i in range(3)]
        f = [c[i] - b[name][i] for i in range(3)]
        ne, nf = math.hypot(*e), math.hypot(*f)
        checked += 1
        if ne > 1e-4 and nf > 1e-4 and sum(x * y for x, y in zip(e, f)) < -0.5 * ne * nf:
            turned += 1
j = json.load(open(report))
theirs = (j["jitter_body_frames"], j["jitter_checked"])
share = 100.0 * turned / max(checked, 1)
print(f"jitter: here {turned} of {checked} body-frames ({share:.1f} %), bench {theirs[0]} of {theirs[1]}, "
      f"free twin {j['twin_jitter_body_frames']}; frozen {j['frozen_windows']} of {j['moving_windows']} windows")
fail = []
if (turned, checked) != theirs:
    fail.append("the bench's counts differ from the --poses file's")
if checked == 0:
    fail.append("no body-frame to check")
if share > max_percent:
    fail.append(f"more than {max_percent:g} % of the body-frames turn back")
print("jitter: " + ("ok" if not fail else "FAILED: " + "; ".join(fail)))
sys.exit(1 if fail else 0)
