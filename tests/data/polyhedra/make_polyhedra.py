#!/usr/bin/python3
# Writes the small polyhedron files the io tests read (needs python3-vtk9):
#   two_polyhedra.vtu  a unit cube written as a polyhedron (6 quads) and,
#                      apart from it, a pentagonal prism (two pentagons,
#                      five quads; z from 1.5 to 2), with point array
#                      T = x + 2y + 3z, cell array T (10, 20) and cell
#                      array id (1, 2);
#   open_polyhedron.vtu      the cube without its top face;
#   bad_face_id.vtu          a face naming point 99 of 14;
#   mixed_polyhedra.vtu      the two polyhedra among other cells, in the
#                            order hexahedron, cube, tetrahedron, prism,
#                            wedge (the others beside the cube, x from 2),
#                            with the same arrays (cell T 5, 10, 15, 20, 25;
#                            id 0, 1, 0, 2, 0);
# and each of two_polyhedra and mixed_polyhedra as legacy .vtk, VTK 9.1's
# writer: <name>_42.vtk / <name>_42b.vtk (version 4.2, ASCII / binary: the
# face stream as the cell's CELLS entry) and <name>_51.vtk / <name>_51b.vtk
# (version 5.1: the face stream as the cell's CONNECTIVITY range).
import math, vtk

def grid(drop_top=False, bad_id=False, mixed=False):
    pts = vtk.vtkPoints()
    cube = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    for p in cube: pts.InsertNextPoint(p)
    for k in range(5):  # the prism's base ring at z = 1.5
        a = 2 * math.pi * k / 5
        pts.InsertNextPoint(0.5 + 0.5 * math.cos(a), 0.5 + 0.5 * math.sin(a), 1.5)
    g = vtk.vtkUnstructuredGrid()
    g.SetPoints(pts)
    faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]  # outward
    if drop_top: faces = faces[:1] + faces[2:]
    if bad_id: faces[1] = [4, 5, 6, 99]
    stream = [len(faces)]
    for f in faces: stream += [len(f)] + f
    ids = vtk.vtkIdList()
    for v in stream: ids.InsertNextId(v)
    if mixed: g.InsertNextCell(vtk.VTK_HEXAHEDRON, 8, list(range(18, 26)))  # its points come after the prism's
    g.InsertNextCell(vtk.VTK_POLYHEDRON, ids)
    if mixed: g.InsertNextCell(vtk.VTK_TETRA, 4, [26, 27, 28, 29])
    # The pentagonal prism: the ring above and its lid at z = 2.
    base = list(range(8, 13))
    for k in range(5):
        a = 2 * math.pi * k / 5
        pts.InsertNextPoint(0.5 + 0.5 * math.cos(a), 0.5 + 0.5 * math.sin(a), 2.0)
    lid = list(range(13, 18))
    pf = [list(reversed(base)), lid] + [[base[k], base[(k + 1) % 5], lid[(k + 1) % 5], lid[k]] for k in range(5)]
    stream = [len(pf)]
    for f in pf: stream += [len(f)] + f
    ids = vtk.vtkIdList()
    for v in stream: ids.InsertNextId(v)
    g.InsertNextCell(vtk.VTK_POLYHEDRON, ids)
    if mixed:
        g.InsertNextCell(vtk.VTK_WEDGE, 6, [30, 31, 32, 33, 34, 35])
        for p in [(2, 0, 0), (3, 0, 0), (3, 1, 0), (2, 1, 0), (2, 0, 1), (3, 0, 1), (3, 1, 1), (2, 1, 1),  # hexahedron
                  (2, 0, 2), (3, 0, 2), (2, 1, 2), (2, 0, 3),  # tetrahedron
                  (2, 0, 4), (3, 0, 4), (2, 1, 4), (2, 0, 5), (3, 0, 5), (2, 1, 5)]:  # wedge
            pts.InsertNextPoint(p)
    t = vtk.vtkFloatArray(); t.SetName("T")
    for i in range(g.GetNumberOfPoints()):
        x, y, z = g.GetPoint(i); t.InsertNextValue(x + 2 * y + 3 * z)
    g.GetPointData().AddArray(t)
    ct = vtk.vtkFloatArray(); ct.SetName("T")
    cid = vtk.vtkFloatArray(); cid.SetName("id")
    for v, i in ([(5, 0), (10, 1), (15, 0), (20, 2), (25, 0)] if mixed else [(10, 1), (20, 2)]):
        ct.InsertNextValue(v); cid.InsertNextValue(i)
    g.GetCellData().AddArray(ct); g.GetCellData().AddArray(cid)
    return g

for name, kw in [("two_polyhedra.vtu", {}), ("open_polyhedron.vtu", {"drop_top": True}), ("bad_face_id.vtu", {"bad_id": True}),
                 ("mixed_polyhedra.vtu", {"mixed": True})]:
    w = vtk.vtkXMLUnstructuredGridWriter()
    w.SetFileName(name); w.SetDataModeToAscii(); w.SetInputData(grid(**kw)); w.Write()

for name, kw in [("two_polyhedra", {}), ("mixed_polyhedra", {"mixed": True})]:
    for version, binary in [(42, False), (42, True), (51, False), (51, True)]:
        w = vtk.vtkUnstructuredGridWriter()
        w.SetFileName("%s_%d%s.vtk" % (name, version, "b" if binary else ""))
        if version == 42: w.SetFileVersion(42)  # else the default, 5.1
        if binary: w.SetFileTypeToBinary()
        w.SetInputData(grid(**kw)); w.Write()
