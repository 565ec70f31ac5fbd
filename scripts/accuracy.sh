#!/usr/bin/env bash
# Regenerates docs/accuracy.csv, docs/accuracy_iso.png and docs/accuracy_dvr.png:
# the fast renderer's speed against its error versus the double-precision
# reference renderer, for every knob that trades one for the other.
# Arguments go to bench_accuracy (e.g. --meshes post,disk --frames 3 --size 128 --full).
# Takes about 16 minutes on 2 idle cores (15 frames per configuration: fewer
# make the speed axis noisy enough to move points off the front; see docs/accuracy.md).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh python3-matplotlib
build=${CELLRAY_BUILD_DIR:-build-accuracy}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCELLRAY_BUILD_TESTS=OFF -DCELLRAY_BUILD_EXAMPLES=OFF \
  -DCELLRAY_BUILD_BENCH=ON >/dev/null
cmake --build "$build" -j"$(nproc)" --target bench_accuracy
mkdir -p docs
"$build"/bench/bench_accuracy --csv docs/accuracy.csv --frames 15 "$@" >/dev/null
# Debian's python3-matplotlib lives in /usr/bin/python3 (a pyenv python3 on PATH lacks it).
py=/usr/bin/python3
[ -x "$py" ] || py=python3
"$py" scripts/accuracy-chart.py docs/accuracy.csv docs
