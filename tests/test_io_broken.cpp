// Malformed files raise IoError naming the file and the line or byte offset,
// with a message saying what is wrong; never a crash, never a partial grid.
// The corpus is tests/data/broken/ (written by make_broken.py there); this
// test runs under the sanitizer build too.

#include <catch2/catch.hpp>

#include <sys/resource.h>
#include <sys/stat.h>

#include <cstring>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <zlib.h>

#include <cellray/io/read_mesh.hpp>

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_io_broken {

using namespace cellray;

namespace {

struct Expect {
  char const* file;
  char const* where;  ///< ":LINE: " or ": byte N: " right after the path
  char const* says;   ///< a part of the message
};

// Lines and byte offsets checked by hand against the generator's layout
// (e.g. bad_index_binary.vtk: 67 header bytes + "POINTS 4 float\n" + 48 +
// "\n" + "CELLS 1 5\n" = 141, + 4 ids * 4 bytes = 157).
Expect const corpus[] = {
    {"empty.vtk", ":1: ", "not a legacy VTK file"},
    {"not_vtk.vtk", ":1: ", "not a legacy VTK file"},
    {"bad_encoding.vtk", ":3: ", "expected ASCII or BINARY, found 'TEXT'"},
    {"polydata.vtk", ":4: ", "dataset type 'POLYDATA' is not supported"},
    {"truncated_ascii_points.vtk", ":5: ", "POINTS: 12 values declared but only 19 bytes"},
    {"non_numeric.vtk", ":7: ", "POINTS: value 4 is 'abc', not a number"},
    {"non_numeric_cells.vtk", ":11: ", "value 4 is 'x3', not an integer"},
    {"huge_points.vtk", ":5: ", "3000000000 values declared"},
    {"too_many_points.vtk", ":5: ", "32-bit vertex ids"},
    {"huge_cells.vtk", ":10: ", "999999999999 values declared"},
    {"huge_count_overflow.vtk", ":5: ", "not a count"},
    {"wrong_cells_size.vtk", ":10: ", "CELLS declares 6 entries but its 1 cells use 5"},
    {"cell_overrun.vtk", ":12: ", "cell 1 claims 100 vertices"},
    {"cell_types_count.vtk", ":12: ", "CELL_TYPES lists 2 cells but CELLS has 1"},
    {"bad_index.vtk", ":12: ", "cell 1 uses vertex id 9, outside [0, 4)"},
    {"negative_index.vtk", ":11: ", "cell 0 uses vertex id -1"},
    {"unknown_cell_type.vtk", ":13: ", "unknown VTK cell type 99"},
    {"quadratic_triangle.vtk", ":15: ", "1 quadratic_triangle (VTK type 22)"},
    {"tet_three_ids.vtk", ":11: ", "cell 0 (tetra) has 3 vertex ids, needs 4"},
    {"point_data_count.vtk", ":14: ", "POINT_DATA declares 5 values for 4 points"},
    {"cell_data_count.vtk", ":14: ", "CELL_DATA declares 2 values for 1 cells"},
    {"field_tuples.vtk", ":16: ", "FIELD array 'T' has 3 tuples but POINT_DATA declares 4"},
    {"scalars_no_lookup.vtk", ":16: ", "expected LOOKUP_TABLE"},
    {"scalars_outside_section.vtk", ":14: ", "SCALARS outside POINT_DATA / CELL_DATA"},
    {"unknown_keyword.vtk", ":10: ", "unknown keyword 'BOGUS'"},
    {"unknown_type.vtk", ":5: ", "unknown data type 'float128'"},
    {"no_cells.vtk", ":10: ", "no CELLS section"},
    {"no_cell_types.vtk", ":12: ", "no CELL_TYPES section"},
    {"two_points_sections.vtk", ":10: ", "a second POINTS section"},
    {"offsets_decreasing.vtk", ":12: ", "offset 2 (3) is smaller than the one before"},
    {"offsets_last.vtk", ":12: ", "the last offset is 4 but CONNECTIVITY has 5 entries"},
    {"offsets_float.vtk", ":11: ", "OFFSETS must have an integer type"},
    {"no_connectivity.vtk", ":13: ", "expected CONNECTIVITY after OFFSETS"},
    {"truncated_binary_points.vtk", ": byte 82: ", "12 values need 48 bytes but only 20 are left"},
    {"truncated_binary_cells.vtk", ": byte 141: ", "5 values need 20 bytes but only 9 are left"},
    {"truncated_binary_scalars.vtk", ": byte 230: ", "4 values need 16 bytes but only 10 are left"},
    {"huge_points_binary.vtk", ": byte 91: ", "need 12000000000 bytes but only 48 are left"},
    {"bad_index_binary.vtk", ": byte 157: ", "cell 0 uses vertex id 70000"},
    {"unknown_cell_type_binary.vtk", ": byte 175: ", "unknown VTK cell type -3"},
    {"binary_string_overrun.vtk", ": byte 232: ", "truncated string length"},
    {"not_xml.vtu", ":1: ", "XML error"},
    {"truncated_xml.vtu", ":4: ", "XML error"},
    {"polydata.vtu", ":2: ", "VTK XML type 'PolyData' is not supported"},
    {"no_piece.vtu", ":3: ", "no Piece element"},
    {"two_pieces.vtu", ":3: ", "2 pieces"},
    {"no_cells.vtu", ":4: ", "no Cells element"},
    {"no_types.vtu", ":8: ", "no DataArray named 'types'"},
    {"points_two_components.vtu", ":6: ", "NumberOfComponents=\"3\""},
    {"bad_count_attr.vtu", ":4: ", "NumberOfPoints is 'four', not a count"},
    {"ascii_too_few.vtu", ":6: ", "12 values declared"},
    {"ascii_too_many.vtu", ":6: ", "more values than the 12 expected"},
    {"non_numeric.vtu", ":6: ", "value 11 is 'x1', not a number"},
    {"bad_index.vtu", ":9: ", "cell 0 uses vertex id 7, outside [0, 4)"},
    {"unknown_cell_type.vtu", ":11: ", "unknown VTK cell type 200"},
    {"offsets_decreasing.vtu", ":10: ", "cell 1 ends at 3, before its start 4"},
    {"quadratic_triangle.vtu", ":11: ", "1 quadratic_triangle (VTK type 22)"},
    {"unknown_data_type.vtu", ":6: ", "unknown DataArray type 'Float16'"},
    {"unknown_format.vtu", ":6: ", "unknown format 'hex'"},
    {"bad_header_type.vtu", ":2: ", "unknown header_type 'UInt16'"},
    {"lz4.vtu", ":2: ", "compressor 'vtkLZ4DataCompressor' is not supported"},
    {"point_tuples.vtu", ":6: ", "NumberOfTuples is not 4"},
    {"bad_base64_char.vtu", ": byte 310: ", "invalid base64 character '*'"},
    {"bad_base64_padding.vtu", ": byte 289: ", "invalid base64 padding"},
    {"truncated_base64.vtu", ": byte 308: ", "48 bytes declared but at most 23 are left"},
    {"base64_wrong_size.vtu", ": byte 289: ", "the header says 40 bytes, expected 48"},
    {"bad_zlib.vtu", ": byte 359: ", "zlib block 0 of 1 does not inflate to 48 bytes"},
    {"zlib_size_lie.vtu", ": byte 359: ", "does not inflate to 48 bytes (got 40)"},
    {"zlib_huge_claim.vtu", ": byte 332: ", "1200000000 bytes cannot come from 10 compressed bytes"},
    {"zlib_huge_block_count.vtu", ": byte 324: ", "4294967295 compressed blocks"},
    {"truncated_appended.vtu", ": byte 662: ", "48 bytes declared but at most 18 are left"},
    {"appended_offset_out_of_range.vtu", ":6: ", "offset 5000 lies beyond the appended data"},
    {"appended_missing.vtu", ":6: ", "no AppendedData"},
    {"appended_no_marker.vtu", ":16: ", "AppendedData must start with '_'"},
    {"appended_huge_header.vtu", ": byte 670: ", "1200000000 bytes declared"},
    {"binary_connectivity_size.vtu", ": byte 422: ", "the header says 24 bytes, expected 32"},
    // Issue #24: a short POINT_DATA count is named where it is declared (it
    // read "unknown keyword '4'" at the first value past the count), the
    // declared type of ASCII connectivity (it said Float64), junk behind a
    // zlib header (byte 700: where block 0's base64 starts).
    {"point_data_short.vtk", ":14: ", "POINT_DATA declares 3 values for 4 points"},
    {"float_connectivity.vtu", ":9: ", "connectivity is stored as Float32, not integers"},
    {"zlib_junk_blocks.vtu", ": byte 700: ", "zlib block 0 of 64 does not inflate to 49152 bytes"},
};

std::string broken(char const* f) { return std::string(CELLRAY_TEST_DATA) + "/broken/" + f; }

}  // namespace

TEST_CASE("every broken file raises IoError naming file, place and problem", "[io][broken]") {
  for (auto const& e : corpus) {
    std::string const path = broken(e.file);
    CAPTURE(path);
    std::string msg;
    try {
      (void)read_mesh(path);
      FAIL("no error for " << path);
    } catch (IoError const& err) {
      msg = err.what();
    }
    CAPTURE(msg);
    CHECK(msg.rfind(path + e.where, 0) == 0);  // starts with the path and the place
    CHECK(msg.find(e.says) != std::string::npos);
    // The in-memory entry gives the same message under the name it is given.
    std::string const bytes = io::read_file_bytes(path);
    CHECK_THROWS_WITH(read_mesh_from_memory(bytes, e.file), std::string(e.file) + msg.substr(path.size()));
  }
}

/// Standard base64 with padding, as VTK writes it.
std::string to_base64(std::string const& in) {
  static char const* const abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < in.size(); i += 3) {
    uint32_t n = uint32_t(uint8_t(in[i])) << 16;
    if (i + 1 < in.size()) n |= uint32_t(uint8_t(in[i + 1])) << 8;
    if (i + 2 < in.size()) n |= uint32_t(uint8_t(in[i + 2]));
    out += abc[n >> 18 & 63], out += abc[n >> 12 & 63];
    out += i + 1 < in.size() ? abc[n >> 6 & 63] : '=';
    out += i + 2 < in.size() ? abc[n & 63] : '=';
  }
  return out;
}

