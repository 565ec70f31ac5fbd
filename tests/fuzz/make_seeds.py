#!/usr/bin/env python3
"""Writes the fuzz seed files next to this script (seeds/vtk, seeds/vtu,
seeds/msh, seeds/validate): one small mixed mesh (a tetrahedron, a hexahedron and a
wedge) in every dialect the readers support, so the fuzzer starts inside each
decoding path (legacy ASCII/BINARY old and 5.1 layouts; VTU ascii, inline
base64, appended raw/base64, zlib, 32/64-bit headers, both byte orders), and
a few decoded meshes for the validate harness; and legacy 4.2 and 5.1 files
with a polyhedron too (the hexahedron's cube again as a face stream, VTK
9.1's layout), so the fuzzer starts inside the polyhedra split; gmsh MSH
2.2 and 4.1 binary files (4.1 in both byte orders) and a 4.0 ASCII one with
node and element data (seeds/msh/mixed22.msh and mixed41.msh, the ASCII
seeds, are written by hand). The outputs are committed; run again after
editing.
"""
import base64
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))

XYZ = [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1,
       2, 0, 0, 3, 0, 0, 3, 1, 0, 2, 1, 0, 2, 0, 1, 3, 0, 1, 3, 1, 1, 2, 1, 1]
CELLS = [(10, [0, 1, 2, 3]), (12, [4, 5, 6, 7, 8, 9, 10, 11]), (13, [0, 1, 2, 4, 5, 7])]
TEMP = [0.1 * i for i in range(12)]
PRESSURE = [1.5, -2.0, 3.25]
# The hexahedron's cube as a polyhedron: [nFaces, nPts, ids..., ...], outward faces.
CUBE = [[4, 7, 6, 5], [8, 9, 10, 11], [4, 5, 9, 8], [5, 6, 10, 9], [6, 7, 11, 10], [7, 4, 8, 11]]
POLY_CELLS = CELLS + [(42, [len(CUBE)] + [x for f in CUBE for x in [len(f)] + f])]


def put(sub, name, data):
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(HERE, "seeds", sub, name), "wb") as f:
        f.write(data)


# --- legacy VTK ---------------------------------------------------------------
def legacy(version, binary, new_layout, cells=CELLS, pressure=PRESSURE):
    def block(fmt, values):
        if binary:
            return struct.pack(">%d%s" % (len(values), fmt), *values) + b"\n"
        return (" ".join(str(v) for v in values) + "\n").encode()

    o = ("# vtk DataFile Version %s\nseed\n%s\nDATASET UNSTRUCTURED_GRID\n" %
         (version, "BINARY" if binary else "ASCII")).encode()
    o += b"POINTS 12 float\n" + block("f", XYZ)
    if new_layout:
        offsets, conn = [0], []
        for _, ids in cells:
            conn += ids
            offsets.append(len(conn))
        o += b"CELLS %d %d\nOFFSETS vtktypeint64\n" % (len(offsets), len(conn)) + block("q", offsets)
        o += b"CONNECTIVITY vtktypeint64\n" + block("q", conn)
    else:
        flat = []
        for _, ids in cells:
            flat += [len(ids)] + ids
        o += b"CELLS %d %d\n" % (len(cells), len(flat)) + block("i", flat)
    o += b"CELL_TYPES %d\n" % len(cells) + block("i", [t for t, _ in cells])
    o += b"POINT_DATA 12\nSCALARS temperature float 1\nLOOKUP_TABLE default\n" + block("f", TEMP)
    o += b"FIELD FieldData 1\nvelocity 3 12 double\n" + block("d", [0.5] * 36)
    o += b"CELL_DATA %d\nSCALARS pressure double\nLOOKUP_TABLE default\n" % len(cells) + block("d", pressure)
    return o


for version in ["2.0", "3.0", "4.2", "5.1"]:
    for binary in [False, True]:
        name = "v%s_%s.vtk" % (version.replace(".", ""), "binary" if binary else "ascii")
        put("vtk", name, legacy(version, binary, version == "5.1"))
for version in ["4.2", "5.1"]:
    for binary in [False, True]:
        name = "poly%s_%s.vtk" % (version.replace(".", ""), "binary" if binary else "ascii")
        put("vtk", name, legacy(version, binary, version == "5.1", POLY_CELLS, PRESSURE + [4.5]))


