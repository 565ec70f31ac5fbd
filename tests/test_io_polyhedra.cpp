// Polyhedra in VTU files (VTK 42, `faces` / `faceoffsets`; issue #21): each
// is split around an added centre point (its volume centroid) into
// pyramids and tetrahedra (faces cut into quads and triangles as OpenFOAM
// cuts them; pyramids stored as collapsed hexahedra), as foamToVTK
// -poly-decomp does; the centre takes
// the polyhedron's value where a cell array has the point array's name,
// and the new cells carry the polyhedron's cell values. Faces that do not
// close or name points the file lacks are errors naming the cell.
// Legacy .vtk files hold the same polyhedra as face streams in their
// connectivity (VTK 9.1's writer, versions 4.2 and 5.1, ASCII and binary)
// and read as the same grid as the .vtu.
// tests/data/polyhedra/make_polyhedra.py (python3-vtk9) wrote the files.

#include <catch2/catch.hpp>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <cellray/io/read_mesh.hpp>
#include <cellray/io/vtk_legacy.hpp>
#include <cellray/io/vtu.hpp>
#include <cellray/mesh/validate.hpp>

#include "support/test_data.hpp"

namespace test_io_polyhedra {

using namespace cellray;

namespace {

std::string file(char const* name) { return std::string(CELLRAY_TEST_DATA) + "/polyhedra/" + name; }

}  // namespace

TEST_CASE("polyhedra in a .vtu split into pyramids and tetrahedra around their centres", "[io][polyhedra]") {
  UnstructuredGrid const g = read_mesh(file("two_polyhedra.vtu"));
  CHECK(g.report.cells_read.at(42) == 2);
  CHECK(g.report.polyhedra_split == 2);
  // Cube: 6 quads -> 6 pyramids. Prism: 5 quads -> 5 pyramids; each
  // pentagon is cut (as OpenFOAM cuts it) into a triangle and a quad: one
  // more tet and one more pyramid each.
  CHECK(g.hex_count() == 13);
  CHECK(g.tet_count() == 2);
  CHECK(g.report.polyhedron_pyramids == 13);
  CHECK(g.report.polyhedron_tets == 2);
  REQUIRE(g.vertex_count() == 18 + 2);
  // Centres at the volume centroids, after the file's points.
  CHECK(g.xyz[3 * 18] == Approx(0.5));
  CHECK(g.xyz[3 * 18 + 1] == Approx(0.5));
  CHECK(g.xyz[3 * 18 + 2] == Approx(0.5));
  CHECK(g.xyz[3 * 19 + 2] == Approx(1.75));
  // Point array T: at the centres, the cell array T's values (foamToVTK).
  PointArray const* t = g.point_array("T");
  REQUIRE(t);
  CHECK(t->values[18] == 10.f);
  CHECK(t->values[19] == 20.f);
  CHECK(t->values[6] == Approx(1 + 2 + 3));  // the file's points keep theirs
  // Cell array id: each new cell carries its polyhedron's value.
  CellArray const* id = g.cell_array("id");
  REQUIRE(id);
  CHECK(id->hex_values == std::vector<float>{1, 1, 1, 1, 1, 1, 2, 2, 2, 2, 2, 2, 2});
  CHECK(id->tet_values == std::vector<float>(2, 2.f));
  // Each piece has its polyhedron's file cell id (the file holds only the two).
  CHECK(g.hex_file_cells == std::vector<uint32_t>{0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1});
  CHECK(g.tet_file_cells == std::vector<uint32_t>{1, 1});
  // Every pyramid's apex is its centre; every cell is positively oriented.
  for (uint64_t c = 0; c < g.hex_count(); ++c)
    for (int k = 4; k < 8; ++k) CHECK(g.hexes[8 * c + uint64_t(k)] == (c < 6 ? 18u : 19u));
  ValidationReport const hr = validate(g.hex_mesh().with_array("T"));
  ValidationReport const tr = validate(g.tet_mesh().with_array("T"));
  CHECK(hr.ok());
  CHECK(!hr.inverted);
  CHECK(!hr.zero_volume);
  CHECK(!tr.inverted);
  CHECK(!tr.zero_volume);
  CHECK_THAT(g.report.summary(), Catch::Contains("2 polyhedra split into 2 tetrahedra and 13 pyramids"));
}

TEST_CASE("the snappy flange's polyhedra split into the cells foamToVTK -poly-decomp made of them",
          "[io][polyhedra][data]") {
  auto const vtu = test::shared_data_file("openfoam/flange_snappy_89k.vtu");
  auto const decomp = test::shared_data_file("openfoam/flange_snappy_89k_decomp.vtk");
  if (!vtu || !decomp) return;
  UnstructuredGrid const g = read_mesh(*vtu);
  UnstructuredGrid const d = read_mesh(*decomp);
  REQUIRE(g.report.polyhedra_split == 10750);
  // foamToVTK wrote 16 wedge-shaped polyhedra as wedges (3 pyramids and 2
  // tets each here) and split the rest; where two cuts of a face tie, each
  // picks its own. Within 0.1% of its pyramids and tets:
  uint64_t const wedges_as_poly = d.report.cells_read.at(13) - g.report.cells_read.at(13);
  CHECK(wedges_as_poly == 16);
  double const pyramids = double(d.report.cells_read.at(14) + 3 * wedges_as_poly);
  double const tets = double(d.report.cells_read.at(10) + 2 * wedges_as_poly);
  CHECK(double(g.report.polyhedron_pyramids) == Approx(pyramids).epsilon(1e-3));
  CHECK(double(g.report.polyhedron_tets) == Approx(tets).epsilon(1e-3));
  // A fan of a concave face made inverted tets (8,070 of 127,428); the cut
  // from the widest corner makes none. No cell of either file is inside
  // out; pyramids over warped faces (and a few concave hexahedra) have a
  // negative Jacobian at a corner, no more here than in foamToVTK's file
  // (2,796 of its pyramids and hexahedra).
  ValidationReport const tr = validate(g.tet_mesh().with_array("T"));
  ValidationReport const hr = validate(g.hex_mesh().with_array("T"));
  ValidationReport const dh = validate(d.hex_mesh().with_array("T"));
  CHECK(tr.inverted.count == 0);
  CHECK(hr.inverted.count == 0);
  CHECK(dh.inverted.count == 0);
  CHECK(dh.distorted.count > 0);
  CHECK(double(hr.distorted.count) <= 1.01 * double(dh.distorted.count));
  // Named by the file's cell ids, both files name the same first distorted
  // cell (foamToVTK keeps OpenFOAM's cell order and appends the polyhedra's
  // pieces); the hexahedral part's index names another one.
  ValidationReport const hr_file = validate(g.hex_mesh().with_array("T"), view(g.hex_file_cells));
  ValidationReport const dh_file = validate(d.hex_mesh().with_array("T"), view(d.hex_file_cells));
  CHECK(hr_file.distorted.count == hr.distorted.count);
  CHECK(hr_file.distorted.first == dh_file.distorted.first);
  CHECK(hr_file.distorted.first != hr.distorted.first);
}

TEST_CASE("a polyhedron whose faces do not close, or name a missing point, is an error naming it", "[io][polyhedra]") {
  CHECK_THROWS_WITH(read_mesh(file("open_polyhedron.vtu")),
                    Catch::Contains("open_polyhedron.vtu:") && Catch::Contains("polyhedron cell 0") &&
                        Catch::Contains("does not close"));
  CHECK_THROWS_WITH(read_mesh(file("bad_face_id.vtu")),
                    Catch::Contains("bad_face_id.vtu:") && Catch::Contains("polyhedron cell 0") &&
                        Catch::Contains("vertex id 99"));
}

}  // namespace test_io_polyhedra

