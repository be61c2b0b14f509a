#!/usr/bin/env python3
"""Writes pinch_head_v2.csv: the first 8 frames of deploy/recordings/pinch.json (right hand) in the
column layout of Project Aria MPS hand_tracking_results_v2.csv (projectaria_tools
core/mps/HandTrackingReader.cpp), device frame = godhand's tracker frame T (Leap (x, y, z) mm ->
(x, -z, y) / 1000 m). The left hand is not tracked (confidence -1). Wrist poses and palm normals
are written as zeros (godhand ignores them). Aria has no thumb CMC; the Leap one is dropped.
usage: make_aria.py [PINCH_JSON] > pinch_head_v2.csv"""
import json
import os
import sys

here = os.path.dirname(os.path.abspath(__file__))
src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "../../../deploy/recordings/pinch.json")
frames = json.load(open(src))["frames"][:8]


def t(p):
    return (p[0] / 1000.0, -p[2] / 1000.0, p[1] / 1000.0)


cols = ["tracking_timestamp_us"]
for side in ("left", "right"):
    cols.append(side + "_tracking_confidence")
    cols += ["t%s_%s_landmark_%d_device" % (a, side, i) for i in range(21) for a in "xyz"]
for side in ("left", "right"):
    cols += ["%s_%s_device_wrist" % (a, side) for a in ("tx", "ty", "tz", "qx", "qy", "qz", "qw")]
for side in ("left", "right"):
    for what in ("palm", "wrist"):
        cols += ["n%s_%s_%s_device" % (a, side, what) for a in "xyz"]
print(",".join(cols))
for f in frames:
    hand = [h for h in f["hands"] if h["type"] == "right"][0]
    fingers = {p["type"]: p for p in f["pointables"] if p.get("handId") == hand["id"]}
    palm = t(hand["palmPosition"])
    mid_mcp = t(fingers[2]["mcpPosition"])
    wrist = tuple(2 * palm[k] - mid_mcp[k] for k in range(3))  # palm centre = midpoint wrist / middle MCP
    lm = [None] * 21
    for i in range(5):
        lm[i] = t(fingers[i]["tipPosition"])
    lm[5] = wrist
    lm[6] = t(fingers[0]["pipPosition"])   # thumb MCP (Leap's thumb pip)
    lm[7] = t(fingers[0]["dipPosition"])   # thumb IP
    for k, finger in enumerate((1, 2, 3, 4)):
        lm[8 + 3 * k] = t(fingers[finger]["mcpPosition"])
        lm[9 + 3 * k] = t(fingers[finger]["pipPosition"])
        lm[10 + 3 * k] = t(fingers[finger]["dipPosition"])
    lm[20] = palm
    row = [str(f["timestamp"])]
    row += ["-1"] + ["0"] * 63
    row += ["%.6f" % hand["confidence"]] + ["%.9f" % c for p in lm for c in p]
    row += ["0"] * 26
    print(",".join(row))
