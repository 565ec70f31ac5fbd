#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include <tbb/task_arena.h>

#include <cellray/bvh/bvh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/validate.hpp>

#include "test_bvh_oracle.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_bvh_build {

using namespace cellray;
using namespace cellray::test;

namespace {

/// An owning mesh made by hand.
template <int N> struct HandMesh {
  std::vector<float> xyz, val;
  std::vector<uint32_t> idx;
  CellMesh<N> mesh() const { return CellMesh<N>{view(xyz), view(idx), view(val)}; }
};

/// A row of `nx * ny * nz` unit hexes at `origin` with spacing `h`.
HandMesh<8> hex_block(int nx, int ny, int nz, double origin, double h) {
  HandMesh<8> m;
  auto id = [&](int i, int j, int k) { return uint32_t((k * (ny + 1) + j) * (nx + 1) + i); };
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i) {
        m.xyz.insert(m.xyz.end(), {float(origin + h * i), float(origin + h * j), float(origin + h * k)});
        m.val.push_back(float(i + 2 * j + 3 * k));
      }
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        m.idx.insert(m.idx.end(), {id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k),
                                   id(i, j, k + 1), id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)});
  return m;
}

}  // namespace

TEST_CASE("every builder gives a valid min-max BVH on generated tets and hexes", "[bvh]") {
  auto const tets = generate_tets(1000, 3);
  auto const hexes = generate_hexes(1000, 4);
  for (BvhBuilder b : all_builders)
    for (uint32_t leaf : {1u, 4u, 7u, 16u}) {
      CAPTURE(builder_name(b), leaf);
      check_bvh(build_minmax_bvh(tets.mesh(), with(b, leaf)), {MeshPiece(tets.mesh())}, leaf);
      check_bvh(build_minmax_bvh(hexes.mesh(), with(b, leaf)), {MeshPiece(hexes.mesh())}, leaf);
    }
}

TEST_CASE("a larger mesh exercises the parallel partition and subtree assembly", "[bvh]") {
  auto const tets = generate_tets(70000, 5);  // > 2^15 items: parallel scans
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    check_bvh(build_minmax_bvh(tets.mesh(), with(b)), {MeshPiece(tets.mesh())}, 7);
  }
}

TEST_CASE("builds are deterministic: the same bytes with 1 thread and with all threads", "[bvh]") {
  auto const tets = generate_tets(70000, 6);
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    MinMaxBvh one;
    tbb::task_arena(1).execute([&] { one = build_minmax_bvh(tets.mesh(), with(b)); });
    MinMaxBvh all = build_minmax_bvh(tets.mesh(), with(b));
    REQUIRE(one.node_count() == all.node_count());
    CHECK(std::memcmp(one.nodes(), all.nodes(), one.node_count() * sizeof(Node)) == 0);
    REQUIRE(one.item_count() == all.item_count());
    CHECK(std::equal(one.items32(), one.items32() + one.item_count(), all.items32()));
    CHECK(one.ranges() == all.ranges());
  }
}

TEST_CASE("a refit gives exactly the ranges a rebuild gives", "[bvh]") {
  auto const tets = generate_tets(5000, 7);
  auto const hexes = generate_hexes(3000, 8);
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    {
      MinMaxBvh bvh = build_minmax_bvh(tets.mesh(), with(b));
      auto const t1 = tets.mesh().with_array("field_t1");
      ValueRanges refit = refit_ranges(bvh, t1);
      MinMaxBvh rebuilt = build_minmax_bvh(t1, with(b));
      CHECK(refit == rebuilt.ranges());
      CHECK(refit != bvh.ranges());  // the time steps differ
      check_bvh(bvh, {MeshPiece(t1)}, 7, &refit);
      refit_values(bvh, t1);  // in place
      CHECK(bvh.ranges() == rebuilt.ranges());
      // Back to t0 into reused storage.
      refit_ranges(bvh, tets.mesh(), refit);
      CHECK(refit == build_minmax_bvh(tets.mesh(), with(b)).ranges());
    }
    {
      MinMaxBvh bvh = build_minmax_bvh(hexes.mesh(), with(b));
      auto const t1 = hexes.mesh().with_array("field_t1");
      CHECK(refit_ranges(bvh, t1) == build_minmax_bvh(t1, with(b)).ranges());
    }
  }
}

