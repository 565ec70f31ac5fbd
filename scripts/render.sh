#!/usr/bin/env bash
# Sets up (Debian packages, Release build) and renders the built-in default
# scene to out/default.png. Arguments go to cellray-render (see --help),
# e.g. ./scripts/render.sh tests/data/real/vtk-data/post.vtk -o out/post.png
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCELLRAY_BUILD_TESTS=OFF -DCELLRAY_BUILD_BENCH=OFF >/dev/null
cmake --build build -j"$(nproc)" --target cellray-render
mkdir -p out
if [ $# -eq 0 ]; then
  set -- -o out/default.png
fi
./build/examples/cellray-render "$@"