# --- VTU ----------------------------------------------------------------------
def vtu(fmt, appended_b64=False, u64=False, compress=False, big=False):
    end = ">" if big else "<"
    appended = bytearray()

    def header(values):
        return struct.pack(end + ("%dQ" if u64 else "%dI") % len(values), *values)

    def pack(raw):
        if not compress:
            return header([len(raw)]), raw
        block = 40
        chunks = [zlib.compress(raw[i:i + block], 6) for i in range(0, len(raw), block)] or [zlib.compress(b"")]
        last = len(raw) % block
        return header([len(chunks), block, last] + [len(c) for c in chunks]), b"".join(chunks)

    def array(vtype, code, name, ncomp, values):
        o = '<DataArray type="%s" Name="%s" NumberOfComponents="%d" format="%s"' % (vtype, name, ncomp, fmt)
        if fmt == "ascii":
            return o + ">\n" + " ".join(str(v) for v in values) + "\n</DataArray>\n"
        head, data = pack(struct.pack(end + "%d%s" % (len(values), code), *values))
        enc = base64.b64encode(head) + base64.b64encode(data)
        if fmt == "binary":
            return o + ">\n  " + enc.decode() + "\n</DataArray>\n"
        o += ' offset="%d"/>\n' % len(appended)
        appended.extend(enc if appended_b64 else head + data)
        return o

    conn, offsets = [], []
    for _, ids in CELLS:
        conn += ids
        offsets.append(len(conn))
    body = '<Piece NumberOfPoints="12" NumberOfCells="%d">\n<PointData Scalars="temperature">\n' % len(CELLS)
    body += array("Float32", "f", "temperature", 1, TEMP)
    body += array("Float64", "d", "velocity", 3, [0.25] * 36)
    body += "</PointData>\n<CellData>\n" + array("Float64", "d", "pressure", 1, PRESSURE)
    body += "</CellData>\n<Points>\n" + array("Float32", "f", "Points", 3, XYZ) + "</Points>\n<Cells>\n"
    body += array("Int64", "q", "connectivity", 1, conn) + array("Int64", "q", "offsets", 1, offsets)
    body += array("UInt8", "B", "types", 1, [t for t, _ in CELLS]) + "</Cells>\n</Piece>\n"
    head = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" byte_order="%s" header_type="%s"%s>\n'
            '<UnstructuredGrid>\n' % ("BigEndian" if big else "LittleEndian", "UInt64" if u64 else "UInt32",
                                      ' compressor="vtkZLibDataCompressor"' if compress else ""))
    o = head.encode() + body.encode() + b"</UnstructuredGrid>\n"
    if fmt == "appended":
        o += b'<AppendedData encoding="%s">\n   _' % (b"base64" if appended_b64 else b"raw") + bytes(appended)
        o += b"\n</AppendedData>\n"
    return o + b"</VTKFile>\n"


put("vtu", "ascii.vtu", vtu("ascii"))
for compress in [False, True]:
    z = "_zlib" if compress else ""
    put("vtu", "binary%s.vtu" % z, vtu("binary", compress=compress))
    put("vtu", "binary_u64_big%s.vtu" % z, vtu("binary", u64=True, compress=compress, big=True))
    put("vtu", "appended_raw%s.vtu" % z, vtu("appended", compress=compress))
    put("vtu", "appended_raw_u64%s.vtu" % z, vtu("appended", u64=True, compress=compress))
    put("vtu", "appended_base64%s.vtu" % z, vtu("appended", appended_b64=True, compress=compress))


# --- gmsh MSH -----------------------------------------------------------------
# The mesh's tetrahedron, hexahedron and wedge as gmsh elements (tags from 1;
# a gmsh prism's triangles run the other way round), a boundary triangle, a
# node view and an element view.
MSH_TYPES = {10: 4, 12: 5, 13: 6}
MSH_ELEMENTS = [(MSH_TYPES[t], [i + 1 for i in (ids if t != 13 else [ids[k] for k in (0, 2, 1, 3, 5, 4)])])
                for t, ids in CELLS] + [(2, [1, 2, 3])]


def msh_data(section, name, records, binary, end):
    o = ('$%s\n1\n"%s"\n1\n0.0\n3\n0\n1\n%d\n' % (section, name, len(records))).encode()
    for tag, value in records:
        o += struct.pack(end + "id", tag, value) if binary else b"%d %r\n" % (tag, value)
    return o + (b"\n" if binary else b"") + b"$End%s\n" % section.encode()