TEST_CASE("refit rejects a mesh of another cell count and ranges of another size", "[bvh]") {
  auto const a = generate_tets(1000);
  auto const c = generate_tets(2000);
  MinMaxBvh bvh = build_minmax_bvh(a.mesh());
  CHECK_THROWS_AS(refit_ranges(bvh, c.mesh()), InvalidArgument);
  CHECK_THROWS_AS(bvh.set_ranges(ValueRanges(3)), InvalidArgument);
  std::vector<float> lo(5), hi(5);
  ValueRanges r;
  CHECK_THROWS_AS(refit_ranges(bvh, view(lo), view(hi), r), InvalidArgument);
}

TEST_CASE("several pieces build into one BVH whose items name piece and cell", "[bvh]") {
  auto const tets = generate_tets(2000, 9);
  auto const hexes = generate_hexes(700, 10);
  auto const t = tets.mesh();
  auto const h = hexes.mesh();
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    MinMaxBvh bvh = build_minmax_bvh({t, h}, with(b));
    REQUIRE(bvh.piece_count() == 2);
    CHECK(bvh.piece_offsets() == std::vector<uint64_t>{0, t.cell_count(), t.cell_count() + h.cell_count()});
    CHECK(bvh.locate(0).piece == 0);
    CHECK(bvh.locate(t.cell_count() - 1).cell == t.cell_count() - 1);
    CHECK(bvh.locate(t.cell_count()).piece == 1);
    CHECK(bvh.locate(t.cell_count()).cell == 0);
    check_bvh(bvh, {MeshPiece(t), MeshPiece(h)}, 7);
    auto const t1 = t.with_array("field_t1");
    auto const h1 = h.with_array("field_t1");
    CHECK(refit_ranges(bvh, {t1, h1}) == build_minmax_bvh({t1, h1}, with(b)).ranges());
    CHECK_THROWS_AS(refit_ranges(bvh, {t1}), InvalidArgument);
    CHECK_THROWS_AS(refit_ranges(bvh, {h1, t1}), InvalidArgument);
  }
}

TEST_CASE("64-bit item ids hold the same tree as 32-bit ones", "[bvh]") {
  auto const tets = generate_tets(3000, 11);
  for (BvhBuilder b : all_builders) {
    BuildOptions o = with(b);
    MinMaxBvh narrow = build_minmax_bvh(tets.mesh(), o);
    o.wide_items = true;
    MinMaxBvh wide = build_minmax_bvh(tets.mesh(), o);
    REQUIRE(wide.wide_items());
    REQUIRE(wide.items32() == nullptr);
    check_bvh(wide, {MeshPiece(tets.mesh())}, 7);
    REQUIRE(wide.node_count() == narrow.node_count());
    CHECK(std::memcmp(wide.nodes(), narrow.nodes(), wide.node_count() * sizeof(Node)) == 0);
    for (uint64_t s = 0; s < wide.item_count(); ++s) REQUIRE(wide.item(s) == narrow.item(s));
    CHECK(wide.memory_bytes() == narrow.memory_bytes() + 4 * narrow.item_count());
  }
}

TEST_CASE("leaf encoding keeps item slots beyond 2^32", "[bvh]") {
  Node n{};
  n.set_leaf((uint64_t(0xABCDEF) << 32) | 0x12345678u, 7);
  CHECK(n.is_leaf());
  CHECK(n.item_count() == 7);
  CHECK(n.first_item() == ((uint64_t(0xABCDEF) << 32) | 0x12345678u));
  n.set_leaf(0, 0);
  CHECK(n.is_leaf());
  CHECK(n.item_count() == 0);
  n.set_inner(41);
  CHECK_FALSE(n.is_leaf());
  CHECK(n.left() == 41);
  CHECK(n.right() == 42);
}

TEST_CASE("an empty mesh gives an empty BVH that no query can enter", "[bvh]") {
  std::vector<float> xyz{0, 0, 0}, val{1};
  std::vector<uint32_t> idx;
  TetMesh mesh{view(xyz), view(idx), view(val)};
  for (BvhBuilder b : all_builders) {
    MinMaxBvh bvh = build_minmax_bvh(mesh, with(b));
    CHECK(bvh.empty());
    REQUIRE(bvh.node_count() == 1);
    Node const& root = bvh.root();
    CHECK(root.is_leaf());
    CHECK(root.item_count() == 0);
    CHECK(root.lo[0] > root.hi[0]);  // empty box: every slab test misses
    CHECK(bvh.ranges()[0].vmin > bvh.ranges()[0].vmax);
    CHECK(refit_ranges(bvh, mesh) == bvh.ranges());
    CHECK(build_minmax_bvh(Span<ItemBox>{}, with(b)).empty());
  }
  MinMaxBvh def;
  CHECK(def.empty());
  CHECK(def.node_count() == 1);
}

