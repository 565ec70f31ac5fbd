#!/usr/bin/env python3
"""Writes the small meshes the hostile-input CLI tests render (tests/cli/hostile.cmake).

Each is a 2x2x2 block of 6-tet cubes (48 tets, 27 vertices) with a smooth
field, changed in one way: coordinates scaled, offset or near float's limits,
values near float's limits or +-inf, a NaN position on a vertex no cell uses.
Run it again after editing; the outputs are committed so tests need no Python.
"""
import os

HERE = os.path.dirname(os.path.abspath(__file__))
N = 2  # cubes per side

# The six tets of a cube around its main diagonal (corner ids 0..7, bit k = axis k).
CUBE_TETS = [(0, 1, 3, 7), (0, 3, 2, 7), (0, 2, 6, 7), (0, 6, 4, 7), (0, 4, 5, 7), (0, 5, 1, 7)]


def block():
    pts = [(x, y, z) for z in range(N + 1) for y in range(N + 1) for x in range(N + 1)]
    vid = lambda x, y, z: x + (N + 1) * (y + (N + 1) * z)
    tets = []
    for z in range(N):
        for y in range(N):
            for x in range(N):
                c = [vid(x + (k & 1), y + (k >> 1 & 1), z + (k >> 2 & 1)) for k in range(8)]
                tets += [tuple(c[i] for i in t) for t in CUBE_TETS]
    vals = [0.3 * p[0] + 0.25 * p[1] * p[1] + 0.2 * p[2] for p in pts]
    return pts, tets, vals


def write(name, pts, tets, vals, ptype="double", fmt="%.17g", extra_pts=()):
    pts = list(pts) + list(extra_pts)
    vals = list(vals) + [0.0] * len(extra_pts)
    lines = ["# vtk DataFile Version 2.0", name, "ASCII", "DATASET UNSTRUCTURED_GRID",
             "POINTS %d %s" % (len(pts), ptype)]
    lines += [" ".join(fmt % c if isinstance(c, float) else str(c) for c in p) for p in pts]
    lines.append("CELLS %d %d" % (len(tets), 5 * len(tets)))
    lines += ["4 %d %d %d %d" % t for t in tets]
    lines.append("CELL_TYPES %d" % len(tets))
    lines += ["10"] * len(tets)
    lines += ["POINT_DATA %d" % len(pts), "SCALARS s %s" % ptype, "LOOKUP_TABLE default"]
    lines += [v if isinstance(v, str) else fmt % v for v in vals]
    with open(os.path.join(HERE, name), "w") as f:
        f.write("\n".join(lines) + "\n")


pts, tets, vals = block()
write("block.vtk", pts, tets, vals)
write("block_scaled_1e-30.vtk", [tuple(1e-30 * c for c in p) for p in pts], tets, vals)
write("block_scaled_1e30.vtk", [tuple(1e30 * c for c in p) for p in pts], tets, vals)
write("block_offset_1e7.vtk", [tuple(1e7 + c for c in p) for p in pts], tets, vals)
# Coordinates spanning float's range: [-3e38, 3e38] (float32 in the file).
write("block_huge.vtk", [tuple(3e38 * (c - 1.0) for c in p) for p in pts], tets, vals, "float", "%.9g")
write("block_huge_values.vtk", pts, tets, [3e38 * (2 * v / max(vals) - 1) for v in vals], "float", "%.9g")
# Every 5th value +-inf: those vertices' cells are invisible, as with NaN.
write("block_inf.vtk", pts, tets, [("inf" if k % 2 else "-inf") if k % 5 == 0 else v for k, v in enumerate(vals)])
write("block_nan.vtk", pts, tets, ["nan" if k % 5 == 0 else v for k, v in enumerate(vals)])
write("block_constant.vtk", pts, tets, [1.5] * len(vals))
# A vertex no cell uses, at a NaN position: ignored with a warning.
write("block_nan_unused_vertex.vtk", pts, tets, vals, extra_pts=[("nan", "nan", "nan")])
