// The BVH on real meshes (the repository's copies of ../shared/data files in
// tests/data/real, read with the io readers):
// every builder checked against the brute-force oracle, refits between the
// files' own point arrays, and one BVH over two files as pieces.

#include <catch2/catch.hpp>

#include <string>

#include <cellray/bvh/bvh.hpp>
#include <cellray/io/read_mesh.hpp>

#include "support/test_data.hpp"
#include "test_bvh_oracle.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_bvh_real {

using namespace cellray;
using namespace cellray::test;

namespace {

UnstructuredGrid read(std::string const& rel, bool skip_other_cells = false) {
  ReadOptions o;
  o.skip_unsupported_cells = skip_other_cells;
  return read_mesh(real_file(rel), o);
}

}  // namespace

TEST_CASE("real tet mesh: post.vtk (8,750 tets, CFD pressure)", "[bvh][data]") {
  auto const grid = read("vtk-data/post.vtk");
  TetMesh const mesh = grid.tet_mesh();
  REQUIRE(mesh.cell_count() == 8750);
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    MinMaxBvh bvh = build_minmax_bvh(mesh, with(b));
    check_bvh(bvh, {MeshPiece(mesh)}, 7);
    CHECK(bvh_stats(bvh).bytes_per_cell <= 24.0);
  }
}

TEST_CASE("real hex mesh: disk_out_ref.vtu (7,472 hexes), refit between its point arrays", "[bvh][data]") {
  auto const grid = read("vtk-data/disk_out_ref.vtu");
  HexMesh const temp = grid.hex_mesh().with_array("Temp");
  HexMesh const pres = grid.hex_mesh().with_array("Pres");
  REQUIRE(temp.cell_count() == 7472);
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    MinMaxBvh bvh = build_minmax_bvh(temp, with(b));
    check_bvh(bvh, {MeshPiece(temp)}, 7);
    ValueRanges const r = refit_ranges(bvh, pres);
    check_bvh(bvh, {MeshPiece(pres)}, 7, &r);
    CHECK(r == build_minmax_bvh(pres, with(b)).ranges());
    CHECK(bvh_stats(bvh).bytes_per_cell <= 24.0);
  }
}

TEST_CASE("real meshes: 84k-tet machine part, flange hexes and wedges (collapsed hexes), two files as pieces", "[bvh][data]") {
  auto const part = read("openfoam/component8_heat_84k.vtk");
  auto const flange = read("openfoam/flange_heat.vtk");
  TetMesh const tets = part.tet_mesh();
  HexMesh const hexes = flange.hex_mesh();
  REQUIRE(tets.cell_count() == 84438);
  REQUIRE(hexes.cell_count() == 5340 + 372);
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    check_bvh(build_minmax_bvh(tets, with(b)), {MeshPiece(tets)}, 7);
    check_bvh(build_minmax_bvh(hexes, with(b)), {MeshPiece(hexes)}, 7);
    MinMaxBvh both = build_minmax_bvh({tets, hexes}, with(b));
    check_bvh(both, {MeshPiece(tets), MeshPiece(hexes)}, 7);
    CHECK(refit_ranges(both, {tets, hexes}) == both.ranges());
  }
}

}  // namespace test_bvh_real