def msh(version, binary, big=False):
    end = ">" if big else "<"
    o = b"$MeshFormat\n%s %d 8\n" % (version.encode(), binary)
    if binary:
        o += struct.pack(end + "i", 1) + b"\n"
    o += b"$EndMeshFormat\n"
    pts = [XYZ[3 * i:3 * i + 3] for i in range(12)]
    if version == "2.2":
        o += b"$Nodes\n12\n"
        for i, p in enumerate(pts):
            o += struct.pack(end + "i3d", i + 1, *p) if binary else b"%d %r %r %r\n" % (i + 1, *p)
        o += (b"\n" if binary else b"") + b"$EndNodes\n$Elements\n%d\n" % len(MSH_ELEMENTS)
        for n, (t, ids) in enumerate(MSH_ELEMENTS):
            if binary:
                o += struct.pack(end + "3i", t, 1, 2) + struct.pack(end + "%di" % (3 + len(ids)), n + 1, 1, 1, *ids)
            else:
                o += b"%d %d 2 1 1 %s\n" % (n + 1, t, b" ".join(b"%d" % i for i in ids))
        o += (b"\n" if binary else b"") + b"$EndElements\n"
    elif binary:  # 4.1: one node block, one element block per element
        o += b"$Entities\n" + struct.pack(end + "4Q", 0, 0, 0, 1) + struct.pack(end + "i6dQQ", 1, 0, 0, 0, 3, 1, 1, 0, 0)
        o += b"\n$EndEntities\n$Nodes\n" + struct.pack(end + "4Q", 1, 12, 1, 12) + struct.pack(end + "3iQ", 3, 1, 0, 12)
        o += struct.pack(end + "12Q", *range(1, 13)) + struct.pack(end + "36d", *XYZ) + b"\n$EndNodes\n$Elements\n"
        o += struct.pack(end + "4Q", len(MSH_ELEMENTS), len(MSH_ELEMENTS), 1, len(MSH_ELEMENTS))
        for n, (t, ids) in enumerate(MSH_ELEMENTS):
            o += struct.pack(end + "3iQ", 3 if t != 2 else 2, 1, t, 1) + struct.pack(end + "%dQ" % (1 + len(ids)), n + 1, *ids)
        o += b"\n$EndElements\n"
    else:  # 4.0 ASCII: entity before dimension, a node's tag and coordinates on one line
        o += b"$Nodes\n1 12\n1 3 0 12\n" + b"".join(b"%d %r %r %r\n" % (i + 1, *p) for i, p in enumerate(pts))
        o += b"$EndNodes\n$Elements\n%d %d\n" % (len(MSH_ELEMENTS), len(MSH_ELEMENTS))
        for n, (t, ids) in enumerate(MSH_ELEMENTS):
            o += b"1 %d %d 1\n%d %s\n" % (3 if t != 2 else 2, t, n + 1, b" ".join(b"%d" % i for i in ids))
        o += b"$EndElements\n"
    o += msh_data("NodeData", "temperature", [(i + 1, v) for i, v in enumerate(TEMP)], binary, end)
    o += msh_data("ElementData", "pressure", [(i + 1, v) for i, v in enumerate(PRESSURE)], binary, end)
    return o


put("msh", "binary22.msh", msh("2.2", 1))
put("msh", "binary41.msh", msh("4.1", 1))
put("msh", "binary41_big.msh", msh("4.1", 1, big=True))
put("msh", "ascii40.msh", msh("4", 0))


# --- validate harness (see fuzz_validate.cpp for the byte layout) --------------
def mesh_seed(flags, nv, nc, iso, tuning, coords, ids, values):
    return bytes([flags, nv - 1, nc, iso, tuning] + coords + ids + values)


# A cube lattice point (i, j, k) in the harness's coordinate palette.
def lattice(i, j, k):
    return [i, j, k]


cube = [lattice(i, j, k) for k in (2, 5) for j in (2, 5) for i in (2, 5)]
cube_xyz = [c for p in cube for c in p]
tets = [0, 1, 3, 7, 0, 3, 2, 7, 0, 2, 6, 7, 0, 6, 4, 7, 0, 4, 5, 7, 0, 5, 1, 7]
hexes = [0, 1, 3, 2, 4, 5, 7, 6]
vals = [20, 60, 100, 140, 180, 220, 40, 120]
for frame in range(4):
    put("validate", "tets_frame%d" % frame, mesh_seed(frame << 4, 8, 6, 120, 0x21, cube_xyz, tets, vals))
    put("validate", "hex_frame%d" % frame, mesh_seed(1 | frame << 4, 8, 1, 120, 0x0a, cube_xyz, hexes, vals))
put("validate", "tets_wide_shadows", mesh_seed(0x42 | 0x80, 8, 6, 100, 0x43, cube_xyz, tets, vals))
put("validate", "tets_nan_value", mesh_seed(0, 8, 6, 120, 0, cube_xyz, tets, [240] + vals[1:]))
put("validate", "tets_bad_index", mesh_seed(0, 8, 6, 120, 0, cube_xyz, [250] + tets[1:], vals))
put("validate", "tets_inf_position", mesh_seed(0, 8, 6, 120, 0, [225] + cube_xyz[1:], tets, vals))