TEST_CASE("one cell, identical cells, coplanar and collinear centroids", "[bvh]") {
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    SECTION("one cell") {
      auto m = hex_block(1, 1, 1, 0.0, 1.0);
      MinMaxBvh bvh = build_minmax_bvh(m.mesh(), with(b));
      check_bvh(bvh, {MeshPiece(m.mesh())}, 7);
      CHECK(bvh.node_count() == 1);
      CHECK(bvh.depth() == 0);
    }
    SECTION("1000 identical cells") {
      HandMesh<4> m;
      m.xyz = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
      m.val = {0, 1, 2, 3};
      for (int c = 0; c < 1000; ++c) m.idx.insert(m.idx.end(), {0, 1, 2, 3});
      MinMaxBvh bvh = build_minmax_bvh(m.mesh(), with(b));
      check_bvh(bvh, {MeshPiece(m.mesh())}, 7);
      CHECK(bvh.depth() <= 10);  // halving by count: log2(1000 / 7) + 1
    }
    SECTION("coplanar centroids (one layer of hexes)") {
      auto m = hex_block(40, 30, 1, -3.0, 0.1);
      check_bvh(build_minmax_bvh(m.mesh(), with(b)), {MeshPiece(m.mesh())}, 7);
    }
    SECTION("collinear centroids (one row of hexes)") {
      auto m = hex_block(500, 1, 1, 0.0, 1.0);
      check_bvh(build_minmax_bvh(m.mesh(), with(b)), {MeshPiece(m.mesh())}, 7);
    }
    SECTION("coordinates around 1e6") {
      auto m = hex_block(12, 10, 9, 1e6, 0.5);  // float spacing 0.0625 at 1e6: 0.5 is exact
      check_bvh(build_minmax_bvh(m.mesh(), with(b)), {MeshPiece(m.mesh())}, 7);
    }
    SECTION("coordinates around 1e-6") {
      auto m = hex_block(12, 10, 9, 1e-6, 1e-7);
      check_bvh(build_minmax_bvh(m.mesh(), with(b)), {MeshPiece(m.mesh())}, 7);
    }
  }
}

TEST_CASE("NaN or inf positions are rejected before the build, naming the cell", "[bvh]") {
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    auto m = hex_block(4, 4, 4, 0.0, 1.0);
    m.xyz[3 * 30 + 1] = bad;  // vertex 30
    CHECK_FALSE(validate(m.mesh()).ok());
    for (BvhBuilder b : all_builders) CHECK_THROWS_AS(build_minmax_bvh(m.mesh(), with(b)), InvalidMesh);
    try {
      build_minmax_bvh(m.mesh());
    } catch (InvalidMesh const& e) {
      CHECK_THAT(e.what(), Catch::Contains("cell"));
    }
    std::vector<ItemBox> boxes(3, ItemBox{{0, 0, 0}, 0, {1, 1, 1}, 1});
    boxes[2].hi.y = bad;
    CHECK_THROWS_AS(build_minmax_bvh(view(boxes)), InvalidArgument);
  }
  auto m = hex_block(2, 2, 2, 0.0, 1.0);
  m.idx[13] = 999;  // vertex id out of range
  CHECK_THROWS_AS(build_minmax_bvh(m.mesh()), InvalidMesh);
}

TEST_CASE("cells with NaN values stay in the tree with the empty range", "[bvh]") {
  auto m = hex_block(8, 8, 8, 0.0, 1.0);
  for (size_t v = 0; v < m.val.size(); v += 7) m.val[v] = std::numeric_limits<float>::quiet_NaN();
  for (BvhBuilder b : all_builders) check_bvh(build_minmax_bvh(m.mesh(), with(b)), {MeshPiece(m.mesh())}, 7);
  // A mesh without values: geometry only, every range empty.
  auto const gen = generate_tets(500);
  TetMesh bare{view(gen.xyz), view(gen.cells)};
  MinMaxBvh bvh = build_minmax_bvh(bare);
  for (uint64_t i = 0; i < bvh.node_count(); ++i) CHECK(bvh.ranges()[i].vmin > bvh.ranges()[i].vmax);
}

