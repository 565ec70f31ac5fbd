// Polyhedra in VTU files (VTK 42, `faces` / `faceoffsets`; issue #21): each
// is split around an added centre point (its volume centroid) into
// pyramids (quad faces, stored as collapsed hexahedra) and tetrahedra
// (other faces, fanned), as foamToVTK -poly-decomp does; the centre takes
// the polyhedron's value where a cell array has the point array's name,
// and the new cells carry the polyhedron's cell values. Faces that do not
// close or name points the file lacks are errors naming the cell.
// tests/data/polyhedra/make_polyhedra.py (python3-vtk9) wrote the files.

#include <catch2/catch.hpp>

#include <string>

#include <cellray/io/read_mesh.hpp>
#include <cellray/io/vtk_legacy.hpp>
#include <cellray/mesh/validate.hpp>

namespace test_io_polyhedra {

using namespace cellray;

namespace {

std::string file(char const* name) { return std::string(CELLRAY_TEST_DATA) + "/polyhedra/" + name; }

}  // namespace

TEST_CASE("polyhedra in a .vtu split into pyramids and tetrahedra around their centres", "[io][polyhedra]") {
  UnstructuredGrid const g = read_mesh(file("two_polyhedra.vtu"));
  CHECK(g.report.cells_read.at(42) == 2);
  CHECK(g.report.polyhedra_split == 2);
  // Cube: 6 quads -> 6 pyramids. Prism: 5 quads -> 5 pyramids, 2 pentagons -> 3 + 3 tets.
  CHECK(g.hex_count() == 11);
  CHECK(g.tet_count() == 6);
  CHECK(g.report.polyhedron_pyramids == 11);
  CHECK(g.report.polyhedron_tets == 6);
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
  CHECK(id->hex_values == std::vector<float>{1, 1, 1, 1, 1, 1, 2, 2, 2, 2, 2});
  CHECK(id->tet_values == std::vector<float>(6, 2.f));
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
  CHECK_THAT(g.report.summary(), Catch::Contains("2 polyhedra split into 6 tetrahedra and 11 pyramids"));
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