/// Peak resident memory of this process so far, bytes (Linux: ru_maxrss in KiB).
uint64_t peak_rss() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return uint64_t(u.ru_maxrss) * 1024;
}

TEST_CASE("a zlib header claiming 1 GiB over 1 MB of junk fails at block 0 without allocating the claim",
          "[io][broken]") {
  // 1024 blocks of 1032192 bytes (88M points) over 1024 x 1001 bytes of
  // junk: within deflate's 1032:1, so only inflating can tell. The reader
  // used to allocate (and zero) the whole claim first: 1 GB of RSS.
  constexpr uint32_t nblocks = 1024, block = 1032192, csize = 1001;
  std::string raw;
  auto put32 = [&raw](uint32_t v) { raw.append(reinterpret_cast<char const*>(&v), 4); };
  put32(nblocks), put32(block), put32(0);
  for (uint32_t i = 0; i < nblocks; ++i) put32(csize);
  std::string const header = raw;
  std::string junk(size_t(nblocks) * csize, '\0');
  for (size_t i = 0; i < junk.size(); ++i) junk[i] = char((i * 97 + 13) % 251);
  std::string const vtu =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
      "header_type=\"UInt32\" compressor=\"vtkZLibDataCompressor\">\n<UnstructuredGrid>\n"
      "<Piece NumberOfPoints=\"88080384\" NumberOfCells=\"1\">\n<Points>\n"
      "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"binary\">" +
      to_base64(header) + to_base64(junk) +
      "</DataArray>\n</Points>\n<Cells>\n"
      "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>\n"
      "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n"
      "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray>\n"
      "</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  uint64_t const before = peak_rss();
  CHECK_THROWS_WITH(read_mesh_from_memory(vtu, "bomb.vtu"),
                    Catch::StartsWith("bomb.vtu: byte ") && Catch::Contains("zlib block 0 of 1024"));
  uint64_t const grown = peak_rss() - before;
  INFO("peak RSS grew by " << grown / (1 << 20) << " MiB");
  CHECK(grown < (uint64_t(100) << 20));
}

