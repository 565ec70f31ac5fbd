#!/usr/bin/env bash
# Renders a turntable with cellray-render --orbit and makes an MP4 of it
# with Debian's ffmpeg (installed here if missing).
# usage: scripts/turntable.sh OUT.mp4 [cellray-render flags, e.g. MESH --array T --orbit 120]
#   The frames go to a folder beside OUT (OUT without .mp4, plus _frames/),
#   kept for reuse; --orbit defaults to 120 views (4 s at 30 frames/s) and
#   --size to 960x720. FPS=30 and CELLRAY_RENDER=<binary> may be set.
set -euo pipefail
[ $# -ge 1 ] || { sed -n 2,8p "$0" >&2; exit 2; }
out=$1
shift
case "$out" in *.mp4) ;; *) echo "turntable.sh: $out: the output must end in .mp4" >&2; exit 2 ;; esac
cd "$(dirname "$0")/.."
./scripts/install-deps.sh ffmpeg
r=${CELLRAY_RENDER:-./build/examples/cellray-render}
if [ -z "${CELLRAY_RENDER:-}" ]; then
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build build -j"$(nproc)" --target cellray-render
fi
args=("$@")
[[ " ${args[*]} " == *" --orbit "* || " ${args[*]} " == *" --orbit="* ]] || args+=(--orbit 120)
[[ " ${args[*]} " == *" --size "* || " ${args[*]} " == *" --size="* ]] || args+=(--size 960x720)
frames=${out%.mp4}_frames
mkdir -p "$frames" "$(dirname "$out")"
rm -f "$frames"/view_*.png
"$r" "${args[@]}" -o "$frames/view.png"
# yuv420p wants even sizes; libx264 with yuv420p plays everywhere.
ffmpeg -loglevel error -y -framerate "${FPS:-30}" -i "$frames/view_%04d.png" \
  -vf "pad=ceil(iw/2)*2:ceil(ih/2)*2" -c:v libx264 -pix_fmt yuv420p -crf 20 "$out"
echo "turntable.sh: wrote $out ($(ls "$frames"/view_*.png | wc -l) frames in $frames)"
