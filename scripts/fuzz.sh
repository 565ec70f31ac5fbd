#!/usr/bin/env bash
# Builds the libFuzzer harnesses (clang, ASan + UBSan) and runs each for a
# bounded time: scripts/fuzz.sh [seconds per harness, default 60] [build dir].
#   CI:       scripts/fuzz.sh 30            (3 x 30 s of one core: 45 s on 2 cores)
#   Longer:   scripts/fuzz.sh 3600 build-fuzz   (the corpus in the build dir grows across runs)
# A crash, hang (> 10 s) or out-of-memory (> 2 GB) input is written to
# <build>/artifacts/<kind>-crash-..., that harness stops and this script fails.
# Make it a regression: copy the file into tests/fuzz/regressions/<harness>/
# (vtk, vtu or validate), fix the bug, and ctest replays it from then on.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
build=${2:-build-fuzz}
cxx=${CELLRAY_FUZZ_CXX:-clang++-14}
shared=../shared/data/vtk-data

# One ISA unit (the widest this CPU runs) keeps the instrumented build short.
cmake -S tests/fuzz -B "$build" -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCELLRAY_ISAS="${CELLRAY_FUZZ_ISAS:-$(./scripts/widest-isa.sh)}" >/dev/null
cmake --build "$build" -j"$(nproc)" --target fuzz_vtk_legacy fuzz_vtu fuzz_validate
mkdir -p "$build/artifacts"

# The three harnesses fuzz side by side, each getting about `seconds` of one
# core: on fewer cores than harnesses their (wall-clock) time limit is
# stretched to seconds * 3 / cores (2 cores: 45 s each for 30), which is the
# same CPU per harness as running them one after another, in 2/3 of the time.
harnesses=3
cores=$(nproc)
[ "$cores" -gt "$harnesses" ] && cores=$harnesses
wall=$(( (seconds * harnesses + cores - 1) / cores ))

# start <harness> <kind: vtk|vtu|validate> [extra seed files...]: seeds and
# regressions of that kind are copied into a corpus that persists in the
# build dir, so longer runs build on earlier ones; the harness runs in the
# background (pid in pids[<harness>]).
declare -A pids kinds
start() {
  local h=$1 kind=$2 corpus="$build/corpus/$2"
  shift 2
  mkdir -p "$corpus"
  for f in tests/fuzz/seeds/"$kind"/* tests/fuzz/regressions/"$kind"/* "$@"; do
    [ -f "$f" ] && cp -n "$f" "$corpus"/
  done
  echo "== $h for ${wall}s beside the others (corpus $corpus)"
  "$build/$h" -max_total_time="$wall" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$build/artifacts/$kind-" "$corpus" 2>"$build/$h.log" &
  pids[$h]=$!
  kinds[$h]=$kind
}
start fuzz_vtk_legacy vtk tests/data/broken/*.vtk "$shared/tetraMesh.vtk" "$shared/post.vtk"
start fuzz_vtu vtu tests/data/broken/*.vtu "$shared/Tetrahedron.vtu" "$shared/disk_out_ref.vtu"
start fuzz_validate validate

failed=0
for h in fuzz_vtk_legacy fuzz_vtu fuzz_validate; do
  if wait "${pids[$h]}"; then
    echo "== $h:"
    grep -E "^stat::number_of_executed_units|^stat::peak_rss_mb" "$build/$h.log" || true
  else
    tail -n 40 "$build/$h.log"
    echo "$h found a failing input: see $build/artifacts/ (copy it to tests/fuzz/regressions/${kinds[$h]}/)" >&2
    failed=1
  fi
done
exit $failed