TEST_CASE("zlib blocks inflate in parallel, yet report the first bad block where the serial reader did", "[io][broken]") {
  // A unit hexahedron whose 96 point bytes are 4 zlib blocks of 24 bytes.
  std::string points;
  for (int i = 0; i < 8; ++i) {
    float const p[3] = {float(i & 1), float(i >> 1 & 1), float(i >> 2 & 1)};
    points.append(reinterpret_cast<char const*>(p), sizeof p);
  }
  constexpr size_t block = 24, nblocks = 4;
  std::vector<std::string> z(nblocks);
  for (size_t b = 0; b < nblocks; ++b) {
    uLongf zl = compressBound(uLong(block));
    z[b].resize(zl);
    compress2(reinterpret_cast<Bytef*>(z[b].data()), &zl, reinterpret_cast<Bytef const*>(points.data()) + b * block,
              uLong(block), 6);
    z[b].resize(zl);
  }
  auto header = [&] {
    std::string h;
    auto put32 = [&h](uint32_t v) { h.append(reinterpret_cast<char const*>(&v), 4); };
    put32(nblocks), put32(block), put32(0);
    for (auto const& c : z) put32(uint32_t(c.size()));
    return h;
  };
  auto vtu = [](std::string const& format, std::string const& inline_text, std::string const& appended) {
    std::string s =
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
        "header_type=\"UInt32\" compressor=\"vtkZLibDataCompressor\">\n<UnstructuredGrid>\n"
        "<Piece NumberOfPoints=\"8\" NumberOfCells=\"1\">\n<Points>\n"
        "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"" + format + "\"" +
        (format == "appended" ? " offset=\"0\"/>\n" : ">" + inline_text + "</DataArray>\n") +
        "</Points>\n<Cells>\n"
        "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 3 2 4 5 7 6</DataArray>\n"
        "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">8</DataArray>\n"
        "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">12</DataArray>\n"
        "</Cells>\n</Piece>\n</UnstructuredGrid>\n";
    if (format == "appended") s += "<AppendedData encoding=\"raw\">_" + appended + "\n</AppendedData>\n";
    return s + "</VTKFile>\n";
  };
  auto blocks = [&] {
    std::string d;
    for (auto const& c : z) d += c;
    return d;
  };

  SECTION("every block lands at its place") {
    UnstructuredGrid const g = read_mesh_from_memory(vtu("appended", "", header() + blocks()), "ok.vtu");
    REQUIRE(g.xyz.size() == 24);
    CHECK(std::memcmp(g.xyz.data(), points.data(), points.size()) == 0);
    CHECK(g.hexes.size() == 8);
  }
  SECTION("a corrupt block is named with the byte where it starts") {
    std::string const good0 = z[0], good1 = z[1];
    z[2].assign(z[2].size(), '\xff');
    std::string const f = vtu("appended", "", header() + blocks());
    size_t const at = f.find("encoding=\"raw\">_") + 16 + header().size() + good0.size() + good1.size();
    CHECK_THROWS_WITH(read_mesh_from_memory(f, "bad.vtu"),
                      Catch::StartsWith("bad.vtu: byte " + std::to_string(at) + ": ") &&
                          Catch::Contains("zlib block 2 of 4 does not inflate to 24 bytes"));
  }
  SECTION("a bad block is reported before a later unreadable one, as the serial reader did") {
    std::string const data_text = to_base64(blocks());
    std::string broken_text = data_text;
    broken_text.insert(data_text.size() / 4 * 3, "*");  // inside block 2 or 3's text
    CHECK_THROWS_WITH(read_mesh_from_memory(vtu("binary", to_base64(header()) + broken_text, ""), "b64.vtu"),
                      Catch::Contains("invalid base64 character '*'"));
    z[0].assign(z[0].size(), '\xff');
    broken_text = to_base64(blocks());
    broken_text.insert(broken_text.size() / 4 * 3, "*");
    CHECK_THROWS_WITH(read_mesh_from_memory(vtu("binary", to_base64(header()) + broken_text, ""), "b64.vtu"),
                      Catch::Contains("zlib block 0 of 4 does not inflate to 24 bytes"));
  }
}

