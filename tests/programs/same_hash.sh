#!/usr/bin/env bash
# Same input => same result: godhand-bench twice on the same recording and scene must report the
# same result_hash (of every God-object pose of every frame).
set -euo pipefail
bench=$1; shift
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
"$bench" "$@" --quiet --json "$out/a.json" >/dev/null
"$bench" "$@" --quiet --json "$out/b.json" >/dev/null
a=$(python3 -c 'import json,sys;print(json.load(open(sys.argv[1]))["result_hash"])' "$out/a.json")
b=$(python3 -c 'import json,sys;print(json.load(open(sys.argv[1]))["result_hash"])' "$out/b.json")
echo "result_hash $a / $b"
[[ $a == "$b" ]] && echo "same hash" || { echo "hashes differ"; exit 1; }
