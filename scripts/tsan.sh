#!/usr/bin/env bash
# ThreadSanitizer build of the concurrency tests (the library's widest ISA
# unit and test_render_concurrency, i.e. tests/test_render_concurrency.cpp
# alone) and a run of them:
#   scripts/tsan.sh [build dir, default build-tsan]
# TBB's scheduler lives in an uninstrumented shared library, so TSan cannot
# see the happens-before edges it creates between a parallel_for's tasks;
# the run therefore caps TBB at one thread per arena
# (CELLRAY_TEST_TBB_THREADS=1) and the concurrency comes from the tests' own
# host threads, each rendering on its own (TBB's caller-runs) thread.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-tsan}
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
  -DCELLRAY_ISAS="$(./scripts/widest-isa.sh)" -DCELLRAY_BUILD_TESTS=ON -DCELLRAY_BUILD_EXAMPLES=OFF \
  -DCELLRAY_BUILD_BENCH=OFF -DCMAKE_CXX_FLAGS="-fsanitize=thread" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread" >/dev/null
cmake --build "$build" -j"$(nproc)" --target test_render_concurrency
TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" CELLRAY_TEST_TBB_THREADS=1 \
  "$build/tests/test_render_concurrency" "[concurrency]"
