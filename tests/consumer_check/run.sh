#!/usr/bin/env bash
# Installs cellray from a configured build tree into a scratch prefix, builds
# tests/consumer against it with find_package(cellray), runs it, and checks
# the image it writes: a 64x48 binary PPM that is not one flat colour.
# usage: run.sh <cellray build dir> <consumer source dir> <scratch dir> <c++ compiler>
set -euo pipefail
build=$1 consumer=$2 work=$3 cxx=$4
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" >"$work/install.log"
cmake -S "$consumer" -B "$work/build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER="$cxx" \
  -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_FIND_PACKAGE_PREFER_CONFIG=ON
# The consumer must find the installed package, not the source tree.
grep -q "^cellray_DIR:PATH=$work/prefix/" "$work/build/CMakeCache.txt" ||
  { echo "FAIL: cellray was not found in the install prefix"; grep cellray_DIR "$work/build/CMakeCache.txt"; exit 1; }
cmake --build "$work/build" -j2
img="$work/consumer.ppm"
"$work/build/consumer" "$img"
header=$(head -c 13 "$img" | tr '\n' ' ')
[ "$header" = "P6 64 48 255 " ] || { echo "FAIL: unexpected PPM header '$header'"; exit 1; }
size=$(stat -c %s "$img")
[ "$size" = $((13 + 64 * 48 * 3)) ] || { echo "FAIL: $img has $size bytes"; exit 1; }
distinct=$(tail -c +14 "$img" | od -An -tu1 -v | tr -s ' ' '\n' | sed '/^$/d' | sort -u | wc -l)
[ "$distinct" -gt 8 ] || { echo "FAIL: the image is (nearly) flat: $distinct distinct byte values"; exit 1; }
echo "ok: installed, built and ran the consumer; $img is 64x48 with $distinct distinct byte values"
