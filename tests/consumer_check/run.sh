#!/usr/bin/env bash
# Installs cellray from a configured build tree into a scratch prefix, builds
# tests/consumer against it with find_package(cellray COMPONENTS io) and
# cellray::io, runs it, and checks the images it writes: a 64x48 binary PPM
# that is not one flat colour (cellray::cellray), and a 32x24 PNG of a tet
# read from a file (cellray::io: readers and stb's PNG writer).
# usage: run.sh <cellray build dir> <consumer source dir> <scratch dir> <c++ compiler>
set -euo pipefail
build=$1 consumer=$2 work=$3 cxx=$4
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" >"$work/install.log"
# At -O1: what is checked is the package (found, linked, dispatched), not the
# code's speed, and the consumer's two ISA units and main compile in half
# the CPU time of -O3 (this test runs beside the others in CI).
cmake -S "$consumer" -B "$work/build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" \
  -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_FIND_PACKAGE_PREFER_CONFIG=ON
# The consumer must find the installed package, not the source tree.
grep -q "^cellray_DIR:PATH=$work/prefix/" "$work/build/CMakeCache.txt" ||
  { echo "FAIL: cellray was not found in the install prefix"; grep cellray_DIR "$work/build/CMakeCache.txt"; exit 1; }
cmake --build "$work/build" -j2
img="$work/consumer.ppm"
png="$work/consumer.png"
"$work/build/consumer" "$img" "$png" "$work/tet.vtk"
header=$(head -c 13 "$img" | tr '\n' ' ')
[ "$header" = "P6 64 48 255 " ] || { echo "FAIL: unexpected PPM header '$header'"; exit 1; }
size=$(stat -c %s "$img")
[ "$size" = $((13 + 64 * 48 * 3)) ] || { echo "FAIL: $img has $size bytes"; exit 1; }
distinct=$(tail -c +14 "$img" | od -An -tu1 -v | tr -s ' ' '\n' | sed '/^$/d' | sort -u | wc -l)
[ "$distinct" -gt 8 ] || { echo "FAIL: the image is (nearly) flat: $distinct distinct byte values"; exit 1; }
# PNG: the 8-byte signature, then the IHDR chunk with width and height (big-endian).
sig=$(head -c 8 "$png" | od -An -tx1 | tr -d ' \n')
[ "$sig" = 89504e470d0a1a0a ] || { echo "FAIL: $png is not a PNG (signature $sig)"; exit 1; }
dims=$(od -An -tu1 -j16 -N8 "$png" | tr -s ' ' | sed 's/^ //')
[ "$dims" = "0 0 0 32 0 0 0 24" ] || { echo "FAIL: $png is not 32x24 (IHDR size bytes: $dims)"; exit 1; }
echo "ok: installed, built and ran the consumer; $img is 64x48 with $distinct distinct byte values; $png is a 32x24 PNG"