namespace test_io_polyhedra {

TEST_CASE("collapsed cells: repeated ids keep the real shape -- fewer than 4 distinct is an error or a skip",
          "[io][polyhedra]") {
  std::string const file =
      "# vtk DataFile Version 3.0\ncollapsed\nASCII\nDATASET UNSTRUCTURED_GRID\n"
      "POINTS 8 float\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
      "CELLS 4 32\n"
      "8 0 1 2 2 4 5 6 6\n"  // a wedge written as a hexahedron (OpenFOAM's prisms): kept
      "8 0 1 1 0 4 4 4 4\n"  // 3 distinct: a triangle, no volume
      "4 0 1 2 2\n"          // a tetrahedron with 3 distinct
      "8 0 1 2 3 4 5 6 7\n"
      "CELL_TYPES 4\n12\n12\n10\n12\n";
  CHECK_THROWS_WITH(read_vtk_legacy_from_memory(file, "collapsed.vtk"),
                    Catch::Contains("collapsed.vtk:") && Catch::Contains("cell 1 (hexahedron) has 3 distinct vertices"));
  ReadOptions skip;
  skip.skip_unsupported_cells = true;
  UnstructuredGrid const g = read_vtk_legacy_from_memory(file, "collapsed.vtk", skip);
  CHECK(g.hex_count() == 2);
  CHECK(g.tet_count() == 0);
  CHECK(g.report.cells_skipped.at(12) == 1);
  CHECK(g.report.cells_skipped.at(10) == 1);
  CHECK(g.hexes == std::vector<uint32_t>{0, 1, 2, 2, 4, 5, 6, 6, 0, 1, 2, 3, 4, 5, 6, 7});
}

}  // namespace test_io_polyhedra

