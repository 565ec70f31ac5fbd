// Round trips through every file dialect the readers accept: a small grid
// with known cells and arrays is written by an independent writer here (its
// own base64, zlib blocks via compress2, big-endian packing) and must read
// back exactly.

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <zlib.h>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/validate.hpp>

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_io_dialects {

using namespace cellray;

namespace {

/// The grid every dialect writes: one of each cell kind the readers keep,
/// a wedge and a pyramid, plus a quadratic triangle (a 2D cell: skipped when
/// asked), with point and cell arrays.
struct TestGrid {
  std::vector<double> xyz;
  std::vector<int> types;
  std::vector<std::vector<int64_t>> cells;
  std::vector<double> temperature;  // point scalar
  std::vector<double> velocity;     // point 3-vector
  std::vector<int> id;              // point int
  std::vector<double> pressure;     // cell scalar
};

TestGrid make_grid(bool with_wedge) {
  TestGrid g;
  for (int i = 0; i < 24; ++i) {
    // 0.1 is not a float: checks double -> float conversion; others are exact.
    g.xyz.insert(g.xyz.end(), {0.1 * i, 0.125 * (i % 5) - 1.0, -0.25 * (i % 7)});
    g.temperature.push_back(0.375 * i - 2.0);
    g.velocity.insert(g.velocity.end(), {3.0, 4.0 * (i % 3), 0.5 * i});
    g.id.push_back(1000 * i - 7);
  }
  auto add = [&](int type, std::vector<int64_t> ids, double p) {
    g.types.push_back(type);
    g.cells.push_back(std::move(ids));
    g.pressure.push_back(p);
  };
  add(10, {0, 1, 2, 3}, 1.5);
  add(12, {4, 5, 6, 7, 8, 9, 10, 11}, -2.25);
  add(24, {12, 13, 14, 15, 0, 1, 2, 3, 4, 5}, 7.0);
  add(11, {16, 17, 18, 19, 20, 21, 22, 23}, 0.0625);
  add(13, {6, 7, 8, 9, 10, 11}, 4.75);   // wedge: a collapsed hexahedron
  add(14, {20, 21, 22, 23, 1}, -0.5);     // pyramid: likewise
  if (with_wedge) add(22, {0, 1, 2, 3, 4, 5}, 99.0);  // a quadratic triangle: not a volume cell
  add(25, {19, 18, 17, 16, 15, 14, 13, 12, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11}, 3.5);
  add(10, {23, 22, 21, 20}, -8.0);
  return g;
}

/// What the reader must return, worked out from the cell list by hand rules.
void check_grid(UnstructuredGrid const& r, TestGrid const& g, bool velocity_read = true) {
  REQUIRE(r.vertex_count() == 24);
  for (size_t i = 0; i < g.xyz.size(); ++i) CHECK(r.xyz[i] == float(g.xyz[i]));
  std::vector<uint32_t> tets, hexes, tet_ids, hex_ids;  // ids: the cells' places in the file
  std::vector<float> ptet, phex;
  for (size_t c = 0; c < g.cells.size(); ++c) {
    auto const& ids = g.cells[c];
    int const t = g.types[c];
    if (t == 10 || t == 24) tet_ids.push_back(uint32_t(c));
    if (t == 11 || t == 12 || t == 13 || t == 14 || t == 25) hex_ids.push_back(uint32_t(c));
    if (t == 10 || t == 24) {
      for (int k = 0; k < 4; ++k) tets.push_back(uint32_t(ids[k]));
      ptet.push_back(float(g.pressure[c]));
    } else if (t == 12 || t == 25) {
      for (int k = 0; k < 8; ++k) hexes.push_back(uint32_t(ids[k]));
      phex.push_back(float(g.pressure[c]));
    } else if (t == 11) {
      for (int k : {0, 1, 3, 2, 4, 5, 7, 6}) hexes.push_back(uint32_t(ids[k]));
      phex.push_back(float(g.pressure[c]));
    } else if (t == 13) {  // VTK's wedge: triangle 0 1 2 facing away from 3 4 5
      for (int k : {0, 2, 1, 1, 3, 5, 4, 4}) hexes.push_back(uint32_t(ids[k]));
      phex.push_back(float(g.pressure[c]));
    } else if (t == 14) {  // quad 0 1 2 3 facing the apex 4
      for (int k : {0, 1, 2, 3, 4, 4, 4, 4}) hexes.push_back(uint32_t(ids[k]));
      phex.push_back(float(g.pressure[c]));
    }
  }
  CHECK(r.tets == tets);
  CHECK(r.hexes == hexes);
  CHECK(r.tet_file_cells == tet_ids);  // a mixed file (and a skipped cell): the readers' order is not the file's
  CHECK(r.hex_file_cells == hex_ids);
  CHECK(r.report.reduced_to_linear == 3);  // quadratic tet, voxel, quadratic hex
  PointArray const* t = r.point_array("temperature");
  REQUIRE(t);
  for (size_t i = 0; i < 24; ++i) CHECK(t->values[i] == float(g.temperature[i]));
  PointArray const* id = r.point_array("id");
  REQUIRE(id);
  for (size_t i = 0; i < 24; ++i) CHECK(id->values[i] == float(g.id[i]));
  if (velocity_read) {
    PointArray const* v = r.point_array("velocity");
    REQUIRE(v);
    CHECK(v->components == 3);
    for (size_t i = 0; i < 24; ++i) {
      double const x = g.velocity[3 * i], y = g.velocity[3 * i + 1], z = g.velocity[3 * i + 2];
      CHECK(v->values[i] == float(std::sqrt(x * x + y * y + z * z)));
    }
  }
  CellArray const* p = r.cell_array("pressure");
  REQUIRE(p);
  CHECK(p->tet_values == ptet);
  CHECK(p->hex_values == phex);
}

// ---------------------------------------------------------------- writers

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

template <class T> void put_be(std::string& out, T v) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (size_t i = sizeof(T); i-- > 0;) out += char(b[i]);
}

struct LegacyStyle {
  std::string version = "2.0";
  bool binary = false;
  bool new_layout = false;   // 5.1 OFFSETS / CONNECTIVITY
  bool fields = false;       // arrays in FIELD blocks (OpenFOAM style) instead of SCALARS
  bool cell_data_first = false;
  bool double_points = true;
};

std::string write_legacy(TestGrid const& g, LegacyStyle const& s) {
  std::string o = "# vtk DataFile Version " + s.version + "\nround trip\n" + (s.binary ? "BINARY\n" : "ASCII\n") +
                  "DATASET UNSTRUCTURED_GRID\n";
  auto floats = [&](std::vector<double> const& v, bool dbl) {
    if (s.binary) {
      for (double x : v) dbl ? put_be(o, x) : put_be(o, float(x));
      o += "\n";
    } else {
      for (size_t i = 0; i < v.size(); ++i) o += num(dbl ? v[i] : double(float(v[i]))) + (i % 9 == 8 ? "\n" : " ");
      o += "\n";
    }
  };
  auto ints = [&](std::vector<int64_t> const& v, bool i64) {
    if (s.binary) {
      for (int64_t x : v) i64 ? put_be(o, x) : put_be(o, int32_t(x));
      o += "\n";
    } else {
      for (int64_t x : v) o += std::to_string(x) + " ";
      o += "\n";
    }
  };
  // Dataset field data (ignored by the reader), as OpenFOAM writes it.
  o += "FIELD FieldData 1\nTimeValue 1 1 float\n";
  floats({0.5}, false);
  o += std::string("POINTS 24 ") + (s.double_points ? "double" : "float") + "\n";
  floats(g.xyz, s.double_points);
  size_t const n = g.cells.size();
  if (s.new_layout) {
    std::vector<int64_t> off{0}, conn;
    for (auto const& c : g.cells) {
      conn.insert(conn.end(), c.begin(), c.end());
      off.push_back(int64_t(conn.size()));
    }
    o += "CELLS " + std::to_string(off.size()) + " " + std::to_string(conn.size()) + "\nOFFSETS vtktypeint64\n";
    ints(off, true);
    o += "CONNECTIVITY vtktypeint64\n";
    ints(conn, true);
  } else {
    std::vector<int64_t> list;
    for (auto const& c : g.cells) {
      list.push_back(int64_t(c.size()));
      list.insert(list.end(), c.begin(), c.end());
    }
    o += "CELLS " + std::to_string(n) + " " + std::to_string(list.size()) + "\n";
    ints(list, false);
  }
  o += "CELL_TYPES " + std::to_string(n) + "\n";
  ints(std::vector<int64_t>(g.types.begin(), g.types.end()), false);

  auto cell_data = [&] {
    o += "CELL_DATA " + std::to_string(n) + "\n";
    if (s.fields) {
      o += "FIELD FieldData 2\npressure 1 " + std::to_string(n) + " double\n";
      floats(g.pressure, true);
      o += "NULL_ARRAY\n";
    } else {
      o += "SCALARS pressure double 1\nLOOKUP_TABLE default\n";
      floats(g.pressure, true);
    }
  };
  auto point_data = [&] {
    o += "POINT_DATA 24\n";
    std::vector<int64_t> ids(g.id.begin(), g.id.end());
    if (s.fields) {
      o += "FIELD FieldData 4\ntemperature 1 24 float\n";
      floats(g.temperature, false);
      // VTK 8+ writes METADATA after arrays; it ends at an empty line.
      o += "METADATA\nINFORMATION 1\nNAME L2_NORM_RANGE LOCATION vtkDataArray\nDATA 2 0 1\n\n";
      o += "velocity 3 24 float\n";
      floats(g.velocity, false);
      o += "labels 1 24 string\n";
      for (int i = 0; i < 24; ++i) {
        std::string const str = "v" + std::to_string(i);
        if (s.binary) o += char(0xC0 | str.size()), o += str;  // VTK's 1-byte length header
        else o += str + "\n";
      }
      if (s.binary) o += "\n";
      o += "id 1 24 int\n";
      ints(ids, false);
    } else {
      o += "SCALARS temperature float\nLOOKUP_TABLE default\n";
      floats(g.temperature, false);
      o += "VECTORS velocity float\n";
      floats(g.velocity, false);
      o += "NORMALS normals float\n";
      floats(std::vector<double>(72, 0.0), false);
      o += "SCALARS id int 1\nLOOKUP_TABLE default\n";
      ints(ids, false);
    }
  };
  if (s.cell_data_first) cell_data(), point_data();
  else point_data(), cell_data();
  return o;
}

std::string base64(std::string const& bytes) {
  static char const* const a = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string o;
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    uint32_t const v = uint32_t(uint8_t(bytes[i])) << 16 | uint32_t(uint8_t(bytes[i + 1])) << 8 | uint8_t(bytes[i + 2]);
    o += a[v >> 18], o += a[(v >> 12) & 63], o += a[(v >> 6) & 63], o += a[v & 63];
  }
  if (bytes.size() - i == 1) {
    uint32_t const v = uint32_t(uint8_t(bytes[i])) << 16;
    o += a[v >> 18], o += a[(v >> 12) & 63], o += "==";
  } else if (bytes.size() - i == 2) {
    uint32_t const v = uint32_t(uint8_t(bytes[i])) << 16 | uint32_t(uint8_t(bytes[i + 1])) << 8;
    o += a[v >> 18], o += a[(v >> 12) & 63], o += a[(v >> 6) & 63], o += '=';
  }
  return o;
}

