#!/usr/bin/env bash
# Regenerates the gmsh meshes tests/test_io_gmsh.cpp compares (gmsh 4.8.4,
# Debian package gmsh): each mesh as MSH 2.2, MSH 4.1 and second order,
# and as gmsh's own legacy VTK export, the independent reference for the
# node order (gmsh writes its prisms' corners 0 2 1 3 5 4 there); binary
# twins (*_bin.msh, gmsh -bin) of some, which must read as their ASCII
# files; layer.geo as MSH 4.0 (-format msh40, ASCII: gmsh 4.8 writes no
# 4.0 binary).
#   mixed.geo: a transfinite hexahedron block glued to a tetrahedron block,
#              pyramids between them (with points, lines and quads on the
#              boundary, as gmsh saves them).
#   layer.geo: a triangulated square extruded into two layers of prisms.
#   sphere_bl.geo: a sphere in a box, tetrahedra around its boundary layer
#              (sphere_bl_small.msh, sphere_bl_prisms_small.msh: the CLI
#              tests of folding).
#   views.geo: layer.geo with a node view "T" and an element view "q",
#              saved as views22[_bin].msh and views41[_bin].msh.
set -euo pipefail
cd "$(dirname "$0")"
gmsh mixed.geo -3 -format msh22 -o mixed22.msh
gmsh mixed.geo -3 -format msh41 -o mixed41.msh
gmsh mixed.geo -3 -order 2 -format msh22 -o mixed22_order2.msh
gmsh mixed.geo -3 -o mixed.vtk
gmsh layer.geo -3 -format msh22 -o layer22.msh
gmsh layer.geo -3 -order 2 -format msh22 -o layer22_order2.msh
gmsh layer.geo -3 -o layer.vtk
gmsh mixed.geo -3 -format msh22 -bin -o mixed22_bin.msh
gmsh mixed.geo -3 -format msh41 -bin -o mixed41_bin.msh
gmsh layer.geo -3 -order 2 -format msh22 -bin -o layer22_order2_bin.msh
gmsh layer.geo -3 -format msh40 -o layer40.msh
# Each view is saved with the mesh; the element view's section is then
# appended to the node view's file (same mesh, version and file type).
join() {
  python3 -c 'import sys
t, q = (open(f, "rb").read() for f in sys.argv[1:3])
i = q.index(b"$ElementData\n")
j = q.index(b"$EndElementData\n", i) + len(b"$EndElementData\n")
open(sys.argv[3], "wb").write(t + q[i:j])' "$1" "$2" "$3"
}
for version in 22 41; do
  for binary in 0 1; do
    out=views$version$([ $binary = 1 ] && echo _bin || true)
    gmsh views.geo -parse_and_exit -setnumber version "${version:0:1}.${version:1}" -setnumber binary $binary -setstring out "$out"
    join "${out}_T.msh" "${out}_q.msh" "$out.msh"
    rm "${out}_T.msh" "${out}_q.msh"
  done
done
# sphere_bl.geo: tetrahedra around a boundary layer of hexahedra, prisms and
# pyramids (75% tets; the benchmark sizes are in the .geo), MSH 2.2 binary.
gmsh sphere_bl.geo -parse_and_exit -setnumber h 0.2 -setnumber hfar 1.0 -setnumber quads 1 -setnumber version 2.2 \
  -setstring out sphere_bl_small
# The same with a layer of prisms alone: 46% tets, not folded by default.
gmsh sphere_bl.geo -parse_and_exit -setnumber h 0.2 -setnumber hfar 1.0 -setnumber quads 0 -setnumber version 2.2 \
  -setstring out sphere_bl_prisms_small
