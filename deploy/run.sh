#!/usr/bin/env bash
# godhand's one entry point for people and CI: installs missing Debian packages, builds, runs.
#   deploy/run.sh demo [bench args]  build, then run the whole method in one process (godhand-bench)
#                                    on the default scene with the bundled real Leap recordings
#   deploy/run.sh test               build, run every test (ctest), then the core tests again
#                                    and every area's unit tests under AddressSanitizer +
#                                    UndefinedBehaviorSanitizer
# Warnings are errors when CI=true. Build trees: build/ (RelWithDebInfo), build-asan/.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
mode=${1:-}
[[ $mode == demo || $mode == test ]] || { echo "usage: deploy/run.sh demo|test [args]" >&2; exit 2; }
shift
deploy/install-deps.sh
werror=OFF
[[ ${CI:-} == true ]] && werror=ON
configure() {  # dir, extra cmake args
  local dir=$1; shift
  cmake -S . -B "$dir" -G Ninja -DGODHAND_WERROR=$werror "$@" >"$dir/configure.log" 2>&1 \
    || { cat "$dir/configure.log"; echo "run.sh: cmake configure failed ($dir)" >&2; exit 1; }
}
build() {  # dir, targets
  local dir=$1; shift
  echo "run.sh: building $dir ${*:-(all)}"
  ninja -C "$dir" "$@" >"$dir/build.log" 2>&1 || { tail -60 "$dir/build.log"; echo "run.sh: build failed ($dir)" >&2; exit 1; }
}
mkdir -p build
configure build
case $mode in
  demo)
    build build godhand-bench godhand-demo
    status=0
    for rec in pinch confidence2-49fps; do
      echo "== godhand-bench: deploy/recordings/$rec.json on deploy/scenes/default.pbtxt =="
      build/bin/godhand-bench --recording deploy/recordings/$rec.json --quiet --check "$@" || status=1
    done
    exit $status
    ;;
  test)
    build build
    ctest --test-dir build --output-on-failure -j2 --timeout 600
    echo "== core tests under ASan + UBSan =="
    mkdir -p build-asan
    configure build-asan -DGODHAND_SANITIZE=ON -DGODHAND_BENCHMARKS=OFF -DCMAKE_BUILD_TYPE=Debug \
      -DCMAKE_CXX_FLAGS="-D_GLIBCXX_ASSERTIONS" \
      -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g"
    build build-asan godhand_core_tests godhand_alloc_test godhand_geometry_tests godhand_scene_tests \
      godhand_physics_tests godhand_bridges_tests godhand_pipeline_tests
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
      ctest --test-dir build-asan --output-on-failure -j2 --timeout 900 -LE programs
    ;;
esac