struct VtuStyle {
  std::string format = "ascii";  // ascii | binary | appended
  bool appended_base64 = false;
  bool uint64_header = false;
  bool zlib = false;
  bool big_endian = false;
  bool header_apart = true;  // base64: header and data encoded separately (VTK does so with zlib)
};

std::string write_vtu(TestGrid const& g, VtuStyle const& s) {
  std::string appended;
  auto put = [&](std::string& o, auto v) {
    unsigned char b[sizeof(v)];
    std::memcpy(b, &v, sizeof(v));
    if (s.big_endian) for (size_t i = sizeof(v); i-- > 0;) o += char(b[i]);
    else for (size_t i = 0; i < sizeof(v); ++i) o += char(b[i]);
  };
  auto header_int = [&](std::string& o, uint64_t v) { s.uint64_header ? put(o, uint64_t(v)) : put(o, uint32_t(v)); };
  // The array's bytes -> (header, data) as VTK lays them out.
  auto pack = [&](std::string const& raw, std::string& head, std::string& data) {
    if (!s.zlib) {
      header_int(head, raw.size());
      data = raw;
      return;
    }
    size_t const block = 40;  // small, so arrays span several blocks with a partial last one
    size_t const nb = (raw.size() + block - 1) / block;
    std::vector<std::string> z;
    for (size_t b = 0; b < nb; ++b) {
      size_t const len = std::min(block, raw.size() - b * block);
      uLongf zl = compressBound(uLong(len));
      std::string buf(zl, '\0');
      compress2(reinterpret_cast<Bytef*>(buf.data()), &zl, reinterpret_cast<Bytef const*>(raw.data()) + b * block, uLong(len), 6);
      buf.resize(zl);
      z.push_back(buf);
    }
    header_int(head, nb);
    header_int(head, block);
    header_int(head, raw.size() % block);
    for (auto const& b : z) header_int(head, b.size());
    for (auto const& b : z) data += b;
  };
  auto array = [&](char const* type, char const* name, int ncomp, std::string const& raw, std::string const& text) {
    std::string o = std::string("<DataArray type=\"") + type + "\" Name=\"" + name + "\" NumberOfComponents=\"" +
                    std::to_string(ncomp) + "\" format=\"" + s.format + "\"";
    if (s.format == "ascii") return o + ">\n" + text + "\n</DataArray>\n";
    std::string head, data;
    pack(raw, head, data);
    std::string const enc = s.header_apart ? base64(head) + base64(data) : base64(head + data);
    if (s.format == "binary") return o + ">\n  " + enc + "\n</DataArray>\n";
    o += " offset=\"" + std::to_string(appended.size()) + "\"/>\n";
    appended += s.appended_base64 ? enc : head + data;
    return o;
  };
  auto f32 = [&](std::vector<double> const& v) {
    std::string raw, text;
    for (double x : v) put(raw, float(x)), text += num(double(float(x))) + " ";
    return std::pair<std::string, std::string>(raw, text);
  };
  auto f64 = [&](std::vector<double> const& v) {
    std::string raw, text;
    for (double x : v) put(raw, x), text += num(x) + " ";
    return std::pair<std::string, std::string>(raw, text);
  };
  auto i64 = [&](std::vector<int64_t> const& v) {
    std::string raw, text;
    for (int64_t x : v) put(raw, x), text += std::to_string(x) + " ";
    return std::pair<std::string, std::string>(raw, text);
  };
  std::vector<int64_t> conn, off;
  for (auto const& c : g.cells) {
    conn.insert(conn.end(), c.begin(), c.end());
    off.push_back(int64_t(conn.size()));
  }
  std::string types_raw, types_text;
  for (int t : g.types) types_raw += char(t), types_text += std::to_string(t) + " ";
  std::string body;
  body += "<Piece NumberOfPoints=\"24\" NumberOfCells=\"" + std::to_string(g.cells.size()) + "\">\n<PointData Scalars=\"temperature\">\n";
  auto [tr, tt] = f32(g.temperature);
  body += array("Float32", "temperature", 1, tr, tt);
  auto [vr, vt] = f64(g.velocity);
  body += array("Float64", "velocity", 3, vr, vt);
  std::string idr, idt;
  for (int x : g.id) put(idr, int32_t(x)), idt += std::to_string(x) + " ";
  body += array("Int32", "id", 1, idr, idt);
  body += "</PointData>\n<CellData>\n";
  auto [pr, pt] = f64(g.pressure);
  body += array("Float64", "pressure", 1, pr, pt);
  body += "<Array type=\"String\" Name=\"tags\" format=\"ascii\">0</Array>\n</CellData>\n<Points>\n";
  auto [xr, xt] = f64(g.xyz);
  body += array("Float64", "Points", 3, xr, xt);
  body += "</Points>\n<Cells>\n";
  auto [cr, ct] = i64(conn);
  body += array("Int64", "connectivity", 1, cr, ct);
  auto [or_, ot] = i64(off);
  body += array("Int64", "offsets", 1, or_, ot);
  body += array("UInt8", "types", 1, types_raw, types_text);
  body += "</Cells>\n</Piece>\n";
  std::string o = std::string("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"") +
                  (s.big_endian ? "BigEndian" : "LittleEndian") + "\" header_type=\"" +
                  (s.uint64_header ? "UInt64" : "UInt32") + "\"" + (s.zlib ? " compressor=\"vtkZLibDataCompressor\"" : "") +
                  ">\n<UnstructuredGrid>\n<FieldData><DataArray type=\"Float32\" Name=\"TimeValue\" NumberOfTuples=\"1\" "
                  "format=\"ascii\">0.5</DataArray></FieldData>\n" +
                  body + "</UnstructuredGrid>\n";
  if (s.format == "appended")
    o += std::string("<AppendedData encoding=\"") + (s.appended_base64 ? "base64" : "raw") + "\">\n   _" + appended +
         "\n</AppendedData>\n";
  return o + "</VTKFile>\n";
}

}  // namespace

