#!/usr/bin/env python3
"""DDS-Security across three hosts: the lab of multihost.py (three network namespaces, UDP only)
with every participant authenticated (PKI-DH), everything encrypted (AES-GCM-GMAC) and per-topic
permissions, from a PKI made here at run time by deploy/security/make-lab-pki.sh in a temporary
directory (never committed). The lab file names the PKI (`security:`), and `godhand-launch
--render systemd` writes each host's secured profiles (its identity is its name). Discovery
through unicast initial peers: Fast DDS 2.9.1 cannot secure a discovery server.

    identity   role      may publish (besides ServiceStatus)
    ingest     ingest    HandTarget                      the ingest host
    solvers    solver    HandProposal                    the solvers host
    scene      scene     HandState, ContactForces, SceneState, SceneDescription   scene + resolver
    observer   monitor   -                               a test reader (positive control)
    rogue      monitor   -                               authenticated, no right to write HandState

Checks: the secured lab's lock-step result_hash equals godhand-bench's in-process one, with these
probes running during that run (tests/security/probe.cc, all on the ingest host)
  * a participant without a certificate reads no HandState/HandTarget of the lab, and what it
    injects (HandState and HandTarget, hand 61) reaches nobody of the lab;
  * "rogue" (valid certificate, permissions without HandState) is refused its HandState and
    HandTarget writers and nothing of hand 62 arrives;
  * positive controls: "observer" (authenticated) receives the lab's HandStates, the HandStates
    of a second participant with the scene identity (hand 60) and the HandTargets of a second
    participant with the ingest identity (hand 59), so the reader would have seen an injection
    had it got through. These control writers are matched before the ingest starts; the lab's own
    HandTargets are reported, not required (the ingest's writer is created when its run starts,
    and its secure handshake with the observer may finish after a 1.5 s lock-step run).
Then a live secured run (no probes) measures the latency.

usage: security.py BIN_DIR DEPLOY_DIR DOMAIN RECORDING PROBE
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import multihost  # noqa: E402
from multihost import check, failures, HOSTS  # noqa: E402

IDENTITIES = {"ingest": "ingest", "solvers": "solver", "scene": "scene", "observer": "monitor", "rogue": "monitor"}


def counts(out, topic):
    """{hand: n} of a probe read line."""
    m = re.search(r"probe read: (hand_state.*)", out)
    if not m:
        return None
    parts = m.group(1).split()
    res, cur = {"hand_state": {}, "hand_target": {}}, None
    for p in parts:
        if p in res:
            cur = p
        elif p == "matched_max":
            cur = None
        elif cur and ":" in p:
            k, n = p.split(":")
            res[cur][int(k)] = int(n)
    return res[topic]


def inner(bin_dir, deploy, domain, recording, tmp, probe):
    pki = os.path.join(tmp, "pki")
    r = subprocess.run(["bash", os.path.join(deploy, "security", "make-lab-pki.sh"), pki] +
                       [f"{n}:{r}" for n, r in IDENTITIES.items()], capture_output=True, text=True, timeout=60)
    print(r.stdout + r.stderr)
    check(r.returncode == 0, "make-lab-pki.sh made the lab PKI")
    if r.returncode != 0:
        return
    # The lab's profiles are secured by `godhand-launch --render` (Lab.security: each host's
    # identity is its name); the probes take the ingest host's rendered profiles with another
    # identity, or without the security properties.
    def probes(profiles):
        rendered = open(profiles["ingest"]).read()
        check("builtin.PKI-DH" in rendered and f"{pki}/ingest.pem" in rendered,
              "the rendered profiles of the ingest host carry DDS-Security with its identity")
        ingest_plain = os.path.join(tmp, "probe-plain.xml")
        open(ingest_plain, "w").write(re.sub(r"<propertiesPolicy>.*?</propertiesPolicy>", "", rendered, flags=re.S))
        for ident in ("observer", "rogue", "scene"):
            open(os.path.join(tmp, f"probe-{ident}.xml"), "w").write(
                rendered.replace(f"{pki}/ingest.pem", f"{pki}/{ident}.pem").replace(f"{pki}/ingest.key", f"{pki}/{ident}.key"))
        base = [probe, "--domain", str(domain), "--seconds", "120"]
        return [("no-cert-reader", "ingest", base + ["--mode", "read", "--profiles", ingest_plain]),
                ("observer", "ingest", base + ["--mode", "read", "--profiles", os.path.join(tmp, "probe-observer.xml")]),
                ("no-cert-injector", "ingest", base + ["--mode", "inject", "--hand", "61", "--profiles", ingest_plain]),
                ("rogue-injector", "ingest", base + ["--mode", "inject", "--hand", "62", "--profiles",
                                                     os.path.join(tmp, "probe-rogue.xml")]),
                ("scene-identity-injector", "ingest", base + ["--mode", "inject", "--hand", "60", "--profiles",
                                                              os.path.join(tmp, "probe-scene.xml")]),
                ("ingest-identity-injector", "ingest", base + ["--mode", "inject", "--hand", "59", "--profiles",
                                                               profiles["ingest"]])]

    # Discovery through unicast initial peers, not the discovery server: with DDS-Security the
    # server's GUID prefix is derived from its certificate (PKI-DH), and Fast DDS 2.9.1's clients,
    # which name the server by its fixed prefix, never find it (secure discovery server support
    # came with Fast DDS 2.10).
    def ready(logs):
        """The observer has finished its handshakes with the resolver (scene host) and the local
        scene- and ingest-identity injectors: its HandState reader matched both HandState writers
        and its HandTarget reader the injector's HandTarget writer."""
        try:
            text = open(os.path.join(logs, "probe-observer.out")).read()
        except OSError:
            return False
        m = re.findall(r"matched hand_state (\d+) hand_target (\d+)", text)
        return bool(m) and max(int(a) for a, _ in m) >= 2 and max(int(b) for _, b in m) >= 1

    res = multihost.inner(bin_dir, deploy, domain, recording, tmp, tag_prefix="secured-", probes=probes, server=False,
                          probes_ready=ready, security=pki)
    if not res:
        return
    _, _, out = res
    obs_s, obs_t = counts(out.get("observer", ""), "hand_state"), counts(out.get("observer", ""), "hand_target")
    nc_s, nc_t = counts(out.get("no-cert-reader", ""), "hand_state"), counts(out.get("no-cert-reader", ""), "hand_target")
    check(obs_s is not None and obs_s.get(0, 0) > 0 and obs_s.get(1, 0) > 0,
          f"control: the authenticated observer received the lab's HandStates {obs_s}")
    check(obs_s is not None and obs_s.get(60, 0) > 0,
          f"control: it received the HandStates written under the scene identity (hand 60: {obs_s and obs_s.get(60, 0)})")
    check(obs_t is not None and obs_t.get(59, 0) > 0,
          f"control: it received the HandTargets written under the ingest identity (hand 59: {obs_t and obs_t.get(59, 0)})")
    print(f"info:   the observer received {obs_t and obs_t.get(0, 0)} of the lab's HandTargets (hand 0; not required, see above)")
    check(nc_s is not None and all(nc_s.get(h, 0) == 0 for h in (0, 1, 60)) and all(nc_t.get(h, 0) == 0 for h in (0, 1, 59)),
          f"a participant without a certificate read nothing of the lab (HandState {nc_s}, HandTarget {nc_t})")
    inj = out.get("no-cert-injector", "")
    check("probe inject: written" in inj and int(re.search(r"written (\d+)", inj).group(1)) > 0,
          f"the uncertified injector did write ({inj.strip().splitlines()[-1] if inj.strip() else '-'})")
    check(obs_s is not None and obs_s.get(61, 0) == 0 and obs_t.get(61, 0) == 0,
          f"nothing it injected reached the lab's authenticated reader (hand 61: {obs_s and obs_s.get(61, 0)} HandStates, "
          f"{obs_t and obs_t.get(61, 0)} HandTargets)")
    rogue = out.get("rogue-injector", "")
    check(re.search(r"refused hand_state hand_target", rogue) is not None and "topic not found in allow rule" in rogue,
          f"the authenticated rogue was refused its HandState and HandTarget writers by access control "
          f"({rogue.strip().splitlines()[-1] if rogue.strip() else '-'})")
    check(obs_s is not None and obs_s.get(62, 0) == 0 and obs_t.get(62, 0) == 0, "nothing of the rogue's (hand 62) arrived")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--inner":
        bin_dir, deploy, domain, recording, tmp, probe = sys.argv[2:8]
        inner(bin_dir, deploy, int(domain), recording, tmp, probe)
        print("PASSED" if not failures else f"{len(failures)} check(s) FAILED")
        sys.exit(0 if not failures else 1)
    if not shutil.which("openssl"):
        print("SKIP: needs openssl")
        sys.exit(77)
    multihost.outer(sys.argv[1:6], __file__)


if __name__ == "__main__":
    main()
