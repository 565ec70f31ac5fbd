#!/usr/bin/env bash
# ODR guard (TOOLCHAIN.md): fails when an ISA object defines a weak symbol
# (inline function, template instance, guard variable) that is not tied to
# its ISA -- by an arch template argument or the CELLRAY_ISA_NS namespace.
# The linker keeps one copy of each weak symbol, so such a symbol compiled
# with AVX-512 flags could replace the baseline copy and crash older CPUs.
# usage: check-isa-symbols.sh <isa-name-pattern> <object>...
set -euo pipefail
pattern=$1
shift
leaks=$(nm -C --defined-only "$@" | awk '$2 == "W" || $2 == "V" || $2 == "u"' | cut -d' ' -f3- |
        grep -v -E "$pattern" | grep -v "^DW\.ref\." | sort -u || true)
if [ -n "$leaks" ]; then
  echo "weak symbols not tied to the ISA ($pattern) in $*:"
  echo "$leaks"
  exit 1
fi
echo "ok: every weak symbol in $# object(s) is tied to the ISA ($pattern)"