TEST_CASE("legacy VTK round trips in every dialect", "[io][legacy]") {
  for (bool wedge : {false, true}) {
    TestGrid const g = make_grid(wedge);
    for (char const* version : {"1.0", "2.0", "3.0", "4.2", "5.1"})
      for (bool binary : {false, true})
        for (bool fields : {false, true})
          for (bool cell_first : {false, true}) {
            LegacyStyle s;
            s.version = version;
            s.binary = binary;
            s.new_layout = std::string(version) == "5.1";
            s.fields = fields;
            s.cell_data_first = cell_first;
            s.double_points = binary != fields;
            CAPTURE(version, binary, fields, cell_first, wedge);
            std::string const bytes = write_legacy(g, s);
            ReadOptions opts;
            opts.skip_unsupported_cells = wedge;
            UnstructuredGrid const r = read_vtk_legacy_from_memory(bytes, "mem.vtk", opts);
            check_grid(r, g);
            CHECK(r.report.skipped_count() == (wedge ? 1u : 0u));
            CHECK(r.report.cells_read.at(10) == 2);
            CHECK(r.report.format == std::string("legacy VTK ") + version + (binary ? " BINARY" : " ASCII"));
            bool ignored_time = false;
            for (auto const& a : r.report.arrays_ignored) ignored_time |= a.find("TimeValue") != std::string::npos;
            CHECK(ignored_time);
            if (wedge) CHECK_THROWS_WITH(read_vtk_legacy_from_memory(bytes, "mem.vtk"), Catch::Contains("1 quadratic_triangle"));
          }
  }
}

