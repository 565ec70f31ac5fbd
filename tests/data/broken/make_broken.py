#!/usr/bin/env python3
"""Writes the hand-made broken mesh files next to this script.

Each file is small and breaks one rule; tests/test_io_broken.cpp lists the
error every file must raise (file name, line or byte offset, message). Run it
again after editing; the outputs are committed so tests need no Python.
"""
import base64
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def put(name, data):
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)


HEAD = "# vtk DataFile Version 2.0\nbroken\nASCII\nDATASET UNSTRUCTURED_GRID\n"
PTS = "POINTS 4 float\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
TET = "CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n"

# --- legacy ASCII -----------------------------------------------------------
put("empty.vtk", b"")
put("not_vtk.vtk", "hello world\n")
put("polydata.vtk", "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 1 float\n0 0 0\n")
put("bad_encoding.vtk", "# vtk DataFile Version 3.0\nx\nTEXT\nDATASET UNSTRUCTURED_GRID\n")
put("truncated_ascii_points.vtk", HEAD + "POINTS 4 float\n0 0 0\n1 0 0\n0 1 0\n")
put("non_numeric.vtk", HEAD + "POINTS 4 float\n0 0 0\n1 abc 0\n0 1 0\n0 0 1\n" + TET)
put("non_numeric_cells.vtk", HEAD + PTS + "CELLS 1 5\n4 0 1 2 x3\nCELL_TYPES 1\n10\n")
put("huge_points.vtk", HEAD + "POINTS 1000000000 float\n0 0 0\n")
put("too_many_points.vtk", HEAD + "POINTS 5000000000 float\n0 0 0\n")
put("huge_cells.vtk", HEAD + PTS + "CELLS 10 999999999999\n4 0 1 2 3\n")
put("huge_count_overflow.vtk", HEAD + "POINTS 99999999999999999999999 float\n")
put("wrong_cells_size.vtk", HEAD + PTS + "CELLS 1 6\n4 0 1 2 3\n0\nCELL_TYPES 1\n10\n")
put("cell_overrun.vtk", HEAD + PTS + "CELLS 2 6\n4 0 1 2 3\n100\nCELL_TYPES 2\n10\n10\n")
put("cell_types_count.vtk", HEAD + PTS + "CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 2\n10 10\n")
put("bad_index.vtk", HEAD + PTS + "CELLS 2 10\n4 0 1 2 3\n4 0 1 2 9\nCELL_TYPES 2\n10\n10\n")
put("negative_index.vtk", HEAD + PTS + "CELLS 1 5\n4 0 -1 2 3\nCELL_TYPES 1\n10\n")
put("unknown_cell_type.vtk", HEAD + PTS + "CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n99\n")
put("quadratic_triangle.vtk", HEAD + "POINTS 6 float\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 1\n0 1 1\n"
    "CELLS 1 7\n6 0 1 2 3 4 5\nCELL_TYPES 1\n22\n")
put("tet_three_ids.vtk", HEAD + PTS + "CELLS 1 4\n3 0 1 2\nCELL_TYPES 1\n10\n")
put("point_data_count.vtk", HEAD + PTS + TET + "POINT_DATA 5\nSCALARS s float\nLOOKUP_TABLE default\n1 2 3 4 5\n")
put("cell_data_count.vtk", HEAD + PTS + TET + "CELL_DATA 2\nSCALARS s float\nLOOKUP_TABLE default\n1 2\n")
put("field_tuples.vtk", HEAD + PTS + TET + "POINT_DATA 4\nFIELD FieldData 1\nT 1 3 float\n1 2 3\n")
put("scalars_no_lookup.vtk", HEAD + PTS + TET + "POINT_DATA 4\nSCALARS s float\n1 2 3 4\n")
put("scalars_outside_section.vtk", HEAD + PTS + TET + "SCALARS s float\nLOOKUP_TABLE default\n1 2 3 4\n")
put("unknown_keyword.vtk", HEAD + PTS + "BOGUS 3\n" + TET)
put("unknown_type.vtk", HEAD + "POINTS 4 float128\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n" + TET)
put("no_cells.vtk", HEAD + PTS)
put("no_cell_types.vtk", HEAD + PTS + "CELLS 1 5\n4 0 1 2 3\n")
put("two_points_sections.vtk", HEAD + PTS + PTS + TET)
HEAD51 = "# vtk DataFile Version 5.1\nbroken\nASCII\nDATASET UNSTRUCTURED_GRID\n"
put("offsets_decreasing.vtk", HEAD51 + PTS + "CELLS 3 8\nOFFSETS vtktypeint64\n0 4 3\n"
    "CONNECTIVITY vtktypeint64\n0 1 2 3 0 1 2 3\nCELL_TYPES 2\n10\n10\n")