TEST_CASE("FIFOs, directories and devices are refused before they are opened", "[io][broken]") {
  std::string const dir = std::filesystem::temp_directory_path().string() + "/cellray_io_nonregular";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir + "/mesh.vtk");
  REQUIRE(mkfifo((dir + "/fifo.vtu").c_str(), 0600) == 0);
  // Opening the FIFO would block until a writer comes: none ever does.
  CHECK_THROWS_WITH(read_mesh(dir + "/fifo.vtu"), Catch::Contains("fifo.vtu: is a FIFO"));
  CHECK_THROWS_WITH(read_mesh(dir + "/mesh.vtk"), Catch::Contains("mesh.vtk: is a directory"));
  CHECK_THROWS_WITH(read_mesh(dir + "/none.vtk"), Catch::Contains("none.vtk: cannot open file"));
  std::filesystem::create_symlink("/dev/zero", dir + "/zero.vtk");
  CHECK_THROWS_WITH(read_mesh(dir + "/zero.vtk"), Catch::Contains("zero.vtk: is a device"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("the broken corpus and its expectations list the same files", "[io][broken]") {
  std::set<std::string> listed, present;
  for (auto const& e : corpus) listed.insert(e.file);
  for (auto const& f : std::filesystem::directory_iterator(std::string(CELLRAY_TEST_DATA) + "/broken")) {
    std::string const ext = f.path().extension().string();
    if (ext == ".vtk" || ext == ".vtu") present.insert(f.path().filename().string());
  }
  CHECK(listed == present);
}

TEST_CASE("truncated and corrupted real files fail cleanly or load", "[io][broken]") {
  // A robustness sweep (the sanitizer build turns any out-of-bounds read into
  // a failure): every prefix of a small VTU, and byte corruptions of it and of
  // a legacy binary file. Each read either succeeds or throws IoError.
  auto attempt = [](std::string const& bytes, char const* name) {
    try {
      UnstructuredGrid const g = read_mesh_from_memory(bytes, name);
      for (uint32_t v : g.tets) REQUIRE(v < g.vertex_count());
      for (uint32_t v : g.hexes) REQUIRE(v < g.vertex_count());
      for (auto const& a : g.point_arrays) REQUIRE(a.values.size() == g.vertex_count());
      return true;
    } catch (IoError const&) {
      return false;
    }
  };
  std::string const vtu = io::read_file_bytes(std::string(CELLRAY_SHARED_DATA) + "/vtk-data/Tetrahedron.vtu");
  // Raw appended data runs to the end of the file, so only a cut inside the
  // closing tags after it (the last 40 bytes) can still load.
  for (size_t n = 0; n + 40 < vtu.size(); ++n) CHECK_FALSE(attempt(vtu.substr(0, n), "t.vtu"));
  CHECK(attempt(vtu, "t.vtu"));
  uint32_t state = 12345;
  auto next = [&state] { return state = state * 1664525u + 1013904223u; };
  for (int i = 0; i < 2000; ++i) {
    std::string v = vtu;
    v[next() % v.size()] = char(next() >> 24);
    attempt(v, "t.vtu");
  }
  std::string const legacy = io::read_file_bytes(std::string(CELLRAY_SHARED_DATA) + "/vtk-data/post.vtk");
  // Only a cut in the final newline after the last value can still load.
  for (size_t n = 0; n + 1 < legacy.size(); n += 1009) CHECK_FALSE(attempt(legacy.substr(0, n), "p.vtk"));
  for (int i = 0; i < 300; ++i) {
    std::string v = legacy;
    for (int k = 0; k < 4; ++k) v[next() % v.size()] = char(next() >> 24);
    attempt(v, "p.vtk");
  }
}

}  // namespace test_io_broken