TEST_CASE("VTU round trips in every encoding", "[io][vtu]") {
  for (bool wedge : {false, true}) {
    TestGrid const g = make_grid(wedge);
    struct Case {
      char const* format;
      bool b64, u64, zlib, big, apart;
    };
    std::vector<Case> cases = {{"ascii", false, false, false, false, true}};
    for (bool u64 : {false, true})
      for (bool zlib : {false, true})
        for (bool big : {false, true})
          for (bool apart : {false, true}) {
            cases.push_back({"binary", true, u64, zlib, big, apart});
            cases.push_back({"appended", false, u64, zlib, big, apart});
            cases.push_back({"appended", true, u64, zlib, big, apart});
          }
    for (auto const& c : cases) {
      VtuStyle s;
      s.format = c.format;
      s.appended_base64 = c.b64;
      s.uint64_header = c.u64;
      s.zlib = c.zlib;
      s.big_endian = c.big;
      s.header_apart = c.apart;
      CAPTURE(c.format, c.b64, c.u64, c.zlib, c.big, c.apart, wedge);
      std::string const bytes = write_vtu(g, s);
      ReadOptions opts;
      opts.skip_unsupported_cells = wedge;
      UnstructuredGrid const r = read_vtu_from_memory(bytes, "mem.vtu", opts);
      check_grid(r, g);
      CHECK(r.report.skipped_count() == (wedge ? 1u : 0u));
      if (wedge) {
        CHECK(r.report.cells_skipped.at(22) == 1);
        CHECK_THROWS_WITH(read_vtu_from_memory(bytes, "mem.vtu"), Catch::Contains("1 quadratic_triangle"));
      }
    }
  }
}