put("offsets_last.vtk", HEAD51 + PTS + "CELLS 2 5\nOFFSETS vtktypeint64\n0 4\n"
    "CONNECTIVITY vtktypeint64\n0 1 2 3 3\nCELL_TYPES 1\n10\n")
put("offsets_float.vtk", HEAD51 + PTS + "CELLS 2 4\nOFFSETS float\n0 4\n"
    "CONNECTIVITY vtktypeint64\n0 1 2 3\nCELL_TYPES 1\n10\n")
put("no_connectivity.vtk", HEAD51 + PTS + "CELLS 2 4\nOFFSETS vtktypeint64\n0 4\nCELL_TYPES 1\n10\n")

# --- legacy BINARY (big-endian) ---------------------------------------------
BHEAD = b"# vtk DataFile Version 3.0\nbroken\nBINARY\nDATASET UNSTRUCTURED_GRID\n"
pts = struct.pack(">12f", 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1)
cells = struct.pack(">5i", 4, 0, 1, 2, 3)
types = struct.pack(">i", 10)
good = (BHEAD + b"POINTS 4 float\n" + pts + b"\nCELLS 1 5\n" + cells + b"\nCELL_TYPES 1\n" + types +
        b"\nPOINT_DATA 4\nSCALARS s float\nLOOKUP_TABLE default\n" + struct.pack(">4f", 1, 2, 3, 4) + b"\n")
put("truncated_binary_points.vtk", BHEAD + b"POINTS 4 float\n" + pts[:20])
put("truncated_binary_cells.vtk", BHEAD + b"POINTS 4 float\n" + pts + b"\nCELLS 1 5\n" + cells[:9])
put("truncated_binary_scalars.vtk", good[:-7])
put("huge_points_binary.vtk", BHEAD + b"POINTS 1000000000 float\n" + pts)
put("bad_index_binary.vtk", BHEAD + b"POINTS 4 float\n" + pts + b"\nCELLS 1 5\n" + struct.pack(">5i", 4, 0, 1, 2, 70000) +
    b"\nCELL_TYPES 1\n" + types + b"\n")
put("unknown_cell_type_binary.vtk", BHEAD + b"POINTS 4 float\n" + pts + b"\nCELLS 1 5\n" + cells +
    b"\nCELL_TYPES 1\n" + struct.pack(">i", -3) + b"\n")
put("binary_string_overrun.vtk", BHEAD + b"POINTS 4 float\n" + pts + b"\nCELLS 1 5\n" + cells + b"\nCELL_TYPES 1\n" +
    types + b"\nPOINT_DATA 4\nFIELD FieldData 1\nnames 1 4 string\n" + b"\xc3abc" + b"\x3f")

# --- VTU --------------------------------------------------------------------
def vtu(pieces_xml, extra_attrs='', appended=b""):
    head = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian"'
            ' header_type="UInt32"' + extra_attrs + '>\n  <UnstructuredGrid>\n' + pieces_xml + '  </UnstructuredGrid>\n')
    if appended:
        return head.encode() + b'  <AppendedData encoding="raw">\n   _' + appended + b"\n  </AppendedData>\n</VTKFile>\n"
    return (head + "</VTKFile>\n").encode()


def piece(points, conn, offsets, types, extra="", npts=4, ncells=1):
    return (f'    <Piece NumberOfPoints="{npts}" NumberOfCells="{ncells}">\n{extra}'
            f'      <Points>\n        {points}\n      </Points>\n'
            f'      <Cells>\n        {conn}\n        {offsets}\n        {types}\n      </Cells>\n    </Piece>\n')


def ascii_da(name, typ, values, ncomp=1):
    comp = f' NumberOfComponents="{ncomp}"' if ncomp != 1 else ""
    return f'<DataArray type="{typ}" Name="{name}"{comp} format="ascii">{values}</DataArray>'


P_OK = ascii_da("Points", "Float32", "0 0 0 1 0 0 0 1 0 0 0 1", 3)
C_OK = ascii_da("connectivity", "Int64", "0 1 2 3")
O_OK = ascii_da("offsets", "Int64", "4")
T_OK = ascii_da("types", "UInt8", "10")

