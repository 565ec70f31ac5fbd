#!/usr/bin/python3
# make_probe.py MESH ARRAY OUT.probe: 20,000 points uniform in MESH's bounds
# (seed 1, rounded to float), ARRAY interpolated there by VTK (python3-vtk9:
# vtkProbeFilter, vtkStaticCellLocator), NaN where VTK finds no cell; the
# records of ../shared/data/oracle (float32 x y z, float64 value, little
# endian). VTK interpolates wedges and pyramids with their own shape
# functions: an independent check of cellray's collapsed hexahedra.
import sys, vtk, struct, random
src, name, dst = sys.argv[1], sys.argv[2], sys.argv[3]
r = vtk.vtkUnstructuredGridReader() if src.endswith('.vtk') else vtk.vtkXMLUnstructuredGridReader()
r.SetFileName(src); r.Update(); g = r.GetOutput()
b = g.GetBounds()
random.seed(1)
pts = vtk.vtkPoints()
P=[]
for i in range(20000):
    p = (random.uniform(b[0], b[1]), random.uniform(b[2], b[3]), random.uniform(b[4], b[5]))
    p = tuple(struct.unpack('f', struct.pack('f', c))[0] for c in p)
    P.append(p); pts.InsertNextPoint(p)
pd = vtk.vtkPolyData(); pd.SetPoints(pts)
loc = vtk.vtkStaticCellLocator(); loc.SetDataSet(g); loc.BuildLocator()
pr = vtk.vtkProbeFilter(); pr.SetInputData(pd); pr.SetSourceData(g)
pr.SetCellLocatorPrototype(loc) if hasattr(pr,'SetCellLocatorPrototype') else None
pr.Update(); o = pr.GetOutput()
valid = o.GetPointData().GetArray(pr.GetValidPointMaskArrayName()); arr = o.GetPointData().GetArray(name)
with open(dst, 'wb') as f:
    for i,p in enumerate(P):
        v = arr.GetTuple1(i) if valid.GetTuple1(i) else float('nan')
        f.write(struct.pack('<fffd', p[0], p[1], p[2], v))
print('inside', sum(1 for i in range(len(P)) if valid.GetTuple1(i)))
