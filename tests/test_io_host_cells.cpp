// split_vtk_cells (io/vtk_host_cells.hpp): a host's cells in VTK 9's layout
// must split into the same tet and hex index arrays the legacy reader makes
// of the same cells written as a VTK 5.1 file (an independent path through
// text), with each cell's host id; bad arrays are an InvalidMesh naming the
// cell.

#include <catch2/catch.hpp>

#include <cstdint>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

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

}  // namespace test_io_host_cells