TEST_CASE("hand-written legacy quirks: CRLF, %20 names, TENSORS, COLOR_SCALARS, lookup tables, METADATA", "[io][legacy]") {
  std::string tensor;  // 2 0 0 / 0 2 0 / 0 0 i: Frobenius norm sqrt(8 + i^2)
  for (int i = 0; i < 5; ++i) tensor += "2 0 0 0 2 0 0 0 " + std::to_string(i) + "\r\n";
  std::string const f =
      "# vtk DataFile Version 4.2\r\nquirks\r\nASCII\r\n\r\nDATASET UNSTRUCTURED_GRID\r\n"
      "POINTS 5 float\r\n0 0 0  1 0 0  0 1 0  0 0 1  +1e0 1 1\r\n"
      "METADATA\r\nINFORMATION 0\r\n\r\n"
      "CELLS 2 10\r\n4 0 1 2 3\r\n4 1 2 3 4\r\nCELL_TYPES 2\r\n10\r\n10\r\n"
      "POINT_DATA 5\r\n"
      "SCALARS my%20field double 2\r\nLOOKUP_TABLE default\r\n3 4 0 0 -6 8 1 0 nan 0\r\n"
      "TENSORS stress float\r\n" + tensor +
      "COLOR_SCALARS rgb 3\r\n0 0.5 1 0 0.5 1 0 0.5 1 0 0.5 1 0 0.5 1\r\n"
      "LOOKUP_TABLE lut 2\r\n0 0 0 1  1 1 1 1\r\n"
      "TEXTURE_COORDINATES uv 2 float\r\n0 0 1 0 0 1 1 1 0.5 0.5\r\n"
      "CELL_DATA 2\r\nSCALARS c%2Fid vtkIdType\r\nLOOKUP_TABLE default\r\n7 9\r\n";
  UnstructuredGrid const r = read_vtk_legacy_from_memory(f, "quirks.vtk");
  REQUIRE(r.tet_count() == 2);
  PointArray const* m = r.point_array("my field");
  REQUIRE(m);
  CHECK(m->components == 2);
  CHECK(m->values[0] == 5.f);
  CHECK(m->values[1] == 0.f);
  CHECK(m->values[2] == 10.f);
  CHECK(m->values[3] == 1.f);
  CHECK(std::isnan(m->values[4]));  // NaN is data, not an error
  PointArray const* t = r.point_array("stress");
  REQUIRE(t);
  CHECK(t->values[3] == float(std::sqrt(8.0 + 9.0)));
  CellArray const* c = r.cell_array("c/id");
  REQUIRE(c);
  CHECK(c->tet_values == std::vector<float>{7.f, 9.f});
  CHECK(r.report.arrays_ignored.size() == 3);  // colours, lookup table, texture coordinates
}

