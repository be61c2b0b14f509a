#!/usr/bin/env python3
"""Writes pinch_head_packed.json: the first 12 frames of deploy/recordings/pinch.json in
leapjs-playback's packed format 2 (frames[0] = packing structure, as in leapjs-playback's
src/recording.js; it has no pointable "type"). Used to check that format 2 reads the same
hands as format 0.1. Standard library only, deterministic."""
import json, os

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(HERE, "..", "..", "..", "deploy", "recordings", "pinch.json")
STRUCTURE = [
    "id", "timestamp",
    {"hands": [["id", "type", "direction", "palmNormal", "palmPosition", "palmVelocity",
                "stabilizedPalmPosition", "pinchStrength", "grabStrength", "confidence"]]},
    {"pointables": [["id", "direction", "handId", "length", "stabilizedTipPosition", "tipPosition",
                     "tipVelocity", "tool", "carpPosition", "mcpPosition", "pipPosition",
                     "dipPosition", "btipPosition", "bases"]]},
    {"interactionBox": ["center", "size"]},
]

def pack(structure, data):
    out = []
    for s in structure:
        if isinstance(s, str):
            out.append(data.get(s))
        elif isinstance(s, list):
            return [pack(s, d) for d in data]
        else:
            (key, sub), = s.items()
            out.append(pack(sub, data[key]))
    return out

def main():
    src = json.load(open(SRC))
    frames = src["frames"][:12]
    meta = dict(src["metadata"], formatVersion=2, frames=len(frames),
                generatedBy="godhand tests/data/leap/make_packed.py from pinch.json (first 12 frames)")
    doc = {"metadata": meta, "frames": [STRUCTURE] + [pack(STRUCTURE, f) for f in frames]}
    with open(os.path.join(HERE, "pinch_head_packed.json"), "w") as f:
        json.dump(doc, f, separators=(",", ":"))
        f.write("\n")

if __name__ == "__main__":
    main()