namespace test_io_polyhedra {

namespace {

std::string bytes_of(std::string const& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// `b` equals `a` value for value: exactly, or within `tol` (relative and
/// absolute) for a file whose numbers went through text of 6 digits.
void check_same_floats(std::vector<float> const& a, std::vector<float> const& b, double tol) {
  REQUIRE(a.size() == b.size());
  if (tol == 0) {
    CHECK(a == b);
    return;
  }
  for (size_t i = 0; i < a.size(); ++i) CHECK(b[i] == Approx(a[i]).epsilon(tol).margin(tol));
}

/// The legacy read `b` is the .vtu read `a`: cells, positions, arrays and counts.
void check_same_grid(UnstructuredGrid const& a, UnstructuredGrid const& b, double tol) {
  CHECK(b.tets == a.tets);
  CHECK(b.hexes == a.hexes);
  check_same_floats(a.xyz, b.xyz, tol);
  CHECK(b.report.cells_read == a.report.cells_read);
  CHECK(b.report.cells_skipped == a.report.cells_skipped);
  CHECK(b.report.polyhedra_split == a.report.polyhedra_split);
  CHECK(b.report.polyhedron_tets == a.report.polyhedron_tets);
  CHECK(b.report.polyhedron_pyramids == a.report.polyhedron_pyramids);
  REQUIRE(b.point_arrays.size() == a.point_arrays.size());
  for (PointArray const& pa : a.point_arrays) {
    PointArray const* pb = b.point_array(pa.name);
    REQUIRE(pb);
    check_same_floats(pa.values, pb->values, tol);
  }
  REQUIRE(b.cell_arrays.size() == a.cell_arrays.size());
  for (CellArray const& ca : a.cell_arrays) {
    CellArray const* cb = b.cell_array(ca.name);
    REQUIRE(cb);
    CHECK(cb->tet_values == ca.tet_values);  // small integers: exact in text too
    CHECK(cb->hex_values == ca.hex_values);
  }
}

}  // namespace

TEST_CASE("legacy .vtk polyhedra (4.2 and 5.1, ASCII and binary) read as the same grid as the .vtu",
          "[io][polyhedra][legacy]") {
  for (char const* name : {"two_polyhedra", "mixed_polyhedra"}) {
    UnstructuredGrid const ref = read_mesh(file((std::string(name) + ".vtu").c_str()));
    REQUIRE(ref.report.polyhedra_split == 2);
    for (char const* variant : {"_42.vtk", "_42b.vtk", "_51.vtk", "_51b.vtk"}) {
      std::string const path = file((std::string(name) + variant).c_str());
      INFO(path);
      // VTK's legacy ASCII writer prints floats with 6 significant digits
      // (the .vtu's ASCII has 9): positions, centres and point values agree
      // to that; binary files hold the same floats, so all is exact.
      bool const binary = std::string(variant).find('b') != std::string::npos;
      double const tol = binary ? 0.0 : 2e-6;
      UnstructuredGrid const g = read_mesh(path);
      CHECK(g.report.format.find(binary ? "BINARY" : "ASCII") != std::string::npos);
      check_same_grid(ref, g, tol);
      // Well-formed polyhedra need no option; skipping changes nothing.
      ReadOptions skip;
      skip.skip_unsupported_cells = true;
      UnstructuredGrid const s = read_vtk_legacy(path, skip);
      CHECK(s.report.cells_skipped.empty());
      check_same_grid(ref, s, tol);
    }
  }
  // The mixed file's own cells come first (hexahedron, wedge as a collapsed
  // hex; tetrahedron), the polyhedra's after them, centres after the points.
  UnstructuredGrid const g = read_mesh(file("mixed_polyhedra_51b.vtk"));
  CHECK(g.hex_count() == 2 + 13);
  CHECK(g.tet_count() == 1 + 2);
  REQUIRE(g.vertex_count() == 36 + 2);
  CHECK(std::vector<uint32_t>(g.hexes.begin(), g.hexes.begin() + 8) == std::vector<uint32_t>{18, 19, 20, 21, 22, 23, 24, 25});
  CHECK(std::vector<uint32_t>(g.tets.begin(), g.tets.begin() + 4) == std::vector<uint32_t>{26, 27, 28, 29});
  CHECK(g.xyz[3 * 36 + 2] == Approx(0.5));
  CHECK(g.xyz[3 * 37 + 2] == Approx(1.75));
  CHECK(g.point_array("T")->values[36] == 10.f);
  CHECK(g.point_array("T")->values[37] == 20.f);
  CellArray const* id = g.cell_array("id");
  REQUIRE(id);
  CHECK(id->hex_values == std::vector<float>{0, 0, 1, 1, 1, 1, 1, 1, 2, 2, 2, 2, 2, 2, 2});
  CHECK(id->tet_values == std::vector<float>{0, 2, 2});
}

namespace {

constexpr char const* cube_points = "POINTS 8 float\n0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1\n";

/// A legacy 4.2 ASCII file of one polyhedron with face stream `stream`
/// (CELLS count and size from it): its connectivity is on line 8.
std::string classic(std::vector<int64_t> const& stream) {
  std::string s = std::string("# vtk DataFile Version 4.2\npoly\nASCII\nDATASET UNSTRUCTURED_GRID\n") + cube_points +
                  "CELLS 1 " + std::to_string(stream.size() + 1) + "\n" + std::to_string(stream.size());
  for (int64_t v : stream) s += " " + std::to_string(v);
  return s + "\nCELL_TYPES 1\n42\n";
}
/// The same as 5.1: a hexahedron, then the polyhedron; its stream is on line 12.
std::string offsets(std::vector<int64_t> const& stream) {
  std::string s = std::string("# vtk DataFile Version 5.1\npoly\nASCII\nDATASET UNSTRUCTURED_GRID\n") + cube_points +
                  "CELLS 3 " + std::to_string(stream.size() + 8) + "\nOFFSETS vtktypeint64\n0 8 " +
                  std::to_string(stream.size() + 8) + "\nCONNECTIVITY vtktypeint64\n0 1 2 3 4 5 6 7\n";
  for (int64_t v : stream) s += std::to_string(v) + " ";
  return s + "\nCELL_TYPES 2\n12\n42\n";
}

/// The unit cube as a polyhedron: 6 outward quads.
std::vector<int64_t> cube() {
  return {6, 4, 0, 3, 2, 1, 4, 4, 5, 6, 7, 4, 0, 1, 5, 4, 4, 1, 2, 6, 5, 4, 2, 3, 7, 6, 4, 3, 0, 4, 7};
}

std::string error_of(std::string const& bytes, char const* name = "poly.vtk") {
  try {
    read_vtk_legacy_from_memory(bytes, name);
  } catch (IoError const& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST_CASE("legacy polyhedra: a face stream that does not fit its cell, or faces that do not close, is an error naming it",
          "[io][polyhedra][legacy]") {
  // The well-formed cube, both layouts.
  UnstructuredGrid const a = read_vtk_legacy_from_memory(classic(cube()), "poly.vtk");
  CHECK(a.hex_count() == 6);
  CHECK(a.report.polyhedra_split == 1);
  UnstructuredGrid const b = read_vtk_legacy_from_memory(offsets(cube()), "poly.vtk");
  CHECK(b.hex_count() == 1 + 6);
  CHECK(b.report.polyhedra_split == 1);

  std::vector<int64_t> s = cube();
  s.pop_back();  // the stream runs past the cell's range
  CHECK(error_of(classic(s)) == "poly.vtk:8: CELLS: polyhedron cell 0: face 5 declares 4 vertices");
  CHECK(error_of(offsets(s)) == "poly.vtk:12: CONNECTIVITY: polyhedron cell 1: face 5 declares 4 vertices");
  s = cube();
  s.push_back(0);  // the range holds an entry after the stream
  CHECK(error_of(classic(s)) == "poly.vtk:8: CELLS: polyhedron cell 0: its 6 faces use 31 of its 32 entries");
  CHECK(error_of(offsets(s)) == "poly.vtk:12: CONNECTIVITY: polyhedron cell 1: its 6 faces use 31 of its 32 entries");
  s = cube();
  s[0] = 100;
  CHECK(error_of(classic(s)) == "poly.vtk:8: CELLS: polyhedron cell 0 declares 100 faces");
  s[0] = -1;
  CHECK(error_of(classic(s)) == "poly.vtk:8: CELLS: polyhedron cell 0 declares -1 faces");
  s = cube();
  s[11] = 2;  // face 2: "2 0 1", then "5 4" is read as a face of 5
  CHECK_THAT(error_of(classic(s)), Catch::StartsWith("poly.vtk:8: CELLS: polyhedron cell 0: face 2 declares 2 vertices"));
  s = cube();
  s[7] = 9;  // face 1 names point 9 of 8
  CHECK(error_of(classic(s)) == "poly.vtk:8: CELLS: polyhedron cell 0 face 1 uses vertex id 9, outside [0, 8)");
  CHECK(error_of(offsets(s)) == "poly.vtk:12: CONNECTIVITY: polyhedron cell 1 face 1 uses vertex id 9, outside [0, 8)");
  s = cube();
  s[7] = -3;
  CHECK_THAT(error_of(classic(s)), Catch::StartsWith("poly.vtk:8: CELLS: polyhedron cell 0 face 1 uses vertex id"));
  s = cube();
  s.erase(s.begin() + 6, s.begin() + 11);  // no top face
  s[0] = 5;
  CHECK_THAT(error_of(classic(s)), Catch::StartsWith("poly.vtk:8: CELLS: polyhedron cell 0 does not close"));
  CHECK_THAT(error_of(offsets(s)), Catch::StartsWith("poly.vtk:12: CONNECTIVITY: polyhedron cell 1 does not close"));
  // Too short to be a polyhedron at all: build_cells' vertex count check.
  CHECK(error_of(classic({4, 3, 0})) == "poly.vtk:8: cell 0 (polyhedron) has 3 vertex ids, needs at least 4");
  CHECK_THAT(error_of(classic({})), Catch::Contains("cell 0 (polyhedron) has 0 vertex ids, needs at least 4"));
  // Every prefix of a well-formed file fails cleanly or reads (never over-reads).
  std::string const whole = offsets(cube());
  for (size_t n = 0; n < whole.size(); ++n) {
    try {
      read_vtk_legacy_from_memory(whole.substr(0, n), "cut.vtk");
    } catch (IoError const&) {
    }
  }
}

TEST_CASE("legacy binary polyhedra: errors give the byte of the cell's face stream", "[io][polyhedra][legacy]") {
  std::string d = bytes_of(file("two_polyhedra_51b.vtk"));
  // CONNECTIVITY is Int64, big-endian: polyhedron 0's face 1 vertex 3
  // (stream entry 10, "4 4 5 6 7") becomes 99.
  size_t const conn = d.find("CONNECTIVITY vtktypeint64\n");
  REQUIRE(conn != std::string::npos);
  size_t const start = conn + std::string("CONNECTIVITY vtktypeint64\n").size();
  REQUIRE(static_cast<unsigned char>(d[start + 8 * 10 + 7]) == 7);
  d[start + 8 * 10 + 7] = char(99);
  CHECK(error_of(d, "two.vtk") == "two.vtk: byte " + std::to_string(start) +
                                      ": CONNECTIVITY: polyhedron cell 0 face 1 uses vertex id 99, outside [0, 18)");
  d = bytes_of(file("two_polyhedra_42b.vtk"));
  size_t const cells = d.find("CELLS 2 71\n");
  REQUIRE(cells != std::string::npos);
  size_t const first = cells + std::string("CELLS 2 71\n").size();  // Int32: count 31, then the stream
  size_t const second = first + 4 * 32;                              // cell 1: count 38, then its stream
  d[second + 4 + 3] = char(3);                                        // declares 3 faces
  CHECK(error_of(d, "two.vtk") == "two.vtk: byte " + std::to_string(second + 4) + ": CELLS: polyhedron cell 1 declares 3 faces");
}

}  // namespace test_io_polyhedra
