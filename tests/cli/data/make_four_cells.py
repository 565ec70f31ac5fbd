#!/usr/bin/python3
# Writes four_cells.vtu and four_cells.e (tests/cli/exodus_check.cpp): one
# hexahedron, wedge, pyramid and tetrahedron, positively oriented in VTK's
# node order, with a point array T, through VTK 9.1's own writers (Debian
# python3-vtk9; run it with /usr/bin/python3). VTK's Exodus writer is the
# reference for how a VTK cell's nodes are ordered in an Exodus file.
import vtk

P = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1),  # hexahedron 0-7
     (2, 0, 0), (2, 0, 1),  # the wedge's far edge
     (0.5, 0.5, 2),         # the pyramid's apex
     (-1, 0, 0)]            # the tetrahedron's fourth corner
pts = vtk.vtkPoints()
for p in P:
    pts.InsertNextPoint(p)
g = vtk.vtkUnstructuredGrid()
g.SetPoints(pts)
for t, ids in [(vtk.VTK_HEXAHEDRON, [0, 1, 2, 3, 4, 5, 6, 7]),
               (vtk.VTK_WEDGE, [1, 2, 8, 5, 6, 9]),  # bottom triangle's normal points away from the top
               (vtk.VTK_PYRAMID, [4, 5, 6, 7, 10]),
               (vtk.VTK_TETRA, [11, 0, 3, 4])]:
    l = vtk.vtkIdList()
    for i in ids:
        l.InsertNextId(i)
    g.InsertNextCell(t, l)
T = vtk.vtkDoubleArray()
T.SetName("T")
for i in range(len(P)):
    T.InsertNextValue(100.0 + i)
g.GetPointData().AddArray(T)
blocks = vtk.vtkIntArray()  # one Exodus element block per cell
blocks.SetName("ElementBlockIds")
for i in range(g.GetNumberOfCells()):
    blocks.InsertNextValue(i + 1)
g.GetCellData().AddArray(blocks)
w = vtk.vtkXMLUnstructuredGridWriter()
w.SetFileName("four_cells.vtu")
w.SetInputData(g)
w.SetDataModeToAscii()
w.Write()
e = vtk.vtkExodusIIWriter()
e.SetFileName("four_cells.e")
e.SetInputData(g)
e.WriteAllTimeStepsOff()
e.Write()
