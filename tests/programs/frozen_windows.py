#!/usr/bin/env python3
"""godhand-bench's frozen-window count, re-measured from its --poses files, on a recording with
tracking dropouts.

  frozen_windows.py BENCH RECORDING MESH[:SIZE]

Every 23rd frame from the 5th loses its palm (null), every 23rd from the 11th its hands: the
frames around them are still frames of the run. A window is frame k and frame k - 5 of one hand,
both with God poses and twin poses (the same hand against `--scene none`); it moves when some
twin body moved > 2 mm, and is frozen when no God body moved 0.05 mm. The bench's own counts
(JSON moving_windows / frozen_windows) must equal the ones computed here (before, each dropout
ended the bench's windows: 13 moving windows of pinch's 160). Exit 0 when they do."""
import collections, copy, csv, json, math, os, subprocess, sys, tempfile

if len(sys.argv) != 4:
    sys.exit(__doc__.strip().split("\n\n")[1])
bench, recording, mesh = sys.argv[1:4]
d = tempfile.mkdtemp(prefix="godhand-frozen-")
rec = json.load(open(recording))
frames = rec["frames"] if isinstance(rec, dict) else rec
for k, fr in enumerate(frames):
    if not fr.get("hands"):
        continue
    if k % 23 == 5:
        fr["hands"][0]["palmPosition"] = [None, None, None]
    elif k % 23 == 11:
        fr["hands"] = []
        fr["pointables"] = []
rec_path = os.path.join(d, "dropouts.json")
json.dump(rec, open(rec_path, "w"))


def run(*args):
    r = subprocess.run([bench, "--recording", rec_path, "--quiet", *args], capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        sys.exit(f"frozen windows: bench failed: {r.stdout.strip().splitlines()[-1:]} {r.stderr.strip()}")


run("--mesh", mesh, "--poses", os.path.join(d, "god.csv"), "--json", os.path.join(d, "god.json"))
run("--scene", "none", "--poses", os.path.join(d, "twin.csv"))


def load(p):
    out = collections.defaultdict(dict)
    for r in csv.DictReader(open(p)):
        out[(r["hand"], int(r["frame"]))][r["body"]] = [float(r[c]) for c in ("px", "py", "pz")]
    return out


S, T = load(os.path.join(d, "god.csv")), load(os.path.join(d, "twin.csv"))
moving = frozen = 0
for (h, k) in S:
    a, b = (h, k - 5), (h, k)
    if a in S and a in T and b in T:
        if max(math.dist(T[b][x], T[a][x]) for x in T[b] if x in T[a]) > 2e-3:
            moving += 1
            frozen += max(math.dist(S[b][x], S[a][x]) for x in S[b] if x in S[a]) < 5e-5
j = json.load(open(os.path.join(d, "god.json")))
mine, theirs = (frozen, moving), (j["frozen_windows"], j["moving_windows"])
print(f"frozen windows: here {frozen} of {moving} moving, bench {theirs[0]} of {theirs[1]} ({len(frames)} frames)")
fail = []
if mine != theirs:
    fail.append("the bench's counts differ from the --poses files'")
if moving == 0:
    fail.append("no moving window to count")
print("frozen windows: " + ("ok" if not fail else "FAILED: " + "; ".join(fail)))
sys.exit(1 if fail else 0)
