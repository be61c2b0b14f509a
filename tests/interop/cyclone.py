#!/usr/bin/env python3
"""Another vendor: a Cyclone DDS subscriber (tests/interop/cyclone_reader.c, types from Cyclone's
idlc on idl/godhand.idl) reads a running lab's HandState and SceneDescription over standard RTPS.

The lab is the shipped local one (Fast DDS, shared memory + UDP on 127.0.0.1, unicast discovery
to 127.0.0.1, no multicast) in lock-step mode; Cyclone is configured to match (CYCLONEDDS_URI:
loopback only, multicast off, unicast peer 127.0.0.1). Cyclone ignores Fast DDS's shared-memory
locators: everything it gets came over UDP.

Checks, each against an independent oracle: every frame of the replay (1..N, N from the
launcher's report and the recording's first 200) of every cluster arrived at the Cyclone reader; the
clusters' names are the lab file's, in its order; each HandState has as many poses as the hand
model file has bodies; the SceneDescription names the scene file's scene and lists exactly its
objects' ids, in order.

usage: cyclone.py BIN_DIR DEPLOY_DIR DOMAIN RECORDING READER
"""
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile

BIN, DEPLOY, DOMAIN, RECORDING, READER = sys.argv[1:6]
failures = []


def check(ok, what):
    print(("ok:     " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


CONFIG = """<?xml version="1.0" encoding="UTF-8" ?>
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain id="any">
    <General>
      <Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
      <AllowMulticast>false</AllowMulticast>
    </General>
    <Discovery>
      <ParticipantIndex>auto</ParticipantIndex>
      <MaxAutoParticipantIndex>40</MaxAutoParticipantIndex>
      <Peers><Peer address="127.0.0.1"/></Peers>
    </Discovery>
  </Domain>
</CycloneDDS>
"""


def main():
    tmp = tempfile.mkdtemp(prefix="godhand-cyclone-")
    reader = None
    try:
        lab_file = os.path.join(DEPLOY, "lab", "local.pbtxt")
        lab = re.sub(r"#.*", "", open(lab_file).read())
        clusters = re.findall(r'clusters\s*\{\s*name:\s*"([^"]+)"\s*model:\s*"([^"]+)"', lab)
        check(len(clusters) >= 1, f"lab file names its clusters ({[c[0] for c in clusters]})")
        bodies = [len(re.findall(r"^bodies \{", open(os.path.normpath(os.path.join(DEPLOY, "lab", m))).read(), re.M))
                  for _, m in clusters]
        scene_path = os.path.normpath(os.path.join(DEPLOY, "lab", re.search(r'^scene:\s*"([^"]+)"', lab, re.M).group(1)))
        scene = open(scene_path).read()
        scene_name = re.search(r'^name:\s*"([^"]+)"', scene, re.M).group(1)
        object_ids = re.findall(r'^objects \{\s*id:\s*"([^"]+)"', scene, re.M)
        # The first 200 frames: fewer than the lock-step writers' history (256), so a reader that
        # matches late (discovery between two vendors takes a moment) still gets every frame.
        n_frames = min(200, len(json.load(open(RECORDING)).get("frames", [])))

        cfg = os.path.join(tmp, "cyclonedds.xml")
        open(cfg, "w").write(CONFIG)
        env = dict(os.environ, CYCLONEDDS_URI="file://" + cfg)
        reader_log = os.path.join(tmp, "reader.out")
        reader = subprocess.Popen([READER, "--domain", DOMAIN, "--hands", str(len(clusters)), "--frames", str(n_frames),
                                   "--seconds", "150"], stdout=open(reader_log, "w"), stderr=subprocess.STDOUT, env=env)
        report = os.path.join(tmp, "report.json")
        r = subprocess.run([os.path.join(BIN, "godhand-launch"), "--lab", lab_file, "--domain", DOMAIN, "--lockstep",
                            "--recording", RECORDING, "--frames", str(n_frames), "--quiet", "--json", report, "--log-dir", os.path.join(tmp, "logs")],
                           capture_output=True, text=True, timeout=240)
        print(r.stdout[-3000:], r.stderr[-2000:])
        check(r.returncode == 0, f"the lab ran (godhand-launch --lockstep exit {r.returncode})")
        j = json.load(open(report)) if os.path.exists(report) else {}
        check(j.get("frames") == n_frames, f"the launcher's monitor saw every frame ({j.get('frames')} of {n_frames})")
        try:
            reader.wait(timeout=15)
        except subprocess.TimeoutExpired:
            reader.send_signal(signal.SIGTERM)
            reader.wait(timeout=15)
        out = open(reader_log).read()
        print(out)
        check(reader.returncode == 0 and "cyclone: done (complete)" in out,
              f"the Cyclone reader finished with everything (exit {reader.returncode}, {re.findall(r'done .*', out)})")
        for h, (name, _) in enumerate(clusters):
            m = re.search(rf"^cyclone: hand {h} cluster (\S+) samples (\d+) frames (\d+) first (\d+) last (\d+) poses (\d+)", out, re.M)
            check(m is not None, f"hand {h}: reported")
            if not m:
                continue
            check(m.group(1) == name, f"hand {h}: cluster '{m.group(1)}' == lab file's '{name}'")
            check(int(m.group(3)) == n_frames and int(m.group(4)) == 1 and int(m.group(5)) == n_frames,
                  f"hand {h}: frames {m.group(4)}..{m.group(5)}, {m.group(3)} distinct == the recording's {n_frames}")
            check(int(m.group(6)) == bodies[h], f"hand {h}: {m.group(6)} poses == the model's {bodies[h]} bodies")
        m = re.search(r"^cyclone: scene (\S+) objects (\d+) ids (\S*)", out, re.M)
        check(m is not None and m.group(1) == scene_name, f"SceneDescription of scene '{m and m.group(1)}' == '{scene_name}'")
        check(m is not None and m.group(3).split(",") == object_ids,
              f"its objects {m and m.group(3)} == the scene file's {object_ids}")
    finally:
        if reader and reader.poll() is None:
            reader.kill()
            reader.wait()
        shutil.rmtree(tmp, ignore_errors=True)
    print("PASSED" if not failures else f"{len(failures)} check(s) FAILED")
    sys.exit(0 if not failures else 1)


main()
