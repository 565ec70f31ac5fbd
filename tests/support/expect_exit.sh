#!/usr/bin/env bash
# Runs a command and checks its exit code and output (the ctests of the
# missing-data skip in tests/CMakeLists.txt).
# usage: expect_exit.sh <exit-code> <extended regex on stdout+stderr> <command> [args...]
set -u
want=$1 re=$2
shift 2
out=$("$@" 2>&1)
rc=$?
printf '%s\n' "$out"
[ "$rc" = "$want" ] || { echo "FAIL: exit code $rc, expected $want"; exit 1; }
printf '%s\n' "$out" | grep -Eq -- "$re" || { echo "FAIL: output does not match /$re/"; exit 1; }
echo "ok"
