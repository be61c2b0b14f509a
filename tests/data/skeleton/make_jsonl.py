#!/usr/bin/env python3
"""Writes pinch_openxr.jsonl, pinch_openxr_tool.jsonl and pinch_mediapipe.jsonl: the first 80 frames of
deploy/recordings/pinch.json (the right hand) in godhand's OpenXR and MediaPipe JSON Lines formats
(bridges/README.md), for the lock-step lab runs of tests/programs/sources.py (formats case).
Leap's device frame (mm, +Y up, right-handed) has OpenXR's axes, so an OpenXR joint is the Leap
point / 1000; MediaPipe's camera frame (x right, y down, z forward) is (x, -y, -z) / 1000, relative
to the wrist (written as the origin). Joints OpenXR has and Leap does not: the wrist (2 palm -
middle MCP) and the four metacarpal joints (midway wrist -> MCP). Only positions are written
(flags 0xA: position valid and tracked), so the palm frame comes from the bones.
pinch_openxr_tool.jsonl also carries a 6-DOF body (id 1, flags 0xF): a controller held 8 cm above
the palm, turned a little more each frame about the vertical, for a lab's tool cluster
(tracker_body 1; tests/data/lab/tool_openxr.pbtxt).
usage: make_jsonl.py [PINCH_JSON] [OUT_DIR]"""
import json
import os
import sys

here = os.path.dirname(os.path.abspath(__file__))
src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "../../../deploy/recordings/pinch.json")
out = sys.argv[2] if len(sys.argv) > 2 else here
frames = json.load(open(src))["frames"][:80]


def xr(p):
    return [p[0] / 1000.0, p[1] / 1000.0, p[2] / 1000.0]


def cam(p):
    return [p[0] / 1000.0, -p[1] / 1000.0, -p[2] / 1000.0]


def mid(a, b):
    return [(a[k] + b[k]) / 2.0 for k in range(3)]


def fmt(v):
    return "[" + ",".join("%.9f" % c for c in v) + "]"


import math

with open(os.path.join(out, "pinch_openxr.jsonl"), "w") as a, open(os.path.join(out, "pinch_mediapipe.jsonl"), "w") as b, \
        open(os.path.join(out, "pinch_openxr_tool.jsonl"), "w") as c:
    a.write('{"format": "godhand-openxr-hands", "version": 1}\n')
    c.write('{"format": "godhand-openxr-hands", "version": 1}\n')
    b.write('{"format": "godhand-mediapipe-world", "version": 1}\n')
    for f in frames:
        hand = [h for h in f["hands"] if h["type"] == "right"][0]
        fingers = {p["type"]: p for p in f["pointables"] if p.get("handId") == hand["id"]}
        palm = hand["palmPosition"]
        mcp_mid = fingers[2]["mcpPosition"]
        wrist = [2 * palm[k] - mcp_mid[k] for k in range(3)]
        # OpenXR: palm, wrist, thumb metacarpal (Leap's thumb mcp = CMC), proximal, distal, tip,
        # then per finger metacarpal, proximal (MCP), intermediate (PIP), distal (DIP), tip.
        joints = [palm, wrist]
        t = fingers[0]
        joints += [t["mcpPosition"], t["pipPosition"], t["dipPosition"], t["tipPosition"]]
        for i in (1, 2, 3, 4):
            p = fingers[i]
            joints += [mid(wrist, p["mcpPosition"]), p["mcpPosition"], p["pipPosition"], p["dipPosition"], p["tipPosition"]]
        js = ",".join("[" + ",".join("%.9f" % c for c in xr(j)) + ",0,0,0,1,0.01,10]" for j in joints)
        a.write('{"time_ns": %d, "hands": [{"side": "right", "id": %d, "active": true, "confidence": %.6f, "joints": [%s]}]}\n'
                % (f["timestamp"] * 1000, hand["id"], hand["confidence"], js))
        # The controller: 8 cm above the palm (OpenXR +Y up), yaw 0.01 rad per frame about +Y.
        k = frames.index(f)
        yaw = 0.01 * k
        pose = xr(palm)
        pose[1] += 0.08
        quat = [0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2)]  # x, y, z, w
        c.write('{"time_ns": %d, "hands": [{"side": "right", "id": %d, "active": true, "confidence": %.6f, "joints": [%s]}], '
                '"bodies": [{"id": 1, "pose": %s, "flags": 15}]}\n'
                % (f["timestamp"] * 1000, hand["id"], hand["confidence"], js, fmt(pose + quat)))
        # MediaPipe: wrist, thumb CMC, MCP, IP, tip, then per finger MCP, PIP, DIP, tip.
        lm = [wrist, t["mcpPosition"], t["pipPosition"], t["dipPosition"], t["tipPosition"]]
        for i in (1, 2, 3, 4):
            p = fingers[i]
            lm += [p["mcpPosition"], p["pipPosition"], p["dipPosition"], p["tipPosition"]]
        o = cam(wrist)
        rel = [[cam(p)[k] - o[k] for k in range(3)] for p in lm]
        b.write('{"time_us": %d, "hands": [{"handedness": "Right", "score": %.6f, "origin": %s, "landmarks": [%s]}]}\n'
                % (f["timestamp"], hand["confidence"], fmt(o), ",".join(fmt(r) for r in rel)))
