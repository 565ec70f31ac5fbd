#!/usr/bin/env bash
# Image writes that fail keep the old file and exit 3 (issue #24, item 6):
# a link to /dev/full, and a file-size limit while replacing a PNG and a PPM.
# usage: write_errors.sh CELLRAY_RENDER OUTDIR
set -u
render=$1
dir=$2/write_errors
rm -rf "$dir"
mkdir -p "$dir"
fail() { echo "FAIL: $*"; cat "$dir/err" 2>/dev/null; exit 1; }

ln -s /dev/full "$dir/full.png"
"$render" --cells 1000 --size 32x24 -o "$dir/full.png" 2>"$dir/err"
rc=$?
[ "$rc" = 3 ] || fail "-o through a link to /dev/full: exit $rc, expected 3"
grep -q "full.png" "$dir/err" || fail "the message does not name full.png"
echo "ok: a link to /dev/full exits 3"

for ext in png ppm; do
  "$render" --cells 1000 --size 32x24 -o "$dir/old.$ext" 2>"$dir/err" || fail "first render ($ext)"
  cp "$dir/old.$ext" "$dir/keep.$ext"
  # 1 KiB limit: the new, larger image cannot be written. The renderer
  # ignores SIGXFSZ, so write() fails with EFBIG and it reports the error.
  (ulimit -f 1 && exec "$render" --cells 2000 --size 256x192 -o "$dir/old.$ext") 2>"$dir/err"
  rc=$?
  [ "$rc" = 3 ] || fail "a file-size limit ($ext): exit $rc, expected 3"
  grep -q "old.$ext: cannot write" "$dir/err" || fail "the message does not name old.$ext"
  cmp -s "$dir/old.$ext" "$dir/keep.$ext" || fail "old.$ext changed although the write failed"
  leftovers=$(find "$dir" -name ".old.$ext.*" | wc -l)
  [ "$leftovers" = 0 ] || fail "a temporary file was left behind"
  echo "ok: a file-size limit keeps the old $ext and exits 3"
done