TEST_CASE("read_mesh dispatches on the extension and names an unknown one", "[io]") {
  TestGrid const g = make_grid(false);
  CHECK(read_mesh_from_memory(write_legacy(g, {}), "x.VTK").tet_count() == 3);
  CHECK(read_mesh_from_memory(write_vtu(g, {}), "dir.v/x.vtu").hex_count() == 5);  // with a wedge and a pyramid
  CHECK_THROWS_WITH(read_mesh_from_memory("", "mesh.inp"),
                    Catch::Contains("mesh.inp") && Catch::Contains("'.inp'") && Catch::Contains(".pvtu and .msh"));
  CHECK_THROWS_WITH(read_mesh_from_memory("", "mesh.MSH"), Catch::Contains("mesh.MSH: empty file"));  // gmsh's reader
  CHECK_THROWS_WITH(read_mesh("/nonexistent/file.vtk"), Catch::Contains("/nonexistent/file.vtk") && Catch::Contains("cannot open"));
  CHECK_THROWS_AS(read_mesh("no_extension"), IoError);
}

TEST_CASE("cell_to_point counts a cell once at a vertex it lists twice (wedges, pyramids, folded tets)", "[io]") {
  // A pyramid (q = 10) and a tet (q = 20) sharing the apex 4: VTK averages
  // each cell once per point, 15 at the apex, although the pyramid is
  // stored as a hexahedron listing its apex four times.
  std::string const f =
      "# vtk DataFile Version 2.0\nc2p\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 7 float\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n2 0 1\n2 1 1\n"
      "CELLS 2 11\n5 0 1 2 3 4\n4 1 2 4 5\nCELL_TYPES 2\n14\n10\nCELL_DATA 2\nSCALARS q float\nLOOKUP_TABLE default\n10 20\n";
  UnstructuredGrid g = read_vtk_legacy_from_memory(f, "c2p.vtk");
  REQUIRE(g.hex_count() == 1);
  g.cell_to_point("q", "avg");
  CHECK(g.point_array("avg")->values[4] == 15.f);
  CHECK(g.point_array("avg")->values[0] == 10.f);
  CHECK(g.point_array("avg")->values[1] == 15.f);
  CHECK(g.point_array("avg")->values[5] == 20.f);
  // Folded into the hexahedra, the tet still counts once at each vertex.
  UnstructuredGrid h = read_vtk_legacy_from_memory(f, "c2p.vtk");
  CHECK(h.fold_tets_into_hexes() == 1);
  h.cell_to_point("q", "avg");
  for (size_t v = 0; v < 6; ++v) CHECK(h.point_array("avg")->values[v] == g.point_array("avg")->values[v]);
  CHECK(std::isnan(h.point_array("avg")->values[6]));  // no cell uses it
}

TEST_CASE("fold_tets_into_hexes stores each tet as a collapsed hexahedron, cell values along", "[io]") {
  std::string const f =
      "# vtk DataFile Version 2.0\nfold\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 9 float\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n0.5 0.5 2\n"
      "CELLS 3 19\n4 4 5 6 8\n8 0 1 2 3 4 5 6 7\n4 4 6 7 8\nCELL_TYPES 3\n10\n12\n10\n"
      "CELL_DATA 3\nSCALARS q float\nLOOKUP_TABLE default\n1 2 3\n";
  UnstructuredGrid g = read_vtk_legacy_from_memory(f, "fold.vtk");
  CHECK(g.fold_tets_into_hexes() == 2);
  CHECK(g.tet_count() == 0);
  REQUIRE(g.hex_count() == 3);
  CHECK(std::vector<uint32_t>(g.hexes.begin() + 8, g.hexes.end()) ==
        std::vector<uint32_t>{4, 5, 6, 6, 8, 8, 8, 8, 4, 6, 7, 7, 8, 8, 8, 8});
  CHECK(g.cell_array("q")->hex_values == std::vector<float>{2, 1, 3});
  CHECK(g.cell_array("q")->tet_values.empty());
  CHECK(g.hex_file_cells == std::vector<uint32_t>{1, 0, 2});  // the file's cell ids follow the cells
  CHECK(g.tet_file_cells.empty());
  ValidationReport const r = validate(g.hex_mesh());  // positive, not flat
  CHECK(!r.inverted);
  CHECK(!r.zero_volume);
  CHECK(g.fold_tets_into_hexes() == 0);
  CHECK(g.hex_file_cells == std::vector<uint32_t>{1, 0, 2});
}