TEST_CASE("options outside their ranges are rejected", "[bvh]") {
  auto const tets = generate_tets(100);
  BuildOptions o;
  o.max_leaf_size = 0;
  CHECK_THROWS_AS(build_minmax_bvh(tets.mesh(), o), InvalidArgument);
  o.max_leaf_size = Node::max_leaf_items + 1;
  CHECK_THROWS_AS(build_minmax_bvh(tets.mesh(), o), InvalidArgument);
  o = {};
  o.sah_bins = 1;
  CHECK_THROWS_AS(build_minmax_bvh(tets.mesh(), o), InvalidArgument);
}

TEST_CASE("item-box builds and per-item refits", "[bvh]") {
  // Boxes on a 20^3 grid with ranges from an analytic function.
  std::vector<ItemBox> boxes;
  std::vector<float> vmin, vmax;
  for (int i = 0; i < 8000; ++i) {
    float const x = float(i % 20), y = float(i / 20 % 20), z = float(i / 400);
    boxes.push_back({{x, y, z}, x - y, {x + 1.5f, y + 1.f, z + 1.f}, x + z});
    vmin.push_back(y);
    vmax.push_back(y + z);
  }
  for (BvhBuilder b : all_builders) {
    MinMaxBvh bvh = build_minmax_bvh(view(boxes), with(b));
    std::vector<int> seen(boxes.size(), 0);
    for (uint64_t s = 0; s < bvh.item_count(); ++s) ++seen[bvh.item(s)];
    CHECK(std::all_of(seen.begin(), seen.end(), [](int c) { return c == 1; }));
    ValueRanges r;
    refit_ranges(bvh, view(vmin), view(vmax), r);
    for (uint64_t i = 0; i < bvh.node_count(); ++i) {
      Node const& n = bvh.node(i);
      if (!n.is_leaf()) continue;
      float lo = std::numeric_limits<float>::infinity(), hi = -lo, blo = lo, bhi = -lo;
      for (uint64_t s = n.first_item(); s < n.first_item() + n.item_count(); ++s) {
        lo = std::min(lo, vmin[bvh.item(s)]);
        hi = std::max(hi, vmax[bvh.item(s)]);
        blo = std::min(blo, boxes[bvh.item(s)].vmin);
        bhi = std::max(bhi, boxes[bvh.item(s)].vmax);
        for (int k = 0; k < 3; ++k) {
          CHECK(n.lo[k] <= boxes[bvh.item(s)].lo[k]);
          CHECK(n.hi[k] >= boxes[bvh.item(s)].hi[k]);
        }
      }
      CHECK(r[i].vmin == lo);
      CHECK(r[i].vmax == hi);
      CHECK(bvh.ranges()[i].vmin == blo);
      CHECK(bvh.ranges()[i].vmax == bhi);
    }
  }
}

TEST_CASE("statistics add up and stay within 24 bytes per cell at the default leaf size", "[bvh]") {
  auto const tets = generate_tets(20000, 12);
  auto const hexes = generate_hexes(20000, 13);
  for (BvhBuilder b : all_builders) {
    BvhStats const st = bvh_stats(build_minmax_bvh(tets.mesh(), with(b)));
    BvhStats const sh = bvh_stats(build_minmax_bvh(hexes.mesh(), with(b)));
    for (BvhStats const* s : {&st, &sh}) {
      CAPTURE(s->to_string());
      uint64_t leaves = 0, items = 0;
      for (size_t k = 0; k < s->leaf_size_histogram.size(); ++k)
        leaves += s->leaf_size_histogram[k], items += k * s->leaf_size_histogram[k];
      CHECK(leaves == s->leaves);
      CHECK(items == s->items);
      CHECK(s->nodes == 2 * s->leaves - 1);
      CHECK(s->leaf_size_histogram.size() <= 8);
      CHECK(s->node_bytes == 32 * s->nodes);
      CHECK(s->range_bytes == 8 * s->nodes);
      CHECK(s->item_bytes == 4 * s->items);
      CHECK(s->bytes_per_cell <= 24.0);
      // SAH cost lies between that of a perfect tree (>= item cost of one
      // leaf-sized box per cell) and that of one leaf holding everything.
      CHECK(s->sah_cost > 0.0);
      CHECK(s->sah_cost < double(s->items));
    }
  }
}

}  // namespace test_bvh_build
