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
)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
[[ ${#missing[@]} -eq 0 ]] && exit 0
echo "install-deps: installing ${missing[*]}"
sudo=""
[[ $(id -u) -eq 0 ]] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
