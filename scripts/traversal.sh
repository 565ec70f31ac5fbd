#!/usr/bin/env bash
# Regenerates docs/traversal.md and docs/traversal_iso.png: packet vs SPMD vs
# hybrid traversal per ISA, mesh and thread count (the paper's Table 1), for
# incoherent rays too, volume samples against group size and step (Tables 2
# and 3) and whole DVR frames (samples vs segments, skipping on/off).
# Run it on an idle machine: about 6 minutes on 2 cores; CELLRAY_BENCH_LARGE=1
# adds generated 1M and 5M-cell meshes (the 5M one needs ~4 GB).
# Arguments go to bench_traverse (e.g. --benchmark_filter='^iso/').
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/bench-build.sh
bench_build bench_traverse
json=$(mktemp --suffix=.json)
trap 'rm -f "$json"' EXIT
"$build"/bench/bench_traverse --benchmark_min_time=0.2 --benchmark_out="$json" --benchmark_out_format=json "$@"
"$py" scripts/traversal-tables.py docs "$json"
echo "wrote docs/traversal.md and docs/traversal_iso.png"