put("not_xml.vtu", "this is not xml <<<\n")
put("truncated_xml.vtu", vtu(piece(P_OK, C_OK, O_OK, T_OK))[:180])
put("polydata.vtu", b'<?xml version="1.0"?>\n<VTKFile type="PolyData" version="1.0">\n</VTKFile>\n')
put("no_piece.vtu", vtu(""))
put("two_pieces.vtu", vtu(piece(P_OK, C_OK, O_OK, T_OK) * 2))
put("no_cells.vtu", vtu('    <Piece NumberOfPoints="4" NumberOfCells="1">\n      <Points>\n        ' + P_OK +
                        '\n      </Points>\n    </Piece>\n'))
put("no_types.vtu", vtu(piece(P_OK, C_OK, O_OK, "")))
put("points_two_components.vtu", vtu(piece(ascii_da("Points", "Float32", "0 0 1 0 0 1 1 1", 2), C_OK, O_OK, T_OK)))
put("bad_count_attr.vtu", vtu(piece(P_OK, C_OK, O_OK, T_OK).replace('NumberOfPoints="4"', 'NumberOfPoints="four"')))
put("ascii_too_few.vtu", vtu(piece(ascii_da("Points", "Float32", "0 0 0 1 0 0 0 1 0 0 0", 3), C_OK, O_OK, T_OK)))
put("ascii_too_many.vtu", vtu(piece(ascii_da("Points", "Float32", "0 0 0 1 0 0 0 1 0 0 0 1 7", 3), C_OK, O_OK, T_OK)))
put("non_numeric.vtu", vtu(piece(ascii_da("Points", "Float32", "0 0 0 1 0 0 0 1 0 0 0 x1", 3), C_OK, O_OK, T_OK)))
put("bad_index.vtu", vtu(piece(P_OK, ascii_da("connectivity", "Int64", "0 1 2 7"), O_OK, T_OK)))
put("unknown_cell_type.vtu", vtu(piece(P_OK, C_OK, O_OK, ascii_da("types", "UInt8", "200"))))
put("offsets_decreasing.vtu", vtu(piece(P_OK, ascii_da("connectivity", "Int64", "0 1 2 3 0 1 2 3"),
                                        ascii_da("offsets", "Int64", "4 3"), ascii_da("types", "UInt8", "10 10"),
                                        ncells=2)))
put("quadratic_triangle.vtu", vtu(piece(ascii_da("Points", "Float32", "0 0 0 1 0 0 0 1 0 0 0 1 1 0 1 0 1 1", 3),
                           ascii_da("connectivity", "Int64", "0 1 2 3 4 5"), ascii_da("offsets", "Int64", "6"),
                           ascii_da("types", "UInt8", "22"), npts=6)))
put("unknown_data_type.vtu", vtu(piece(P_OK.replace("Float32", "Float16"), C_OK, O_OK, T_OK)))
put("unknown_format.vtu", vtu(piece(P_OK.replace('format="ascii"', 'format="hex"'), C_OK, O_OK, T_OK)))
put("bad_header_type.vtu", vtu(piece(P_OK, C_OK, O_OK, T_OK)).replace(b'header_type="UInt32"', b'header_type="UInt16"'))
put("lz4.vtu", vtu(piece(P_OK, C_OK, O_OK, T_OK), ' compressor="vtkLZ4DataCompressor"'))
put("point_tuples.vtu", vtu(piece(P_OK, C_OK, O_OK, T_OK, extra='      <PointData>\n        <DataArray type="Float32"'
                                  ' Name="s" NumberOfTuples="3" format="ascii">1 2 3 4</DataArray>\n      </PointData>\n')))

pts_le = struct.pack("<12f", 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1)


def b64_da(name, typ, payload_b64, ncomp=1):
    comp = f' NumberOfComponents="{ncomp}"' if ncomp != 1 else ""
    return f'<DataArray type="{typ}" Name="{name}"{comp} format="binary">\n          {payload_b64}\n        </DataArray>'


good_b64 = base64.b64encode(struct.pack("<I", len(pts_le)) + pts_le).decode()
put("bad_base64_char.vtu", vtu(piece(b64_da("Points", "Float32", good_b64[:10] + "*" + good_b64[11:], 3), C_OK, O_OK, T_OK)))
put("bad_base64_padding.vtu", vtu(piece(b64_da("Points", "Float32", "A===" + good_b64[4:], 3), C_OK, O_OK, T_OK)))
put("truncated_base64.vtu", vtu(piece(b64_da("Points", "Float32", good_b64[:30], 3), C_OK, O_OK, T_OK)))
put("base64_wrong_size.vtu", vtu(piece(b64_da("Points", "Float32", base64.b64encode(struct.pack("<I", 40) + pts_le[:40]).decode(), 3),
                                       C_OK, O_OK, T_OK)))

