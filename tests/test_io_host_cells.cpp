// split_vtk_cells (io/vtk_host_cells.hpp): a host's cells in VTK 9's layout
// must split into the same tet and hex index arrays the legacy reader makes
// of the same cells written as a VTK 5.1 file (an independent path through
// text), with each cell's host id; bad arrays are an InvalidMesh naming the
// cell. A host's polyhedra (faces in VTK 9.0's or 9.4's layout) split as the
// VTU reader splits the same file's.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include <pugixml.hpp>

#include <cellray/io/read_mesh.hpp>
#include <cellray/io/vtk_host_cells.hpp>
#include <cellray/io/vtk_legacy.hpp>

namespace test_io_host_cells {

using namespace cellray;

namespace {

/// Cells of every kind the split handles, over 14 points: a tetrahedron, a
/// hexahedron, a triangle (2D: unsupported), a wedge, a pyramid, a
/// quadratic tetrahedron (kept as its corners) and a voxel.
struct HostCells {
  std::vector<uint8_t> types = {10, 12, 5, 13, 14, 24, 11};
  std::vector<int64_t> offsets;
  std::vector<int64_t> connectivity;
  uint64_t points = 14;
  HostCells() {
    std::vector<std::vector<int64_t>> const cells = {{0, 1, 2, 3},
                                                     {0, 1, 2, 3, 4, 5, 6, 7},
                                                     {0, 1, 2},
                                                     {8, 9, 10, 11, 12, 13},
                                                     {0, 1, 2, 3, 8},
                                                     {4, 5, 6, 7, 8, 9, 10, 11, 12, 13},
                                                     {13, 12, 11, 10, 9, 8, 7, 6}};
    offsets.push_back(0);
    for (auto const& c : cells) {
      connectivity.insert(connectivity.end(), c.begin(), c.end());
      offsets.push_back(int64_t(connectivity.size()));
    }
  }
  /// The same cells as a legacy VTK 5.1 ASCII file (OFFSETS / CONNECTIVITY).
  std::string as_legacy() const {
    std::ostringstream s;
    s << "# vtk DataFile Version 5.1\nhost cells\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS " << points << " float\n";
    for (uint64_t i = 0; i < points; ++i) s << float(i % 3) << " " << float(i / 3 % 3) << " " << float(i / 9) << "\n";
    s << "CELLS " << offsets.size() << " " << connectivity.size() << "\nOFFSETS vtktypeint64\n";
    for (auto o : offsets) s << o << " ";
    s << "\nCONNECTIVITY vtktypeint64\n";
    for (auto c : connectivity) s << c << " ";
    s << "\nCELL_TYPES " << types.size() << "\n";
    for (auto t : types) s << int(t) << "\n";
    return s.str();
  }
};

}  // namespace

TEST_CASE("split_vtk_cells splits mixed cells as the legacy reader splits the same file", "[io][host]") {
  HostCells const h;
  ReadOptions skip;
  skip.skip_unsupported_cells = true;
  CHECK_THROWS_WITH(split_vtk_cells(view(h.types), view(h.offsets), view(h.connectivity), h.points),
                    Catch::Contains("split_vtk_cells: cell 2: unsupported cells: 1 triangle (VTK type 5)"));
  SplitCells const s = split_vtk_cells(view(h.types), view(h.offsets), view(h.connectivity), h.points, skip);
  UnstructuredGrid const g = read_vtk_legacy_from_memory(h.as_legacy(), "host.vtk", skip);
  CHECK(s.tets == g.tets);
  CHECK(s.hexes == g.hexes);
  CHECK(s.tets.size() == 2 * 4);
  CHECK(s.hexes.size() == 4 * 8);
  CHECK(s.tet_cells == std::vector<uint64_t>{0, 5});
  CHECK(s.hex_cells == std::vector<uint64_t>{1, 3, 4, 6});
  // The reader names the same cells by their file ids.
  CHECK(std::vector<uint64_t>(g.tet_file_cells.begin(), g.tet_file_cells.end()) == s.tet_cells);
  CHECK(std::vector<uint64_t>(g.hex_file_cells.begin(), g.hex_file_cells.end()) == s.hex_cells);
  CHECK(s.report.cells_read == g.report.cells_read);
  CHECK(s.report.skipped_count() == 1);
  CHECK(s.report.reduced_to_linear == 2);  // the quadratic tetrahedron and the voxel

  // Narrower host types give the same split.
  std::vector<int32_t> const off32(h.offsets.begin(), h.offsets.end()), conn32(h.connectivity.begin(), h.connectivity.end());
  std::vector<uint32_t> const types32(h.types.begin(), h.types.end());
  SplitCells const n = split_vtk_cells(view(types32), view(off32), view(conn32), h.points, skip);
  CHECK(n.tets == s.tets);
  CHECK(n.hexes == s.hexes);
}

TEST_CASE("split_vtk_cells of tetrahedra only is their connectivity: a view of it copies nothing", "[io][host]") {
  std::vector<uint8_t> const types(3, 10);
  std::vector<int64_t> const offsets = {0, 4, 8, 12};
  std::vector<uint32_t> const conn = {0, 1, 2, 3, 1, 2, 3, 4, 2, 3, 4, 5};
  SplitCells const s = split_vtk_cells(view(types), view(offsets), view(conn), 6);
  CHECK(s.tets == conn);
  CHECK(s.hexes.empty());
  CHECK(s.tet_cells == std::vector<uint64_t>{0, 1, 2});
}

TEST_CASE("split_vtk_cells: bad host arrays are InvalidMesh naming the cell", "[io][host]") {
  std::vector<uint8_t> const types = {10, 13};
  std::vector<int64_t> const conn = {0, 1, 2, 3, 0, 1, 2, 3, 4, 5};
  auto split = [&](std::vector<int64_t> const& offsets, std::vector<int64_t> const& c, uint64_t points = 6,
                   std::vector<uint8_t> const& t = {10, 13}) {
    return split_vtk_cells(view(t), view(offsets), view(c), points);
  };
  CHECK_NOTHROW(split({0, 4, 10}, conn));
  CHECK_THROWS_WITH(split({0, 4}, conn), Catch::Contains("2 cell types need 3 offsets, got 2"));
  CHECK_THROWS_WITH(split({0, 4, 11}, conn), Catch::Contains("cell 1: offsets [4, 11) do not lie in the connectivity's 10 ids"));
  CHECK_THROWS_WITH(split({4, 0, 10}, conn), Catch::Contains("cell 0: offsets [4, 0)"));
  CHECK_THROWS_WITH(split({0, 4, 9}, conn), Catch::Contains("cell 1 (wedge) has 5 vertex ids, needs 6"));
  CHECK_THROWS_WITH(split({0, 4, 10}, conn, 5), Catch::Contains("cell 1 uses vertex id 5, outside [0, 5)"));
  CHECK_THROWS_WITH(split({0, 4, 10}, conn, 6, {10, 99}), Catch::Contains("cell 1 has unknown VTK cell type 99"));
  CHECK_THROWS_WITH(split({0, 4, 10}, {0, 1, 2, 3, 0, 0, 0, 1, 1, 1}),
                    Catch::Contains("cell 1 (wedge) has 2 distinct vertices"));
  CHECK_THROWS_AS(split({0, 4, 10}, conn, 5), InvalidMesh);
}

namespace {

/// An ASCII DataArray of a .vtu, by name, parsed here (not by the reader).
template <class T> std::vector<T> vtu_array(pugi::xml_document const& doc, char const* name) {
  pugi::xpath_node const n = doc.select_node((std::string("//DataArray[@Name='") + name + "']").c_str());
  REQUIRE(n);
  std::istringstream in(n.node().child_value());
  std::vector<T> out;
  double v;
  while (in >> v) out.push_back(T(v));
  return out;
}

/// tests/data/polyhedra/mixed_polyhedra.vtu's arrays as a host holds them:
/// cells in VTK 9's layout, faces in VTK 9.0's (a stream and each cell's
/// start) and 9.4's (every face's points, each cell's faces).
struct HostPolyhedra {
  std::vector<uint8_t> types;
  std::vector<int64_t> offsets{0}, connectivity, stream, locations;
  std::vector<float> points, point_t, cell_t;
  std::vector<int64_t> face_offsets{0}, face_points, cell_face_offsets{0}, cell_faces;
  explicit HostPolyhedra(std::string const& path) {
    pugi::xml_document doc;
    REQUIRE(doc.load_file(path.c_str()));
    types = vtu_array<uint8_t>(doc, "types");
    for (int64_t o : vtu_array<int64_t>(doc, "offsets")) offsets.push_back(o);
    connectivity = vtu_array<int64_t>(doc, "connectivity");
    points = vtu_array<float>(doc, "Points");
    pugi::xpath_node_set const t = doc.select_nodes("//DataArray[@Name='T']");
    REQUIRE(t.size() == 2);
    for (int a = 0; a < 2; ++a) {
      std::istringstream in(t[size_t(a)].node().child_value());
      float v;
      while (in >> v) (a == 0 ? point_t : cell_t).push_back(v);
    }
    stream = vtu_array<int64_t>(doc, "faces");
    int64_t start = 0;  // a .vtu's faceoffsets are where each stream ends
    for (int64_t end : vtu_array<int64_t>(doc, "faceoffsets")) {
      locations.push_back(end < 0 ? -1 : start);
      if (end >= 0) start = end;
    }
    for (int64_t at : locations) {
      if (at >= 0) {
        auto i = uint64_t(at);
        int64_t const nfaces = stream[i++];
        for (int64_t f = 0; f < nfaces; ++f) {
          int64_t const n = stream[i++];
          for (int64_t q = 0; q < n; ++q) face_points.push_back(stream[i++]);
          face_offsets.push_back(int64_t(face_points.size()));
          cell_faces.push_back(int64_t(face_offsets.size()) - 2);
        }
      }
      cell_face_offsets.push_back(int64_t(cell_faces.size()));
    }
  }
  uint64_t point_count() const { return points.size() / 3; }
  FaceStreams<int64_t, int64_t> streams() const { return {view(locations), view(stream)}; }
  FaceCellArrays<int64_t, int64_t, int64_t, int64_t> cell_arrays() const {
    return {view(face_offsets), view(face_points), view(cell_face_offsets), view(cell_faces)};
  }
  /// Each polyhedron's distinct points, from its face stream.
  std::vector<std::vector<int64_t>> polyhedron_points() const {
    std::vector<std::vector<int64_t>> out;
    for (int64_t at : locations) {
      if (at < 0) continue;
      std::vector<int64_t> ids;
      auto i = uint64_t(at);
      int64_t const nfaces = stream[i++];
      for (int64_t f = 0; f < nfaces; ++f) {
        int64_t const n = stream[i++];
        for (int64_t q = 0; q < n; ++q) ids.push_back(stream[i++]);
      }
      std::sort(ids.begin(), ids.end());
      ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
      out.push_back(ids);
    }
    return out;
  }
};

}  // namespace

TEST_CASE("split_vtk_cells splits a host's polyhedra as the .vtu reader splits the same file's", "[io][host][polyhedra]") {
  std::string const path = std::string(CELLRAY_TEST_DATA) + "/polyhedra/mixed_polyhedra.vtu";
  HostPolyhedra const h(path);
  UnstructuredGrid const g = read_mesh(path);
  REQUIRE(g.report.polyhedra_split == 2);
  uint64_t const np = h.point_count();

  SplitCells const s = split_vtk_cells(view(h.types), view(h.offsets), view(h.connectivity), view(h.points), h.streams());
  CHECK(s.tets == g.tets);
  CHECK(s.hexes == g.hexes);
  CHECK(s.point_count == np);
  CHECK(s.polyhedron_cells.size() == 2);
  CHECK(s.report.polyhedra_split == 2);
  CHECK(s.report.polyhedron_tets == g.report.polyhedron_tets);
  CHECK(s.report.polyhedron_pyramids == g.report.polyhedron_pyramids);
  // The centres are the reader's added points.
  CHECK(s.centres == std::vector<float>(g.xyz.begin() + long(3 * np), g.xyz.end()));
  for (uint64_t k = 0; k < s.polyhedron_cells.size(); ++k) CHECK(h.types[s.polyhedron_cells[k]] == 42);
  // Every cell's host cell, polyhedra's pieces included: its cell value is
  // the one the reader gave it.
  CellArray const* ct = g.cell_array("T");
  REQUIRE(ct);
  REQUIRE(s.tet_cells.size() == ct->tet_values.size());
  REQUIRE(s.hex_cells.size() == ct->hex_values.size());
  for (size_t i = 0; i < s.tet_cells.size(); ++i) CHECK(h.cell_t[s.tet_cells[i]] == ct->tet_values[i]);
  for (size_t i = 0; i < s.hex_cells.size(); ++i) CHECK(h.cell_t[s.hex_cells[i]] == ct->hex_values[i]);

  // Centre values: the polyhedron's own where the host has it per cell (as
  // the reader, whose file has a cell array T) ...
  std::vector<float> const own = polyhedron_centre_values(s, view(h.point_t), view(h.cell_t));
  PointArray const* pt = g.point_array("T");
  REQUIRE(pt);
  CHECK(own == std::vector<float>(pt->values.begin() + long(np), pt->values.end()));
  // ... else the mean of its distinct points.
  std::vector<float> const mean = polyhedron_centre_values(s, view(h.point_t));
  auto const pts = h.polyhedron_points();
  REQUIRE(pts.size() == mean.size());
  for (size_t k = 0; k < pts.size(); ++k) {
    double sum = 0;
    for (int64_t v : pts[k]) sum += double(h.point_t[uint64_t(v)]);
    CHECK(mean[k] == Approx(sum / double(pts[k].size())).epsilon(1e-6));
    CHECK(mean[k] != own[k]);  // the file's cell values differ from the means
  }

  // Many polyhedra: the means are computed in blocks, each finding its
  // first pieces on its own. The host's cells repeated 300 times over the
  // same points: polyhedron k is the file's polyhedron k % 2 again.
  HostPolyhedra many = h;
  int64_t const ncells = int64_t(h.types.size()), nconn = int64_t(h.connectivity.size());
  int64_t const nstream = int64_t(h.stream.size());
  for (int64_t r = 1; r < 300; ++r) {
    for (int64_t c = 0; c < ncells; ++c) {
      many.types.push_back(h.types[uint64_t(c)]);
      many.offsets.push_back(h.offsets[uint64_t(c + 1)] + r * nconn);
      many.locations.push_back(h.locations[uint64_t(c)] < 0 ? -1 : h.locations[uint64_t(c)] + r * nstream);
    }
    many.connectivity.insert(many.connectivity.end(), h.connectivity.begin(), h.connectivity.end());
    many.stream.insert(many.stream.end(), h.stream.begin(), h.stream.end());
  }
  SplitCells const sm =
      split_vtk_cells(view(many.types), view(many.offsets), view(many.connectivity), view(many.points), many.streams());
  std::vector<float> const many_means = polyhedron_centre_values(sm, view(h.point_t));
  REQUIRE(many_means.size() == 600);
  for (size_t k = 0; k < many_means.size(); ++k) CHECK(many_means[k] == mean[k % 2]);

  // VTK 9.4's layout splits the same.
  SplitCells const s94 =
      split_vtk_cells(view(h.types), view(h.offsets), view(h.connectivity), view(h.points), h.cell_arrays());
  CHECK(s94.tets == s.tets);
  CHECK(s94.hexes == s.hexes);
  CHECK(s94.centres == s.centres);
  CHECK(s94.tet_cells == s.tet_cells);
  CHECK(s94.hex_cells == s.hex_cells);

  // Without faces a polyhedron is unsupported (or a counted skip).
  CHECK_THROWS_WITH(split_vtk_cells(view(h.types), view(h.offsets), view(h.connectivity), np),
                    Catch::Contains("polyhedron (VTK type 42)"));
  ReadOptions skip;
  skip.skip_unsupported_cells = true;
  SplitCells const none = split_vtk_cells(view(h.types), view(h.offsets), view(h.connectivity), np, skip);
  CHECK(none.report.skipped_count() == 2);
  CHECK(none.centres.empty());
  CHECK(none.tets.size() < s.tets.size());
}

TEST_CASE("split_vtk_cells: a host's bad polyhedron faces are InvalidMesh naming the cell", "[io][host][polyhedra]") {
  HostPolyhedra const h(std::string(CELLRAY_TEST_DATA) + "/polyhedra/mixed_polyhedra.vtu");
  uint64_t const poly = uint64_t(std::find(h.types.begin(), h.types.end(), 42) - h.types.begin());
  std::string const cell = "polyhedron cell " + std::to_string(poly);
  auto split = [&](HostPolyhedra const& x) {
    return split_vtk_cells(view(x.types), view(x.offsets), view(x.connectivity), view(x.points), x.streams());
  };
  auto split94 = [&](HostPolyhedra const& x) {
    return split_vtk_cells(view(x.types), view(x.offsets), view(x.connectivity), view(x.points), x.cell_arrays());
  };
  CHECK_NOTHROW(split(h));
  {
    HostPolyhedra x = h;
    x.locations[poly] = -1;
    CHECK_THROWS_WITH(split(x), Catch::Contains(cell + " has face location -1"));
    x.locations[poly] = int64_t(x.stream.size());
    CHECK_THROWS_WITH(split(x), Catch::Contains(cell + " has face location"));
    x = h;
    x.locations.pop_back();
    CHECK_THROWS_WITH(split(x), Catch::Contains("face locations"));
  }
  {
    HostPolyhedra x = h;  // a point id past the points, in the stream and in the face points
    auto const at = uint64_t(x.locations[poly]) + 2;
    x.stream[at] = int64_t(h.point_count()) + 5;
    CHECK_THROWS_AS(split(x), InvalidMesh);
    CHECK_THROWS_WITH(split(x), Catch::Contains(cell));
    x = h;
    x.face_points[uint64_t(x.face_offsets[uint64_t(x.cell_faces[uint64_t(x.cell_face_offsets[poly])])])] =
        int64_t(h.point_count()) + 5;
    CHECK_THROWS_WITH(split94(x), Catch::Contains(cell));
  }
  {
    HostPolyhedra x = h;  // faces that do not close: one face's point moved to another point
    auto const at = uint64_t(x.locations[poly]) + 2;
    x.stream[at] = x.stream[at + 1];
    CHECK_THROWS_WITH(split(x), Catch::Contains(cell));
    x = h;  // a face id that is no face
    x.cell_faces[uint64_t(x.cell_face_offsets[poly])] = int64_t(x.face_offsets.size());
    CHECK_THROWS_WITH(split94(x), Catch::Contains(cell + " names face"));
    x = h;
    x.cell_face_offsets.pop_back();
    CHECK_THROWS_WITH(split94(x), Catch::Contains("cell face offsets"));
  }
  {
    HostPolyhedra x = h;  // points that are not 3 per point
    x.points.pop_back();
    CHECK_THROWS_WITH(split(x), Catch::Contains("coordinates"));
  }
}

}  // namespace test_io_host_cells
