#!/usr/bin/env bash
# Regenerates the pictures in docs/images/ shown in the README, with
# cellray-render from a Release build in build/ (built here if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
# The meshes come from the shared data set: $CELLRAY_DATA_DIR, by default
# ../shared/data beside the repository.
d=${CELLRAY_DATA_DIR:-../shared/data}
for f in openfoam/component8_heat_608k.vtk openfoam/boxturb48_dns.vtk vtk-data/disk_out_ref.vtu \
    openfoam/flange_snappy_89k.vtu vtk-data/kiefer_dataset.vtu gmsh/component8_84k.msh; do
  [ -f "$d/$f" ] || { echo "make-images.sh: $d/$f missing: set CELLRAY_DATA_DIR to the shared data set" >&2; exit 1; }
done
./scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target cellray-render example_04_embree_host
r=./build/examples/cellray-render
out=docs/images
mkdir -p "$out"
set -x
$r --size 640x480 -o $out/default.png
$r "$d"/openfoam/component8_heat_608k.vtk --array T --iso 330,423,520 --iso-opacity 0.35,0.6,1 \
   --shadows --size 640x480 -o $out/component8_iso_shadows.png
$r "$d"/openfoam/boxturb48_dns.vtk --array enstrophy --iso 0.1,0.25 --iso-opacity 0.3,1 --ao 8 \
   --size 640x480 -o $out/boxturb_iso_ao.png
$r "$d"/openfoam/component8_heat_608k.vtk --array T --mode dvr --tf inferno --size 640x480 \
   -o $out/component8_dvr.png
$r "$d"/vtk-data/disk_out_ref.vtu --array Temp --mode dvr --tf cool-warm --size 640x480 \
   -o $out/disk_out_ref_dvr.png
$r "$d"/openfoam/component8_heat_608k.vtk --array T --mode dvr --tf inferno --legend \
   --title "component8_heat_608k: temperature" --azimuth 25 --size 640x480 -o $out/component8_legend.png
$r "$d"/openfoam/component8_heat_608k.vtk --array T --iso 330,423,520 --iso-opacity 0.35,0.6,1 --legend \
   --size 640x480 -o $out/component8_iso_legend.png
$r "$d"/openfoam/component8_heat_608k.vtk --array T --iso 423 --normals flat --zoom 2.5 --azimuth 20 \
   --size 480x360 -o $out/component8_normals_flat.png
$r "$d"/openfoam/component8_heat_608k.vtk --array T --iso 423 --zoom 2.5 --azimuth 20 \
   --size 480x360 -o $out/component8_normals_smooth.png
$r "$d"/openfoam/boxturb48_dns.vtk --array enstrophy --iso 0.25 --color-by p --color-map cool-warm --legend \
   --title "enstrophy 0.25 coloured by pressure" --size 480x360 -o $out/boxturb_color_by_p.png
$r "$d"/openfoam/component8_heat_608k.vtk --array T --iso 330,423,520 --iso-opacity 0.35,0.6,1 \
   --clip 0,172,0,0,0,1 --clip-caps --color-map inferno --size 480x360 -o $out/component8_clip_caps.png
$r "$d"/openfoam/component8_heat_608k.vtk --array T --mode dvr --tf inferno --clip 0,172,0,0,0,1 \
   --size 480x360 -o $out/component8_clip_dvr.png
# The snappyHexMesh flange: hexahedra, wedges and polyhedra (split by cellray).
$r "$d"/openfoam/flange_snappy_89k.vtu --mode iso --iso 300,450 --iso-opacity 1 --clip 0,0,-0.005,0,0,1 \
   --clip-caps --color-map inferno --legend --title "snappy flange: T, cut at z = -5 mm" --size 480x360 \
   -o $out/flange_snappy_iso.png
$r "$d"/openfoam/flange_snappy_89k.vtu --mode dvr --tf inferno --legend --title "snappy flange: T" \
   --size 480x360 -o $out/flange_snappy_dvr.png
# Files without point data: the FEA bracket's cell stress averaged to the
# vertices; the bare gmsh mesh by its longest coordinate.
$r "$d"/vtk-data/kiefer_dataset.vtu --iso 0.5,2,6 --legend --title "kiefer bracket: stress (psi)" \
   --size 480x360 -o $out/kiefer_stress_iso.png
$r "$d"/gmsh/component8_84k.msh --mode dvr --size 480x360 -o $out/component8_msh_dvr.png
# A narrow opacity peak (T from 472 to 474 K, opacity 1 at 473): cell
# segments at the default step and the double-precision reference.
for ref in "" --reference; do
  $r "$d"/openfoam/component8_heat_608k.vtk --array T --mode dvr --tf docs/images/narrow_peak_tf.json \
     --tf-file-range --unit-distance 0.3 --background white $ref --size 400x300 \
     -o $out/component8_narrow_peak${ref:+_reference}.png
done
# The Embree host example (examples/04_embree_host.cpp): its generated mesh.
./build/examples/04_embree_host $out/embree_host.png
./build/examples/04_embree_host --iso $out/embree_host_iso.png
