#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <vector>

#include <cellray/mesh/cell_boxes.hpp>

#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_mesh_cell_boxes {

using namespace cellray;

TEST_CASE("cell boxes and ranges match a scalar loop, NaN cells get the empty range", "[mesh][isa]") {
  // 37 tets (not a multiple of any width) over 20 vertices with a NaN value.
  std::vector<float> xyz, val;
  for (int v = 0; v < 20; ++v) {
    xyz.insert(xyz.end(), {float(v % 3) + 0.1f * v, float(v % 5) - 2.f, float(v * v % 7)});
    val.push_back(v == 13 ? std::numeric_limits<float>::quiet_NaN() : float(v) * 0.5f - 3.f);
  }
  std::vector<uint32_t> idx;
  for (uint32_t c = 0; c < 37; ++c) idx.insert(idx.end(), {c % 20, (c * 7 + 1) % 20, (c * 3 + 2) % 20, (c * 11 + 5) % 20});
  TetMesh mesh{view(xyz), view(idx), view(val)};
  std::vector<ItemBox> boxes(mesh.cell_count());
  dispatch<CellBoxes>(test::isa(), mesh, uint64_t(0), mesh.cell_count(), boxes.data());
  std::vector<float> vmin(mesh.cell_count()), vmax(mesh.cell_count());
  dispatch<CellRanges>(test::isa(), mesh, uint64_t(0), mesh.cell_count(), vmin.data(), vmax.data());
  for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f}, a = 1e30f, b = -1e30f;
    bool nan = false;
    for (int k = 0; k < 4; ++k) {
      auto v = mesh.vertex(c, k);
      for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], xyz[3 * v + d]), hi[d] = std::max(hi[d], xyz[3 * v + d]);
      nan |= std::isnan(val[v]);
      a = std::min(a, val[v]);
      b = std::max(b, val[v]);
    }
    for (int d = 0; d < 3; ++d) {
      CHECK(boxes[c].lo[d] == lo[d]);
      CHECK(boxes[c].hi[d] == hi[d]);
    }
    if (nan) {
      CHECK(boxes[c].vmin == std::numeric_limits<float>::infinity());
      CHECK(boxes[c].vmax == -std::numeric_limits<float>::infinity());
    } else {
      CHECK(boxes[c].vmin == a);
      CHECK(boxes[c].vmax == b);
    }
    CHECK(vmin[c] == boxes[c].vmin);
    CHECK(vmax[c] == boxes[c].vmax);
  }
}

}  // namespace test_mesh_cell_boxes
