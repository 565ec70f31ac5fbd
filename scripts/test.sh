#!/usr/bin/env bash
# Sets up (Debian packages) and runs the whole test suite twice: a Release
# build (which also compiles the examples and benchmarks) and an ASan+UBSan
# build. Exits non-zero when any test fails.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
jobs=$(nproc)

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCELLRAY_BUILD_TESTS=ON -DCELLRAY_BUILD_BENCH=ON >/dev/null
cmake --build build -j"$jobs"
(cd build && ctest --output-on-failure -j"$jobs")

# The sanitized build compiles one ISA unit, the widest this CPU runs (the
# Release build above tests all three), at -O1 with line tables only: the
# sanitizers need no more, and CI time is spent on running, not compiling.
widest=$(./scripts/widest-isa.sh)
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
  -DCELLRAY_SANITIZE=ON -DCELLRAY_ISAS="$widest" \
  -DCELLRAY_BUILD_TESTS=ON -DCELLRAY_BUILD_BENCH=OFF -DCELLRAY_BUILD_EXAMPLES=ON >/dev/null
cmake --build build-asan -j"$jobs"
(cd build-asan && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --output-on-failure -j"$jobs" -LE no-sanitizer)

# Reliability (docs/reliability.md): each libFuzzer harness for 30 s (clang,
# ASan + UBSan), then the concurrency tests under ThreadSanitizer.
./scripts/fuzz.sh 30 build-fuzz
./scripts/tsan.sh build-tsan
