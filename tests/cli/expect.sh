#!/usr/bin/env bash
# Runs a command and checks how it ends (used by the cellray-render ctests).
# usage: expect.sh [--absent FILE] [--png FILE W H] [--skip-without-avx512] [--needs REL]... [--reject RE] [--also RE]
#                  <exit-code> <regex|""> <command> [args...]
#   exit-code  the code the command must exit with
#   regex      extended regex the command's stdout+stderr must match ("any": no check)
#   --absent   FILE must not exist afterwards (no image written on failure)
#   --reject   extended regex the command's stdout+stderr must not match
#   --also     another extended regex the output must match (regexes match
#              within one line)
#   --png      FILE must be a W x H PNG that is not one flat colour (checked
#              by the program in $PNG_CHECK, tests/cli/png_check.cpp)
#   --needs    REL, a file of the shared data set, must exist in the data
#              directory ($CELLRAY_DATA_DIR, default ../shared/data beside
#              the repository); if it does not, the test is skipped (exit 77,
#              which the ctests treat as skipped). "{data}" in the command's
#              arguments stands for that directory.
# A failing command (non-zero exit expected) must print exactly one line on
# stderr, starting "cellray-render: error:".
set -u
absent="" png="" skip_avx512=0 needs=() reject="" also=""
while [ $# -gt 0 ]; do
  case "$1" in
    --needs) needs+=("$2"); shift 2 ;;
    --absent) absent=$2; shift 2 ;;
    --reject) reject=$2; shift 2 ;;
    --also) also=$2; shift 2 ;;
    --png) png=("$2" "$3" "$4"); shift 4 ;;
    --skip-without-avx512) skip_avx512=1; shift ;;
    *) break ;;
  esac
done
want=$1 re=$2
shift 2
if [ "$skip_avx512" = 1 ] && ! grep -qw avx512bw /proc/cpuinfo; then
  echo "this CPU lacks AVX-512: skipped"
  exit 77
fi
data_dir=${CELLRAY_DATA_DIR:-$(cd "$(dirname "$0")/../.." && pwd)/../shared/data}
for rel in ${needs[@]+"${needs[@]}"}; do
  if [ ! -f "$data_dir/$rel" ]; then
    echo "skipped: $data_dir/$rel missing (set CELLRAY_DATA_DIR)"
    exit 77
  fi
done
placeholder='{data}'
args=()
for a in "$@"; do args+=("${a//"$placeholder"/$data_dir}"); done
set -- "${args[@]}"
for f in "$absent" "${png[0]:-}"; do [ -n "$f" ] && rm -f "$f"; done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$@" >"$tmp/out" 2>"$tmp/err"
rc=$?
cat "$tmp/out" "$tmp/err"
fail() { echo "FAIL: $*"; exit 1; }
[ "$rc" = "$want" ] || fail "exit code $rc, expected $want"
if [ "$re" != any ]; then
  cat "$tmp/out" "$tmp/err" | grep -Eq -- "$re" || fail "output does not match /$re/"
fi
if [ -n "$also" ] && ! cat "$tmp/out" "$tmp/err" | grep -Eq -- "$also"; then
  fail "output does not match /$also/"
fi
if [ -n "$reject" ] && cat "$tmp/out" "$tmp/err" | grep -Eq -- "$reject"; then
  fail "output matches /$reject/"
fi
if [ "$want" != 0 ]; then
  [ "$(wc -l <"$tmp/err")" = 1 ] || fail "expected exactly one line on stderr"
  grep -q '^cellray-render: error: ' "$tmp/err" || fail "stderr does not start with 'cellray-render: error: '"
fi
if [ -n "$absent" ] && [ -e "$absent" ]; then fail "$absent was written although the command failed"; fi
if [ -n "$png" ]; then
  "$PNG_CHECK" "${png[@]}" || fail "bad image ${png[0]}"
fi
echo "ok"