# zlib, base64 header and blocks encoded separately as VTK does.
def zlib_b64(raw, corrupt=False, claim=None):
    z = zlib.compress(raw)
    if corrupt:
        z = z[:4] + bytes([z[4] ^ 0xFF, z[5] ^ 0x55]) + z[6:]
    total = claim if claim is not None else len(raw)
    hdr = struct.pack("<4I", 1, total, total, len(z))
    return base64.b64encode(hdr).decode() + base64.b64encode(z).decode()


ZATTR = ' compressor="vtkZLibDataCompressor"'
put("bad_zlib.vtu", vtu(piece(b64_da("Points", "Float32", zlib_b64(pts_le, corrupt=True), 3), C_OK, O_OK, T_OK), ZATTR))
put("zlib_size_lie.vtu", vtu(piece(b64_da("Points", "Float32", zlib_b64(pts_le[:40], claim=48), 3), C_OK, O_OK, T_OK), ZATTR))
hdr_bomb = struct.pack("<4I", 1, 4 * 3 * 100000000, 0, 10)
put("zlib_huge_claim.vtu", vtu(piece(b64_da("Points", "Float32", base64.b64encode(hdr_bomb + bytes(10)).decode(), 3),
                                     C_OK, O_OK, T_OK).replace('NumberOfPoints="4"', 'NumberOfPoints="100000000"'), ZATTR))
hdr_blocks = struct.pack("<3I", 0xFFFFFFFF, 65536, 0)
put("zlib_huge_block_count.vtu", vtu(piece(b64_da("Points", "Float32", base64.b64encode(hdr_blocks).decode(), 3),
                                           C_OK, O_OK, T_OK), ZATTR))


def app_da(name, typ, offset, ncomp=1):
    comp = f' NumberOfComponents="{ncomp}"' if ncomp != 1 else ""
    return f'<DataArray type="{typ}" Name="{name}"{comp} format="appended" offset="{offset}"/>'


blob = struct.pack("<I", len(pts_le)) + pts_le
put("truncated_appended.vtu", vtu(piece(app_da("Points", "Float32", 0, 3), C_OK, O_OK, T_OK), appended=blob)[:-60])
put("appended_offset_out_of_range.vtu", vtu(piece(app_da("Points", "Float32", 5000, 3), C_OK, O_OK, T_OK), appended=blob))
put("appended_missing.vtu", vtu(piece(app_da("Points", "Float32", 0, 3), C_OK, O_OK, T_OK)))
put("appended_no_marker.vtu", vtu(piece(app_da("Points", "Float32", 0, 3), C_OK, O_OK, T_OK), appended=blob)
    .replace(b"   _", b"   X"))
put("appended_huge_header.vtu", vtu(piece(app_da("Points", "Float32", 0, 3), C_OK, O_OK, T_OK).replace(
    'NumberOfPoints="4"', 'NumberOfPoints="100000000"'), appended=struct.pack("<I", 1200000000) + pts_le))
put("binary_connectivity_size.vtu", vtu(piece(P_OK, b64_da("connectivity", "Int64",
                                                            base64.b64encode(struct.pack("<I", 24) + struct.pack("<3q", 0, 1, 2)).decode()),
                                              O_OK, T_OK)))
# Issue #24: counts and types found where they are declared, and a zlib
# header whose claim no data backs (inflated block by block, nothing allocated
# for the claim).
put("point_data_short.vtk", HEAD + PTS + TET + "POINT_DATA 3\nSCALARS s float\nLOOKUP_TABLE default\n1 2 3 4\n")
put("float_connectivity.vtu", vtu(piece(P_OK, ascii_da("connectivity", "Float32", "0 1 2 3"), O_OK, T_OK)))
junk_blocks = bytes((i * 97 + 13) % 251 for i in range(60))  # not a zlib stream
hdr_junk = struct.pack("<3I", 64, 49152, 0) + struct.pack("<I", len(junk_blocks)) * 64
put("zlib_junk_blocks.vtu", vtu(piece(b64_da("Points", "Float32", base64.b64encode(hdr_junk).decode() +
                                             base64.b64encode(junk_blocks * 64).decode(), 3),
                                      C_OK, O_OK, T_OK).replace('NumberOfPoints="4"', 'NumberOfPoints="262144"'), ZATTR))
print("wrote", len([f for f in os.listdir(HERE) if f.endswith((".vtk", ".vtu"))]), "files")
