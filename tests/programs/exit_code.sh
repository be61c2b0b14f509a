#!/usr/bin/env bash
# exit_code.sh CMD ARGS...: runs CMD, passes its output through and ends with "exit code N"
# (a ctest PASS_REGULAR_EXPRESSION then checks the message and the exit code together; a
# crash shows as "exit code 134" and the like).
"$@" 2>&1
echo "exit code $?"
