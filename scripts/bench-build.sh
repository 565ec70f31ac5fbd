# Sourced (not run) by the scripts that regenerate docs/ from benchmark runs
# (accuracy.sh, failure-report.sh, traversal.sh):
#   bench_build [--with-tests] TARGET...
# installs what is missing (plus python3-matplotlib for the charts),
# configures a Release build with the benchmarks in $CELLRAY_BUILD_DIR
# (default build-bench; --with-tests also configures the tests), builds
# TARGET... and sets $build (that directory) and $py (Debian's python3, which
# has matplotlib; a pyenv python3 on PATH may not).
bench_build() {
  local tests=OFF
  if [ "${1:-}" = --with-tests ]; then tests=ON; shift; fi
  ./scripts/install-deps.sh python3-matplotlib
  build=${CELLRAY_BUILD_DIR:-build-bench}
  cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DCELLRAY_BUILD_TESTS="$tests" -DCELLRAY_BUILD_EXAMPLES=OFF \
    -DCELLRAY_BUILD_BENCH=ON >/dev/null
  cmake --build "$build" -j"$(nproc)" --target "$@"
  mkdir -p docs
  py=/usr/bin/python3
  [ -x "$py" ] || py=python3
}
