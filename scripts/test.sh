#!/usr/bin/env bash
# Sets up (Debian packages) and runs the whole test suite twice: a Release
# build (which also compiles the examples and benchmarks) and an ASan+UBSan
# build, then the fuzzers and ThreadSanitizer. Exits non-zero when any test
# fails. Each stage ends with a "== <stage>: N s" line (CI time budget).
set -euo pipefail
cd "$(dirname "$0")/.."
stage_start=$SECONDS
stage() { echo "== $1: $((SECONDS - stage_start)) s (total $SECONDS s)"; stage_start=$SECONDS; }
./scripts/install-deps.sh
jobs=$(nproc)
stage "dependencies"

# CELLRAY_BENCH_SYNTAX_ONLY=ON (CI: .ci/run) checks that the benchmarks
# compile instead of building them (bench/CMakeLists.txt).
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCELLRAY_BUILD_TESTS=ON -DCELLRAY_BUILD_BENCH=ON \
  -DCELLRAY_BENCH_SYNTAX_ONLY="${CELLRAY_BENCH_SYNTAX_ONLY:-OFF}" >/dev/null
cmake --build build -j"$jobs"
stage "Release build"
(cd build && ctest --output-on-failure -j"$jobs")
stage "Release tests"

# The sanitized build compiles one ISA unit, the widest this CPU runs (the
# Release build above tests all three), at -O1 with line tables only: the
# sanitizers need no more, and CI time is spent on running, not compiling.
# It uses clang 14: with ASan+UBSan it compiles this code about twice as fast
# as g++ 12 (ISA unit 16 s vs 72 s CPU) and the tests run ~3x faster, and
# it keeps the whole suite -Werror clean on clang (g++ is the Release build).
# The slowest image tests render smaller frames there (CELLRAY_TEST_SANITIZED,
# tests/support/sanitized.hpp); the Release build runs them at full size.
widest=$(./scripts/widest-isa.sh)
cmake -S . -B build-asan -DCMAKE_CXX_COMPILER="${CELLRAY_ASAN_CXX:-clang++-14}" \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
  -DCELLRAY_SANITIZE=ON -DCELLRAY_ISAS="$widest" \
  -DCELLRAY_BUILD_TESTS=ON -DCELLRAY_BUILD_BENCH=OFF -DCELLRAY_BUILD_EXAMPLES=ON >/dev/null
cmake --build build-asan -j"$jobs"
stage "ASan+UBSan build"
(cd build-asan && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --output-on-failure -j"$jobs" -LE no-sanitizer)
stage "ASan+UBSan tests"

# Reliability (docs/reliability.md): each libFuzzer harness for 20 s (clang,
# ASan + UBSan), then the concurrency tests under ThreadSanitizer.
./scripts/fuzz.sh 20 build-fuzz
stage "fuzz (build + 4 x 20 s, two at a time)"
./scripts/tsan.sh build-tsan
stage "TSan (build + run)"