TEST_CASE("validation names the file's cell ids where the reader reordered the cells", "[io]") {
  // Hexahedron, tet, a wedge turned inside out (its first triangle's normal
  // points at the second), tet, a hexahedron turned inside out. The readers keep the tets
  // and hexahedra apart: the hexahedral part's cells 1 and 2 are the
  // file's cells 2 and 4, and the folded tets come after them.
  std::string const f =
      "# vtk DataFile Version 2.0\nids\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 14 float\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
      "0 0 2\n1 0 2\n0 1 2\n0 0 3\n1 0 3\n0 1 3\n"
      "CELLS 5 35\n8 0 1 2 3 4 5 6 7\n4 4 5 6 8\n6 8 9 10 11 12 13\n4 4 6 7 8\n8 4 5 6 7 0 1 2 3\n"
      "CELL_TYPES 5\n12\n10\n13\n10\n12\n";
  UnstructuredGrid g = read_vtk_legacy_from_memory(f, "ids.vtk");
  CHECK(g.tet_file_cells == std::vector<uint32_t>{1, 3});
  CHECK(g.hex_file_cells == std::vector<uint32_t>{0, 2, 4});
  CHECK(g.hex_file_cell(1) == 2);
  CHECK(g.tet_file_cell(1) == 3);
  ValidationReport const by_index = validate(g.hex_mesh());
  REQUIRE(by_index.inverted.count == 2);
  CHECK(by_index.inverted.first == 1);  // the view's index
  ValidationReport const by_file = validate(g.hex_mesh(), view(g.hex_file_cells));
  CHECK(by_file.inverted.count == 2);
  CHECK(by_file.inverted.first == 2);  // the file's id, as ParaView shows it
  CHECK_THAT(by_file.message(), Catch::Contains("first cell 2)"));
  CHECK_THROWS_AS(validate(g.hex_mesh(), view(g.tet_file_cells)), InvalidArgument);  // one id per cell
  std::vector<uint64_t> const global = {100, 7, 5};  // a rank's global ids, say: the smallest is named
  CHECK(validate(g.hex_mesh(), view(global)).inverted.first == 5);
  // Folded: the smallest file id among the findings, wherever it sits.
  CHECK(g.fold_tets_into_hexes() == 2);
  CHECK(g.hex_file_cells == std::vector<uint32_t>{0, 2, 4, 1, 3});
  CHECK(validate(g.hex_mesh(), view(g.hex_file_cells)).inverted.first == 2);
  // A file of one cell type keeps none: each index is its id.
  std::string const hexes_only =
      "# vtk DataFile Version 2.0\nh\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 float\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\nCELLS 1 9\n8 0 1 2 3 4 5 6 7\nCELL_TYPES 1\n12\n";
  UnstructuredGrid const h = read_vtk_legacy_from_memory(hexes_only, "h.vtk");
  CHECK(h.hex_file_cells.empty());
  CHECK(h.hex_file_cell(0) == 0);
}

TEST_CASE("cell_to_point averages the cells around each vertex", "[io]") {
  // Two tets sharing the face 1-2-3 and a hex over vertices 5..12; vertex 13 is unused.
  std::string f = "# vtk DataFile Version 2.0\nc2p\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 14 float\n";
  for (int i = 0; i < 14; ++i) f += std::to_string(i) + " 0 0\n";
  f += "CELLS 3 19\n4 0 1 2 3\n4 1 2 3 4\n8 5 6 7 8 9 10 11 12\nCELL_TYPES 3\n10\n10\n12\n"
       "CELL_DATA 3\nSCALARS q float\nLOOKUP_TABLE default\n1 4 10\n"
       "POINT_DATA 14\nSCALARS q float\nLOOKUP_TABLE default\n0 0 0 0 0 0 0 0 0 0 0 0 0 0\n";
  UnstructuredGrid r = read_vtk_legacy_from_memory(f, "c2p.vtk");
  CHECK_THROWS_AS(r.cell_to_point("q"), InvalidArgument);  // a point array 'q' exists
  CHECK_THROWS_WITH(r.cell_to_point("nope"), Catch::Contains("q"));
  r.cell_to_point("q", "q_avg");
  PointArray const* p = r.point_array("q_avg");
  REQUIRE(p);
  std::vector<float> const want = {1.f, 2.5f, 2.5f, 2.5f, 4.f, 10.f, 10.f, 10.f, 10.f, 10.f, 10.f, 10.f, 10.f};
  for (size_t v = 0; v < want.size(); ++v) CHECK(p->values[v] == want[v]);
  CHECK(std::isnan(p->values[13]));
  // Views carry every point array; the first is active.
  TetMesh const m = r.tet_mesh();
  CHECK(m.arrays().size() == 2);
  CHECK(m.active_array() == "q");
  CHECK(m.with_array("q_avg").value(1) == 2.5f);
  CHECK(r.hex_mesh().cell_count() == 1);
}

