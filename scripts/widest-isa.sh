#!/usr/bin/env bash
# Prints the widest cellray ISA this CPU runs (avx512, avx2 or sse4): the one
# ISA unit the sanitizer and fuzz builds compile (CELLRAY_ISAS).
set -euo pipefail
flags=$(grep -m1 '^flags' /proc/cpuinfo)
has() { [[ " $flags " == *" $1 "* ]]; }
if has avx512f && has avx512cd && has avx512dq && has avx512bw; then echo avx512
elif has avx2 && has fma; then echo avx2
else echo sse4
fi
