// The VTU decode paths of issue #23 against the plain ASCII reading of the
// same data: long base64 runs decoded in parallel chunks (with line breaks
// and stray whitespace that send the decoder back to its careful path),
// inline vs appended, raw vs base64, UInt32 vs UInt64 headers, zlib with
// several blocks and a short last one; DataArray text kept out of pugixml
// (error lines after it, comments and quoted '>' around it); polyhedra split
// in parallel chunks (the first error in file order is the one reported).
// The files are written here by a small generator (VTK's layout: a header
// of byte counts, for zlib nblocks, block size, last block size and the
// compressed sizes; base64 header and blocks as separate padded streams).

#include <catch2/catch.hpp>

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <type_traits>
#include <string>
#include <vector>

#include <cellray/io/vtu.hpp>

namespace test_io_vtu_encodings {

using namespace cellray;

namespace {

std::string base64(unsigned char const* p, size_t n) {
  static char const sym[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string s;
  for (size_t i = 0; i < n; i += 3) {
    uint32_t v = uint32_t(p[i]) << 16;
    if (i + 1 < n) v |= uint32_t(p[i + 1]) << 8;
    if (i + 2 < n) v |= p[i + 2];
    s += sym[v >> 18];
    s += sym[(v >> 12) & 63];
    s += i + 1 < n ? sym[(v >> 6) & 63] : '=';
    s += i + 2 < n ? sym[v & 63] : '=';
  }
  return s;
}

struct Encoding {
  std::string format = "ascii";  ///< ascii, binary (inline base64) or appended
  bool appended_base64 = false;
  int header = 8;                ///< header_type bytes: 4 (UInt32) or 8 (UInt64)
  size_t zblock = 0;             ///< zlib block size; 0 = uncompressed
  size_t wrap = 0;               ///< inline base64: a line break every `wrap` characters
};

/// One DataArray's values, as bytes (little-endian host) and as text.
struct Array {
  std::string name, type;
  int ncomp = 1;
  std::vector<unsigned char> bytes;
  std::string ascii;
};
template <class T> Array array(std::string name, std::string type, std::vector<T> const& v, int ncomp = 1) {
  Array a{std::move(name), std::move(type), ncomp, std::vector<unsigned char>(v.size() * sizeof(T)), {}};
  if (!v.empty()) std::memcpy(a.bytes.data(), v.data(), a.bytes.size());
  char buf[32];
  for (T x : v) {
    if constexpr (std::is_floating_point_v<T>) std::snprintf(buf, sizeof buf, "%.9g ", double(x));  // reads back bitwise
    else std::snprintf(buf, sizeof buf, "%lld ", static_cast<long long>(x));
    a.ascii += buf;
  }
  return a;
}

/// A lattice of n x n x m unit cubes: the first `npoly` written as polyhedra
/// (VTK 42, six quads), the rest as hexahedra; point array T, cell array id.
struct Lattice {
  int n = 36, m = 36;
  uint64_t npoly = 700;

  std::vector<Array> arrays() const {
    auto pid = [&](int i, int j, int k) { return int64_t((k * (n + 1) + j) * (n + 1) + i); };
    std::vector<float> xyz, t;
    for (int k = 0; k <= m; ++k)
      for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
          xyz.insert(xyz.end(), {float(i) * 0.5f, float(j) * 0.25f + 0.1f, float(k) / 3.f});
          t.push_back(float(i) + 2.f * float(j) - float(k) / 7.f);
        }
    std::vector<int64_t> conn, offsets, faces, faceoffsets;
    std::vector<uint8_t> types;
    std::vector<float> id;
    uint64_t c = 0;
    for (int k = 0; k < m; ++k)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i, ++c) {
          int64_t const v[8] = {pid(i, j, k),     pid(i + 1, j, k),     pid(i + 1, j + 1, k),     pid(i, j + 1, k),
                                pid(i, j, k + 1), pid(i + 1, j, k + 1), pid(i + 1, j + 1, k + 1), pid(i, j + 1, k + 1)};
          conn.insert(conn.end(), v, v + 8);
          offsets.push_back(int64_t(conn.size()));
          id.push_back(float(c));
          if (c < npoly) {
            types.push_back(42);
            int const f[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
            faces.push_back(6);
            for (auto const& q : f) faces.insert(faces.end(), {4, v[q[0]], v[q[1]], v[q[2]], v[q[3]]});
            faceoffsets.push_back(int64_t(faces.size()));
          } else {
            types.push_back(12);
            faceoffsets.push_back(-1);
          }
        }
    return {array("T", "Float32", t),          array("id", "Float32", id),      array("Points", "Float32", xyz, 3),
            array("connectivity", "Int64", conn), array("offsets", "Int64", offsets), array("types", "UInt8", types),
            array("faces", "Int64", faces),     array("faceoffsets", "Int64", faceoffsets)};
  }
  uint64_t points() const { return uint64_t(n + 1) * uint64_t(n + 1) * uint64_t(m + 1); }
  uint64_t cells() const { return uint64_t(n) * uint64_t(n) * uint64_t(m); }
};

/// VTK's binary layout of one array: header (+ zlib blocks), as one byte
/// string, or for inline base64 the text of its separately encoded parts.
struct Payload {
  std::vector<unsigned char> header, data;
};
Payload payload(std::vector<unsigned char> const& b, Encoding const& e) {
  Payload p;
  auto put = [&](uint64_t v) {
    for (int i = 0; i < e.header; ++i) p.header.push_back((unsigned char)(v >> (8 * i)));
  };
  if (!e.zblock) {
    put(b.size());
    p.data = b;
    return p;
  }
  uint64_t const nblocks = (b.size() + e.zblock - 1) / e.zblock;
  put(nblocks);
  put(e.zblock);
  put(b.size() % e.zblock);  // 0 when the last block is full
  for (uint64_t i = 0; i < nblocks; ++i) {
    size_t const at = size_t(i) * e.zblock, len = std::min(e.zblock, b.size() - at);
    uLongf zlen = compressBound(uLong(len));
    std::vector<unsigned char> z(zlen);
    REQUIRE(compress2(z.data(), &zlen, b.data() + at, uLong(len), 1) == Z_OK);
    put(zlen);
    p.data.insert(p.data.end(), z.begin(), z.begin() + long(zlen));
  }
  return p;
}

std::string wrapped(std::string const& s, size_t every) {
  if (!every) return s;
  std::string w;
  for (size_t i = 0; i < s.size(); i += every) w += s.substr(i, every) + "\n";
  return w;
}

/// The lattice as a .vtu in encoding `e`.
std::string vtu(Lattice const& l, Encoding const& e) {
  std::vector<Array> const arrays = l.arrays();
  std::string appended;
  auto element = [&](Array const& a) {
    std::string s = "<DataArray type=\"" + a.type + "\" Name=\"" + a.name + "\"";
    if (a.ncomp > 1) s += " NumberOfComponents=\"" + std::to_string(a.ncomp) + "\"";
    if (e.format == "ascii") return s + " format=\"ascii\">\n" + a.ascii + "\n</DataArray>\n";
    Payload const p = payload(a.bytes, e);
    if (e.format == "binary") {
      std::string text;
      if (e.zblock) text = base64(p.header.data(), p.header.size()) + base64(p.data.data(), p.data.size());
      else {
        std::vector<unsigned char> all(p.header);
        all.insert(all.end(), p.data.begin(), p.data.end());
        text = base64(all.data(), all.size());
      }
      return s + " format=\"binary\">\n" + wrapped(text, e.wrap) + "\n</DataArray>\n";
    }
    s += " format=\"appended\" offset=\"" + std::to_string(appended.size()) + "\"/>\n";
    if (e.appended_base64 && e.zblock)
      appended += base64(p.header.data(), p.header.size()) + base64(p.data.data(), p.data.size());
    else if (e.appended_base64) {
      std::vector<unsigned char> all(p.header);
      all.insert(all.end(), p.data.begin(), p.data.end());
      appended += base64(all.data(), all.size());
    } else {
      appended.append(p.header.begin(), p.header.end());
      appended.append(p.data.begin(), p.data.end());
    }
    return s;
  };
  std::string d = "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\"";
  d += e.header == 8 ? " header_type=\"UInt64\"" : " header_type=\"UInt32\"";
  if (e.zblock) d += " compressor=\"vtkZLibDataCompressor\"";
  d += ">\n<!-- not data: <DataArray Name=\"x\"> 1 2 3 --> <!-- > -->\n<UnstructuredGrid>\n";
  d += "<Piece NumberOfPoints=\"" + std::to_string(l.points()) + "\" NumberOfCells=\"" + std::to_string(l.cells()) + "\">\n";
  d += "<PointData Note=\"a > in quotes\">\n" + element(arrays[0]) + "</PointData>\n";
  d += "<CellData>\n" + element(arrays[1]) + "</CellData>\n";
  d += "<Points>\n" + element(arrays[2]) + "</Points>\n<Cells>\n";
  for (size_t i = 3; i < arrays.size(); ++i) d += element(arrays[i]);
  d += "</Cells>\n</Piece>\n</UnstructuredGrid>\n";
  if (e.format == "appended")
    d += std::string("<AppendedData encoding=\"") + (e.appended_base64 ? "base64" : "raw") + "\">\n _" + appended +
         "\n</AppendedData>\n";
  return d + "</VTKFile>\n";
}

void require_same(UnstructuredGrid const& a, UnstructuredGrid const& b) {
  REQUIRE(a.xyz == b.xyz);
  REQUIRE(a.tets == b.tets);
  REQUIRE(a.hexes == b.hexes);
  REQUIRE(a.point_arrays.size() == b.point_arrays.size());
  for (size_t i = 0; i < a.point_arrays.size(); ++i) REQUIRE(a.point_arrays[i].values == b.point_arrays[i].values);
  REQUIRE(a.cell_arrays.size() == b.cell_arrays.size());
  for (size_t i = 0; i < a.cell_arrays.size(); ++i) {
    REQUIRE(a.cell_arrays[i].tet_values == b.cell_arrays[i].tet_values);
    REQUIRE(a.cell_arrays[i].hex_values == b.cell_arrays[i].hex_values);
  }
  REQUIRE(a.report.polyhedra_split == b.report.polyhedra_split);
}

/// The message of the IoError reading `bytes` throws ("" if none).
std::string error_of(std::string const& bytes) {
  try {
    (void)read_vtu_from_memory(bytes, "gen.vtu");
  } catch (IoError const& e) {
    return e.what();
  }
  return "";
}

uint64_t line_of(std::string const& s, size_t offset) { return 1 + uint64_t(std::count(s.begin(), s.begin() + long(offset), '\n')); }

}  // namespace

TEST_CASE("VTU encodings read the same grid as ASCII: base64 in parallel chunks, appended, zlib blocks", "[io][vtu]") {
  // Points: 37^3 x 12 bytes = 608 KB and connectivity 3 MB: more than two
  // parallel base64 chunks of 192 KB each.
  Lattice const l;
  UnstructuredGrid const ref = read_vtu_from_memory(vtu(l, Encoding{}), "ascii.vtu");
  REQUIRE(ref.report.polyhedra_split == l.npoly);
  REQUIRE(ref.hex_count() == l.cells() - l.npoly + 6 * l.npoly);
  REQUIRE(ref.vertex_count() == l.points() + l.npoly);
  struct Case {
    char const* what;
    Encoding e;
  };
  Case const cases[] = {
      {"inline base64, UInt64", {"binary", false, 8, 0, 0}},
      {"inline base64, UInt32", {"binary", false, 4, 0, 0}},
      {"inline base64, lines of 76", {"binary", false, 8, 0, 76}},
      {"inline base64, lines of 4000 (breaks inside parallel chunks)", {"binary", false, 4, 0, 4000}},
      {"inline base64 zlib, blocks of 32768 with a short last one, UInt32", {"binary", false, 4, 32768, 0}},
      {"inline base64 zlib, UInt64, wrapped", {"binary", false, 8, 32768, 1000}},
      // Blocks before the break decode where they inflate, then the whole
      // array is read again by the careful path.
      {"inline base64 zlib, a line break after 200000 characters", {"binary", false, 4, 32768, 200000}},
      {"appended raw, UInt64", {"appended", false, 8, 0, 0}},
      {"appended raw, UInt32", {"appended", false, 4, 0, 0}},
      {"appended base64, UInt64", {"appended", true, 8, 0, 0}},
      {"appended base64, UInt32", {"appended", true, 4, 0, 0}},
      {"appended raw zlib, UInt64", {"appended", false, 8, 32768, 0}},
      {"appended base64 zlib, UInt32", {"appended", true, 4, 65536, 0}},
  };
  for (Case const& c : cases) {
    INFO(c.what);
    require_same(read_vtu_from_memory(vtu(l, c.e), "gen.vtu"), ref);
  }
}

TEST_CASE("VTU base64: a stray space deep in a long run, and errors placed exactly past the parallel chunks", "[io][vtu]") {
  Lattice const l;
  UnstructuredGrid const ref = read_vtu_from_memory(vtu(l, Encoding{}), "ascii.vtu");
  std::string const doc = vtu(l, Encoding{"binary", false, 8, 0, 0});
  size_t const conn = doc.find('>', doc.find("Name=\"connectivity\"")) + 2;  // the text starts after ">\n"
  size_t const group = conn + 4 * 150000;  // a 4-character group in the third chunk of 65536
  REQUIRE(doc.find('<', conn) > group + 100);
  SECTION("whitespace inside a group: same values") {
    std::string d = doc;
    d.insert(group + 1, " \n ");
    require_same(read_vtu_from_memory(d, "gen.vtu"), ref);
  }
  SECTION("an invalid character: named with its file byte") {
    std::string d = doc;
    d[group + 1] = '!';
    CHECK(error_of(d) == "gen.vtu: byte " + std::to_string(group + 1) + ": connectivity: invalid base64 character '!'");
  }
  SECTION("padding in the middle of a group: named at the group") {
    std::string d = doc;
    d[group + 1] = '=';
    CHECK(error_of(d) == "gen.vtu: byte " + std::to_string(group) + ": connectivity: invalid base64 padding");
  }
  SECTION("truncated text: the header's byte count is more than is left") {
    std::string d = doc;
    size_t const pts = d.find('>', d.find("Name=\"Points\"")) + 2;
    d.erase(pts + 4000, 400000);
    std::string const err = error_of(d);
    CHECK(err.find("gen.vtu: byte ") == 0);
    CHECK(err.find(": Points: " + std::to_string(l.points() * 12) + " bytes declared but at most") != std::string::npos);
  }
}

TEST_CASE("VTU: lines in errors count the DataArray text kept out of the XML parser", "[io][vtu]") {
  Lattice const l{4, 3, 10};
  for (Encoding const& e : {Encoding{}, Encoding{"binary", false, 8, 0, 60}}) {
    std::string const doc = vtu(l, e);
    SECTION(e.format + ": an error in a late array names its element's line") {
      std::string d = doc;
      size_t const at = d.find("Name=\"types\" format=\"");
      size_t const q = d.find('"', at + 21);
      d.replace(at + 21, q - (at + 21), "bogus");
      CHECK(error_of(d) == "gen.vtu:" + std::to_string(line_of(d, at)) + ": types: unknown format 'bogus'");
    }
    SECTION(e.format + ": an XML error after the arrays names its own line") {
      std::string d = doc;
      size_t const at = d.find("</Piece>");
      d.replace(at, 8, "</Pieces>");
      CHECK(error_of(d) == "gen.vtu:" + std::to_string(line_of(d, at)) + ": XML error: Start-end tags mismatch");
    }
  }
}

TEST_CASE("VTU polyhedra split in chunks: the first error in file order is the one reported", "[io][vtu][polyhedra]") {
  Lattice const l{12, 10, 1000};  // 1,000 polyhedra: 4 chunks of 256
  std::string const doc = vtu(l, Encoding{});
  size_t const faces = doc.find('>', doc.find("Name=\"faces\"")) + 2;
  // Polyhedron p's face stream is 31 numbers: 6, then (4, a, b, c, d) x 6.
  auto token = [&](std::string const& d, uint64_t index) {
    size_t at = faces;
    for (uint64_t i = 0; i < index; ++i) at = d.find(' ', at) + 1;
    return at;
  };
  auto set_faces = [&](std::string& d, uint64_t poly, char const* nfaces) {
    size_t const at = token(d, 31 * poly);
    d.replace(at, 1, nfaces);
  };
  UnstructuredGrid const ok = read_vtu_from_memory(doc, "gen.vtu");
  CHECK(ok.report.polyhedra_split == 1000);
  CHECK(ok.report.polyhedron_pyramids == 6000);
  std::string const at = "gen.vtu:" + std::to_string(line_of(doc, doc.find("Name=\"faces\""))) + ": faces: ";
  SECTION("errors in chunks 3 and 1: chunk 1's") {
    std::string d = doc;
    set_faces(d, 900, "3");
    set_faces(d, 300, "2");
    CHECK(error_of(d) == at + "polyhedron cell 300 declares 2 faces");
  }
  SECTION("a face that does not close, in the last chunk") {
    std::string d = doc;
    size_t const a = token(d, 31 * 999 + 2);  // polyhedron 999's first face's first vertex
    d.replace(a, d.find(' ', a) - a, "0");
    CHECK(error_of(d).find(at + "polyhedron cell 999 ") == 0);
  }
  SECTION("a faceoffsets error after a faces error: the faces error, before it") {
    std::string d = doc;
    size_t const fo = d.find('>', d.find("Name=\"faceoffsets\"")) + 2;
    size_t b = fo;
    for (int i = 0; i < 800; ++i) b = d.find(' ', b) + 1;
    d.replace(b, d.find(' ', b) - b, "5");  // polyhedron 800 ends before it starts
    std::string const order = error_of(d);
    CHECK(order == "gen.vtu:" + std::to_string(line_of(d, d.find("Name=\"faceoffsets\""))) +
                       ": faceoffsets: polyhedron cell 800 ends at 5, before its start " + std::to_string(31 * 800));
    set_faces(d, 500, "2");
    CHECK(error_of(d) == at + "polyhedron cell 500 declares 2 faces");
  }
}

}  // namespace test_io_vtu_encodings
