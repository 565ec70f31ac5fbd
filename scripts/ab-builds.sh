#!/usr/bin/env bash
# Two builds of cellray-render, alternating processes (A B, A B, ...), over
# five workloads: boxturb48 and component8 DVR at #23's representative
# transfer functions (512x512), their isosurfaces (1024x1024), and the flange
# DVR. Prints render_ms_min per run and the ratio A/B (above 1: B faster).
#
#   scripts/ab-builds.sh OLD/cellray-render NEW/cellray-render [rounds] [workloads...]
#
# For changes the in-process harness (ab-harness.patch) cannot see: inlining
# and code placement, which change the whole binary (docs/performance.md,
# "Tried and dropped": hex DVR moved 4-7% between builds of the same march).
# Data: CELLRAY_DATA_DIR, else ../shared/data beside the repository.
set -euo pipefail
[ $# -ge 2 ] || { sed -n 2,12p "$0"; exit 2; }
A=$1 B=$2 ROUNDS=${3:-3}
shift $(( $# >= 3 ? 3 : 2 ))
here=$(cd "$(dirname "$0")/.." && pwd)
data=${CELLRAY_DATA_DIR:-$here/../shared/data}
D=$data/openfoam
for f in boxturb48_dns.vtk component8_heat_608k.vtk flange_snappy_89k.vtu; do
  [ -f "$D/$f" ] || { echo "ab-builds: $D/$f is missing (set CELLRAY_DATA_DIR)" >&2; exit 2; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Opacity where the data is (the trapezoids of issue #23), in file units.
cat > "$tmp/box.json" <<'EOF'
[{"Name": "rep", "RGBPoints": [0.0015834, 0.23, 0.299, 0.754, 0.3594177, 0.865, 0.865, 0.865, 0.717252, 0.706, 0.016, 0.15],
  "Points": [0.0015834, 0, 0.5, 0.0, 0.1, 0, 0.5, 0.0, 0.15963905, 0.3, 0.5, 0.0, 0.27891715, 0.3, 0.5, 0.0, 0.3385562, 0, 0.5, 0.0, 0.717252, 0, 0.5, 0.0]}]
EOF
cat > "$tmp/c8.json" <<'EOF'
[{"Name": "rep", "RGBPoints": [273, 0.23, 0.299, 0.754, 423.0, 0.865, 0.865, 0.865, 573, 0.706, 0.016, 0.15],
  "Points": [273, 0, 0.5, 0.0, 423, 0, 0.5, 0.0, 448.0, 0.3, 0.5, 0.0, 498.0, 0.3, 0.5, 0.0, 523.0, 0, 0.5, 0.0, 573, 0, 0.5, 0.0]}]
EOF
declare -A W
W[box_dvr]="$D/boxturb48_dns.vtk --array enstrophy --mode dvr --tf $tmp/box.json --tf-file-range --opacity 1 --unit-distance 0.049487 --eye 2.37239,1.9043,2.55963 --at 0.5,0.5,0.5 --up 0,1,0 --fov 30 --size 512x512 --frames 5"
W[c8_dvr]="$D/component8_heat_608k.vtk --array T --mode dvr --tf $tmp/c8.json --tf-file-range --opacity 1 --unit-distance 1.6792 --eye 63.5347,219.835,69.8882 --at 0,172.184,0 --up 0,1,0 --fov 30 --size 512x512 --frames 5"
W[c8_iso]="$D/component8_heat_608k.vtk --array T --iso 423 --iso-opacity 1 --eye 63.5347,219.835,69.8882 --at 0,172.184,0 --up 0,1,0 --fov 30 --size 1024x1024 --frames 7"
W[box_iso]="$D/boxturb48_dns.vtk --array enstrophy --iso 0.1 --iso-opacity 1 --eye 2.37239,1.9043,2.55963 --at 0.5,0.5,0.5 --up 0,1,0 --fov 30 --size 1024x1024 --frames 7"
W[flange_dvr]="$D/flange_snappy_89k.vtu --mode dvr --size 512x384 --frames 5"
run() {
  # shellcheck disable=SC2086
  "$1" ${W[$2]} --threads 1 --stats -o "$tmp/ab.png" 2>/dev/null |
    python3 -c "import json,sys; print('%.1f' % json.load(sys.stdin)['render_ms_min'])"
}
workloads=("$@")
[ ${#workloads[@]} -gt 0 ] || workloads=(box_dvr c8_dvr c8_iso box_iso flange_dvr)
for r in $(seq "$ROUNDS"); do
  for w in "${workloads[@]}"; do
    [ -n "${W[$w]:-}" ] || { echo "ab-builds: unknown workload $w" >&2; exit 2; }
    a=$(run "$A" "$w") b=$(run "$B" "$w")
    echo "round $r $w A=$a B=$b A/B=$(python3 -c "print('%.3f' % ($a / $b))")"
  done
done
