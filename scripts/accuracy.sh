#!/usr/bin/env bash
# Regenerates docs/accuracy.csv, docs/accuracy_iso.png and docs/accuracy_dvr.png:
# the fast renderer's speed against its error versus the double-precision
# reference renderer, for every knob that trades one for the other.
# Arguments go to bench_accuracy (e.g. --meshes post,disk --frames 3 --size 128 --full).
# Takes about 15 minutes on 2 idle cores (15 frames per configuration: fewer
# make the speed axis noisy enough to move points off the front; see docs/accuracy.md).
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/bench-build.sh
bench_build bench_accuracy
"$build"/bench/bench_accuracy --csv docs/accuracy.csv --frames 15 "$@" >/dev/null
"$py" scripts/accuracy-chart.py docs/accuracy.csv docs
