#!/bin/bash
# Builds the libFuzzer targets of tests/fuzz/ with Debian's clang (-fsanitize=fuzzer,address,
# undefined) and runs each for SECONDS on a copy of its committed seed corpus (tests/fuzz/corpus/
# NAME). Exit 0: no crash; 1: a crash (the reproducer is kept in OUT_DIR/crash-*: add it to
# tests/fuzz/regressions/NAME/ and fix the parser); 77: clang or libFuzzer is not installed.
#   run_fuzz.sh SOURCE_DIR OUT_DIR SECONDS [TARGET...]
# Longer run (documented in bridges/README.md): run_fuzz.sh . /tmp/fuzz 600 dtrack
set -u
SRC=$(cd "$1" && pwd); OUT=$2; SECS=$3; shift 3
TARGETS=("$@"); [ ${#TARGETS[@]} -eq 0 ] && TARGETS=(dtrack leap jsonl mesh text)
CXX=${FUZZ_CXX:-clang++}
if ! command -v "$CXX" >/dev/null; then echo "SKIPPED: $CXX not installed"; exit 77; fi
mkdir -p "$OUT"
echo 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }' > "$OUT/probe.cc"
if ! "$CXX" -fsanitize=fuzzer "$OUT/probe.cc" -o "$OUT/probe" 2>/dev/null; then echo "SKIPPED: libFuzzer not available to $CXX"; exit 77; fi
# The text target parses protobuf text: its messages are generated here with Debian's protoc.
GEN="$OUT/gen"; mkdir -p "$GEN"
FLAGS=(-std=c++17 -O1 -gline-tables-only -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -I"$SRC/bridges" -I"$SRC/core" -I"$SRC/services" -I"$GEN" -isystem /usr/include/eigen3 -DNDEBUG)
declare -A SOURCES=(
  [dtrack]="$SRC/tests/fuzz/fuzz_dtrack.cc $SRC/bridges/dtrack/dtrack.cc $SRC/bridges/leap/leap_recording.cc $SRC/core/math/pose.cc"
  [leap]="$SRC/tests/fuzz/fuzz_leap.cc $SRC/bridges/leap/leap_recording.cc $SRC/core/math/pose.cc"
  [mesh]="$SRC/tests/fuzz/fuzz_mesh.cc $SRC/core/scene/mesh_io.cc $SRC/core/geometry/mesh.cc $SRC/core/geometry/bvh.cc $SRC/core/geometry/distance.cc $SRC/core/math/pose.cc"
  [text]="$SRC/tests/fuzz/fuzz_text.cc $SRC/core/scene/scene_file.cc $SRC/core/scene/mesh_io.cc $SRC/core/geometry/mesh.cc $SRC/core/geometry/bvh.cc $SRC/core/geometry/distance.cc $SRC/core/model/hand_model.cc $SRC/core/model/text_proto.cc $SRC/core/math/pose.cc $SRC/services/common/lab_config.cc $SRC/services/common/sweep_spec.cc $SRC/services/common/files.cc $GEN/hand_model.pb.cc $GEN/scene.pb.cc $GEN/lab.pb.cc $GEN/sweep.pb.cc"
  [jsonl]="$SRC/tests/fuzz/fuzz_jsonl.cc $SRC/bridges/skeleton/jsonl.cc $SRC/bridges/skeleton/skeleton.cc $SRC/bridges/skeleton/aria.cc $SRC/bridges/synthetic/synthetic.cc $SRC/bridges/leap/leap_recording.cc $SRC/core/math/pose.cc"
)
# An object is stale when its source or any header it includes (clang's -MMD list) is newer: a
# header change (a struct's layout) with only the .cc's time checked left objects of two
# layouts in one binary (seen: a leak reported where a member was never destroyed).
stale() {
  local obj=$1 src=$2 dep
  [ -f "$obj" ] && [ -f "$obj.d" ] || return 0
  for dep in $(sed -e 's/^[^:]*://' -e 's/\\$//' "$obj.d"); do
    [ "$dep" -nt "$obj" ] && return 0
  done
  return 1
}
status=0
for t in "${TARGETS[@]}"; do
  [ -n "${SOURCES[$t]:-}" ] || { echo "unknown fuzz target $t"; exit 2; }
  echo "== building fuzz_$t"
  LIBS=()
  if [ "$t" = text ]; then
    command -v protoc >/dev/null || { echo "SKIPPED: protoc not installed"; exit 77; }
    for proto in hand_model scene lab sweep; do
      if [ ! -f "$GEN/$proto.pb.cc" ] || [ "$SRC/idl/$proto.proto" -nt "$GEN/$proto.pb.cc" ]; then
        protoc -I"$SRC/idl" --cpp_out="$GEN" "$SRC/idl/$proto.proto" || { echo "FAILED: protoc $proto.proto"; exit 1; }
      fi
    done
    LIBS=(-lprotobuf)
  fi
  objs=()
  for src in ${SOURCES[$t]}; do  # each source compiled once for all targets
    obj="$OUT/obj/$(echo "${src#$SRC/}" | tr '/' '_').o"
    mkdir -p "$OUT/obj"
    if stale "$obj" "$src"; then
      if ! nice "$CXX" "${FLAGS[@]}" -MMD -MF "$obj.d" -c "$src" -o "$obj"; then echo "FAILED: compiling $src"; exit 1; fi
    fi
    objs+=("$obj")
  done
  if ! "$CXX" -fsanitize=fuzzer,address,undefined "${objs[@]}" "${LIBS[@]}" -o "$OUT/fuzz_$t"; then echo "FAILED: link of fuzz_$t"; exit 1; fi
  corpus="$OUT/corpus_$t"; rm -rf "$corpus"; mkdir -p "$corpus"
  cp "$SRC/tests/fuzz/corpus/$t/"* "$corpus/"
  # Regression inputs (former crashes) must pass first.
  if [ -d "$SRC/tests/fuzz/regressions/$t" ]; then
    if ! "$OUT/fuzz_$t" "$SRC/tests/fuzz/regressions/$t/"* >"$OUT/regress_$t.log" 2>&1; then
      echo "FAILED: a regression input of $t crashes"; tail -30 "$OUT/regress_$t.log"; status=1; continue
    fi
  fi
  echo "== fuzzing fuzz_$t for ${SECS}s"
  (cd "$OUT" && nice "$OUT/fuzz_$t" -max_total_time="$SECS" -seed=1 -max_len=8192 -timeout=10 -rss_limit_mb=1024 \
     -print_final_stats=1 "$corpus" >"$OUT/fuzz_$t.log" 2>&1)
  rc=$?
  grep -E "stat::number_of_executed_units|stat::new_units_added" "$OUT/fuzz_$t.log" | sed "s/^/fuzz_$t: /"
  if [ $rc -ne 0 ]; then echo "FAILED: fuzz_$t found a crash (exit $rc):"; grep -E "ERROR|SUMMARY|Test unit written" "$OUT/fuzz_$t.log" | head; status=1; fi
done
[ $status -eq 0 ] && echo "PASSED"
exit $status
