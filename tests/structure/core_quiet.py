#!/usr/bin/env python3
"""core/ reads no environment and writes to no console: every getenv, stdout/stderr stream or
printf-family call to a stream in core/ is listed and fails the test (diagnostics go through
PipelineParams::trace_sink, set by the services). usage: core_quiet.py CORE_DIR"""
import os
import re
import sys

PATTERNS = [r"\bgetenv\s*\(", r"\bstd::(cout|cerr|clog)\b", r"\b(f?printf|puts|fputs|perror)\s*\(", r"\bstd(out|err)\b"]
bad = []
for root, _, files in os.walk(sys.argv[1]):
    for f in files:
        if not f.endswith((".cc", ".h", ".cpp", ".hpp")):
            continue
        path = os.path.join(root, f)
        for n, line in enumerate(open(path, encoding="utf-8", errors="replace"), 1):
            code = line.split("//", 1)[0]
            if any(re.search(p, code) for p in PATTERNS):
                bad.append(f"{path}:{n}: {line.strip()}")
for b in bad:
    print(b)
print(f"{len(bad)} line(s) of core/ read the environment or write to a console")
print("PASSED" if not bad else "FAILED")
sys.exit(1 if bad else 0)
