#!/usr/bin/env bash
# Installs every Debian package godhand's build, tests and demo need. Idempotent and
# non-interactive: packages already present are not touched; apt-get runs only when one is missing.
# Usage: deploy/install-deps.sh        (as root, or with sudo available)
set -euo pipefail
pkgs=(
  build-essential cmake pkg-config ninja-build python3 procps iproute2
  libeigen3-dev libbullet-dev libfcl-dev libccd-dev
  libprotobuf-dev protobuf-compiler
  libfastrtps-dev libfastcdr-dev fastddsgen fastdds-tools default-jre-headless
  libgtest-dev libgmock-dev nlohmann-json3-dev libbenchmark-dev
  libwebsocketpp-dev libboost-dev chromium  # godhand-viewer: its server, and the browser its tests drive
  clang libfuzzer-14-dev libclang-rt-14-dev  # libFuzzer targets of the parsers (tests/fuzz/run_fuzz.sh)
  cyclonedds-dev cyclonedds-tools openssl  # interop test (a Cyclone DDS reader, its idlc); lab PKI (deploy/security)
  python3-matplotlib  # godhand-bench --sweep --plot (Debian's python3, /usr/bin/python3)
  libmujoco-dev  # godhand-bench --compare mujoco (deploy/run.sh compare) and its tests
  gdb  # where a service hangs: godhand-launch prints its threads' backtraces before it kills it
  valgrind  # tests/programs/ab.py --instructions: before and after by callgrind's count
)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
# Node.js and npm for the viewer's page (npm ci in services/viewer/web): Debian's, unless a node
# with npm is already installed (another distribution of node conflicts with Debian's npm package).
command -v npm >/dev/null 2>&1 && command -v node >/dev/null 2>&1 || missing+=(nodejs npm)
[[ ${#missing[@]} -eq 0 ]] && exit 0
echo "install-deps: installing ${missing[*]}"
sudo=""
[[ $(id -u) -eq 0 ]] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
