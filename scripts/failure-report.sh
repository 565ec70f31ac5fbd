#!/usr/bin/env bash
# Regenerates docs/failure_modes.md: measured failure rates of each method
# (cracks at shared faces, missed double roots, Newton non-convergence, NaN
# scalars and degenerate cells), fast renderer against the reference.
# Arguments go to bench_accuracy (e.g. --size 128). About a minute on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
build=${CELLRAY_BUILD_DIR:-build-accuracy}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCELLRAY_BUILD_TESTS=OFF -DCELLRAY_BUILD_EXAMPLES=OFF \
  -DCELLRAY_BUILD_BENCH=ON >/dev/null
cmake --build "$build" -j"$(nproc)" --target bench_accuracy
mkdir -p docs
"$build"/bench/bench_accuracy --report docs/failure_modes.md --size 192 "$@"
