#!/usr/bin/env bash
# Builds the libFuzzer harnesses (clang, ASan + UBSan) and runs each for a
# bounded time: scripts/fuzz.sh [seconds per harness, default 60] [build dir].
#   CI:       scripts/fuzz.sh 20            (four harnesses, two at a time: 40 s)
#   Longer:   scripts/fuzz.sh 3600 build-fuzz   (the corpus in the build dir grows across runs)
# A crash, hang (> 10 s) or out-of-memory (> 2 GB) input is written to
# <build>/artifacts/<harness>-crash-..., the run stops and this script fails.
# Make it a regression: copy the file into tests/fuzz/regressions/<harness>/
# (vtk, vtu, msh or validate), fix the bug, and ctest replays it from then on.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
build=${2:-build-fuzz}
cxx=${CELLRAY_FUZZ_CXX:-clang++-14}
real=tests/data/real/vtk-data  # the repository's copies of small real files

# One ISA unit (the widest this CPU runs) keeps the instrumented build short.
cmake -S tests/fuzz -B "$build" -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCELLRAY_ISAS="${CELLRAY_FUZZ_ISAS:-$(./scripts/widest-isa.sh)}" >/dev/null
cmake --build "$build" -j"$(nproc)" --target fuzz_vtk_legacy fuzz_vtu fuzz_gmsh fuzz_validate
mkdir -p "$build/artifacts"

# run <harness> <kind: vtk|vtu|msh|validate> [extra seed files...]: seeds and
# regressions of that kind are copied into a corpus that persists in the
# build dir, so longer runs build on earlier ones. The harness runs in the
# background, its status in $build/<harness>.status; `finish` waits for the
# running ones and reports.
running=()
run() {
  local h=$1 kind=$2 corpus="$build/corpus/$2"
  shift 2
  mkdir -p "$corpus"
  for f in tests/fuzz/seeds/"$kind"/* tests/fuzz/regressions/"$kind"/* "$@"; do
    [ -f "$f" ] && cp -n "$f" "$corpus"/
  done
  echo "== $h for ${seconds}s (corpus $corpus)"
  ( status=0
    "$build/$h" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
      -artifact_prefix="$build/artifacts/$kind-" "$corpus" 2>"$build/$h.log" || status=$?
    echo "$status $kind" >"$build/$h.status" ) &
  running+=("$h")
}
failed=0
finish() {
  wait
  local h status kind
  for h in "${running[@]}"; do
    read -r status kind <"$build/$h.status"
    if [ "$status" -ne 0 ]; then
      tail -n 40 "$build/$h.log"
      echo "$h found a failing input: see $build/artifacts/ (copy it to tests/fuzz/regressions/$kind/)" >&2
      failed=1
    else
      echo "== $h:"
      grep -E "^stat::number_of_executed_units|^stat::peak_rss_mb" "$build/$h.log" || true
    fi
  done
  running=()
  [ "$failed" -eq 0 ] || exit 1
}
# Two harnesses at a time, each on a core of its own for `seconds`: the same
# fuzzing per harness as one after another, in half the time on 2 cores.
run fuzz_vtk_legacy vtk tests/data/broken/*.vtk tests/cli/data/block*.vtk "$real/tetraMesh.vtk" "$real/post.vtk"
run fuzz_vtu vtu tests/data/broken/*.vtu "$real/Tetrahedron.vtu" "$real/disk_out_ref.vtu"
finish
run fuzz_gmsh msh
run fuzz_validate validate
finish
