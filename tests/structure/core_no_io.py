#!/usr/bin/env python3
"""core/ does no I/O: it reads no environment, opens no files, asks the file system nothing and
writes to no console. Every such line in core/ is listed as FILE:LINE: what: code and fails the
test. Diagnostics go through PipelineParams::trace_sink, set by the services; files are read in
services/common/files.cc and handed to core as text (parseScene takes a MeshLoader).
std::filesystem::path arithmetic (lexically_normal, stem, extension, ...) is allowed: it asks
the file system nothing. usage: core_no_io.py CORE_DIR"""
import os
import re
import sys

# Queries and changes of the file system (std::filesystem free functions, under any alias
# ending in "fs" or spelled filesystem::); the path class and its members are pure.
FS_CALLS = ("exists|is_regular_file|is_directory|is_symlink|is_empty|is_other|is_block_file|"
            "is_character_file|is_fifo|is_socket|status|symlink_status|canonical|weakly_canonical|"
            "absolute|relative|proximate|current_path|temp_directory_path|file_size|last_write_time|"
            "directory_iterator|recursive_directory_iterator|create_directory|create_directories|"
            "create_symlink|create_hard_link|remove|remove_all|rename|copy|copy_file|copy_symlink|"
            "read_symlink|space|equivalent|hard_link_count|permissions|resize_file")
PATTERNS = [
    ("reads the environment", r"\b(secure_)?getenv\s*\(|\benviron\b|\b(setenv|putenv|unsetenv)\s*\("),
    ("writes to a console", r"\bstd::(cout|cerr|clog)\b|\b(f?printf|puts|fputs|perror)\s*\(|\bstd(out|err|in)\b"),
    ("opens a file", r"#\s*include\s*<(fstream|unistd\.h|fcntl\.h|dirent\.h|sys/stat\.h)>|\b[io]?fstream\b|"
                     r"\bf(open|reopen|read|write|close|gets|scanf)\s*\(|\btmpfile\s*\(|(?<![\w.>])open\s*\(|"
                     r"\bpopen\s*\(|\bstd::system\s*\("),
    ("asks the file system", r"\b(\w*fs|filesystem)::(" + FS_CALLS + r")\b|\busing\s+namespace\s+std::filesystem\b"),
]
bad = []
for root, _, files in os.walk(sys.argv[1]):
    for f in sorted(files):
        if not f.endswith((".cc", ".h", ".cpp", ".hpp")):
            continue
        path = os.path.join(root, f)
        for n, line in enumerate(open(path, encoding="utf-8", errors="replace"), 1):
            code = line.split("//", 1)[0]
            for what, p in PATTERNS:
                if re.search(p, code):
                    bad.append(f"{path}:{n}: {what}: {line.strip()}")
for b in bad:
    print(b)
print(f"{len(bad)} line(s) of core/ read the environment, open files, ask the file system or write to a console")
print("PASSED" if not bad else "FAILED")
sys.exit(1 if bad else 0)