TEST_CASE("legacy VTK with more cells than one parallel task: ids in order, first bad id named", "[io][legacy]") {
  // 50,000 cells cross several 16,384-cell tasks of the parallel copy; a mix of
  // kinds (wedges read as hexahedra, quadratic triangles skipped) makes each
  // task's first output slot differ.
  TestGrid g;
  int const np = 24;  // write_legacy writes 24 points
  for (int i = 0; i < np; ++i) {
    g.xyz.insert(g.xyz.end(), {0.5 * i, -0.25 * i, 1.0});
    g.temperature.push_back(i);
    g.velocity.insert(g.velocity.end(), {1.0, 0.0, 0.0});
    g.id.push_back(i);
  }
  int const nc = 50000;
  for (int c = 0; c < nc; ++c) {
    auto v = [&](int k) { return int64_t((c * 7 + k * 13) % np); };
    int const kind = (c / 3 + c % 5) % 4;
    if (kind == 0) g.types.push_back(10), g.cells.push_back({v(0), v(1), v(2), v(3)});
    else if (kind == 1) g.types.push_back(12), g.cells.push_back({v(0), v(1), v(2), v(3), v(4), v(5), v(6), v(7)});
    else if (kind == 2) g.types.push_back(11), g.cells.push_back({v(0), v(1), v(2), v(3), v(4), v(5), v(6), v(7)});
    else if (c % 2 == 0) g.types.push_back(13), g.cells.push_back({v(0), v(1), v(2), v(3), v(4), v(5)});
    else g.types.push_back(22), g.cells.push_back({v(0), v(1), v(2), v(3), v(4), v(5)});  // skipped
    g.pressure.push_back(0.5 * c);
  }
  std::vector<uint32_t> tets, hexes;
  std::vector<float> ptet, phex;
  for (size_t c = 0; c < g.cells.size(); ++c) {
    auto const& ids = g.cells[c];
    if (g.types[c] == 10) {
      for (int k = 0; k < 4; ++k) tets.push_back(uint32_t(ids[k]));
      ptet.push_back(float(g.pressure[c]));
    } else if (g.types[c] != 22) {
      static constexpr int voxel_order[8] = {0, 1, 3, 2, 4, 5, 7, 6};
      static constexpr int wedge_order[8] = {0, 2, 1, 1, 3, 5, 4, 4};
      int const* order = g.types[c] == 11 ? voxel_order : g.types[c] == 13 ? wedge_order : nullptr;
      for (int k = 0; k < 8; ++k) hexes.push_back(uint32_t(ids[size_t(order ? order[k] : k)]));
      phex.push_back(float(g.pressure[c]));
    }
  }
  ReadOptions opts;
  opts.skip_unsupported_cells = true;
  for (bool binary : {true, false})
    for (bool new_layout : {false, true}) {
      CAPTURE(binary, new_layout);
      LegacyStyle s;
      s.version = new_layout ? "5.1" : "4.2";
      s.binary = binary;
      s.new_layout = new_layout;
      TestGrid bad = g;
      UnstructuredGrid const r = read_vtk_legacy_from_memory(write_legacy(g, s), "big.vtk", opts);
      CHECK(r.tets == tets);
      CHECK(r.hexes == hexes);
      REQUIRE(r.cell_array("pressure"));
      CHECK(r.cell_array("pressure")->tet_values == ptet);
      CHECK(r.cell_array("pressure")->hex_values == phex);
      REQUIRE(r.vertex_count() == uint64_t(np));
      for (int i = 0; i < 3 * np; ++i) CHECK(r.xyz[size_t(i)] == float(g.xyz[size_t(i)]));
      // Bad ids in two tasks (and one negative): the earliest cell is named.
      bad.cells[45001][1] = np;
      bad.cells[40000][2] = -1;
      bad.cells[20002][3] = np + 5;
      CHECK_THROWS_WITH(read_vtk_legacy_from_memory(write_legacy(bad, s), "big.vtk", opts),
                        Catch::Contains("cell 20002 uses vertex id " + std::to_string(np + 5) + ", outside [0, 24)"));
      bad.cells[20002][3] = 0;
      CHECK_THROWS_WITH(read_vtk_legacy_from_memory(write_legacy(bad, s), "big.vtk", opts),
                        Catch::Contains("cell 40000 uses vertex id -1"));
    }
}

}  // namespace test_io_dialects
