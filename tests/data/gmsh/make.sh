#!/usr/bin/env bash
# Regenerates the gmsh meshes tests/test_io_gmsh.cpp compares (gmsh 4.8.4,
# Debian package gmsh): each mesh as MSH 2.2, MSH 4.1 and second order,
# and as gmsh's own legacy VTK export, the independent reference for the
# node order (gmsh writes its prisms' corners 0 2 1 3 5 4 there).
#   mixed.geo: a transfinite hexahedron block glued to a tetrahedron block,
#              pyramids between them (with points, lines and quads on the
#              boundary, as gmsh saves them).
#   layer.geo: a triangulated square extruded into two layers of prisms.
set -euo pipefail
cd "$(dirname "$0")"
gmsh mixed.geo -3 -format msh22 -o mixed22.msh
gmsh mixed.geo -3 -format msh41 -o mixed41.msh
gmsh mixed.geo -3 -order 2 -format msh22 -o mixed22_order2.msh
gmsh mixed.geo -3 -o mixed.vtk
gmsh layer.geo -3 -format msh22 -o layer22.msh
gmsh layer.geo -3 -order 2 -format msh22 -o layer22_order2.msh
gmsh layer.geo -3 -o layer.vtk
