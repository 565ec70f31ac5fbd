#include <catch2/catch.hpp>

#include <algorithm>
#include <limits>
#include <set>
#include <vector>

#include <cellray/bvh/bvh.hpp>
#include <cellray/mesh/generate.hpp>

#include "test_bvh_oracle.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_bvh_refit_plan {

using namespace cellray;
using namespace cellray::test;

namespace {

/// Brute force: every leaf appears once in the plan, with the sorted set of
/// its cells' corner ids, the last one marked; child() names the left child
/// of an inner node and the node itself for a leaf.
void check_plan_contents(MinMaxBvh const& bvh, RefitPlan const& plan, std::vector<MeshPiece> const& pieces) {
  REQUIRE(plan.node_count() == bvh.node_count());
  std::vector<std::vector<uint64_t>> want(bvh.node_count());
  uint64_t leaves = 0;
  bool ok = true;
  for (uint64_t i = 0; i < bvh.node_count(); ++i) {
    Node const& n = bvh.node(i);
    ok = ok && plan.child()[i] == (n.is_leaf() ? i : n.left());
    if (!n.is_leaf()) continue;
    ++leaves;
    std::set<uint64_t> set;
    for (uint64_t s = n.first_item(); s < n.first_item() + n.item_count(); ++s) {
      PieceCell const pc = bvh.locate(bvh.item(s));
      pieces[pc.piece].visit([&](auto const& mesh) {
        for (int k = 0; k < std::decay_t<decltype(mesh)>::corners; ++k)
          set.insert(plan.vertex_offsets()[pc.piece] + mesh.vertex(pc.cell, k));
      });
    }
    want[i].assign(set.begin(), set.end());
  }
  REQUIRE(plan.leaf_count() == leaves);
  std::vector<int> seen(bvh.node_count(), 0);
  uint64_t k = 0;
  for (uint64_t l = 0; l < plan.leaf_count() && ok; ++l) {
    if (l % RefitPlan::leaf_block == 0) ok = ok && plan.block_begin()[l / RefitPlan::leaf_block] == k;
    uint32_t const node = plan.leaf_node()[l];
    REQUIRE(node < bvh.node_count());
    ++seen[node];
    std::vector<uint64_t> got;  // whole chunks of 4, padded with repeats of the last id
    while (k < plan.id_count()) {
      uint32_t const raw = plan.ids()[k++];
      got.push_back(raw & ~RefitPlan::last_bit);
      if (raw & RefitPlan::last_bit) break;
    }
    ok = ok && got.size() % 4 == 0 && got.size() < want[node].size() + 4;
    ok = ok && std::is_sorted(got.begin(), got.end());
    got.erase(std::unique(got.begin(), got.end()), got.end());
    ok = ok && got == want[node];
  }
  CHECK(ok);
  CHECK(k == plan.id_count());
  for (uint64_t i = 0; i < bvh.node_count(); ++i) CHECK(seen[i] == (bvh.node(i).is_leaf() ? 1 : 0));
}

}  // namespace

TEST_CASE("a refit through a plan gives the oracle's ranges, equal to the plain refit's", "[bvh]") {
  auto const tets = generate_tets(5000, 7);
  auto const hexes = generate_hexes(3000, 8);
  for (BvhBuilder b : all_builders)
    for (uint32_t leaf : {1u, 7u, 16u}) {
      CAPTURE(builder_name(b), leaf);
      {
        MinMaxBvh const bvh = build_minmax_bvh(tets.mesh(), with(b, leaf));
        RefitPlan const plan = make_refit_plan(bvh, tets.mesh());
        check_plan_contents(bvh, plan, {MeshPiece(tets.mesh())});
        auto const t1 = tets.mesh().with_array("field_t1");
        ValueRanges r;
        refit_ranges(bvh, plan, t1, r);
        check_bvh(bvh, {MeshPiece(t1)}, leaf, &r);
        CHECK(r == refit_ranges(bvh, t1));
        refit_ranges(bvh, plan, tets.mesh(), r);  // back to t0, reused storage
        CHECK(r == bvh.ranges());
      }
      {
        MinMaxBvh const bvh = build_minmax_bvh(hexes.mesh(), with(b, leaf));
        RefitPlan const plan = make_refit_plan(bvh, hexes.mesh());
        check_plan_contents(bvh, plan, {MeshPiece(hexes.mesh())});
        auto const t1 = hexes.mesh().with_array("field_t1");
        ValueRanges r;
        refit_ranges(bvh, plan, t1, r);
        check_bvh(bvh, {MeshPiece(t1)}, leaf, &r);
        CHECK(r == refit_ranges(bvh, t1));
      }
    }
}

TEST_CASE("refit plan: a vertex shared inside a leaf is stored once", "[bvh]") {
  // 6 tets per lattice cell share its main diagonal: a leaf of 6 tets has
  // far fewer distinct vertices than 24 corners.
  auto const tets = generate_tets(20000, 3);
  MinMaxBvh const bvh = build_minmax_bvh(tets.mesh());
  RefitPlan const plan = make_refit_plan(bvh, tets.mesh());
  CHECK(plan.id_count() < 3 * bvh.item_count());       // 4 corners per tet without sharing
  CHECK(plan.id_count() >= 4 * bvh_stats(bvh).leaves);  // a leaf has at least one tet
  uint64_t const blocks = (plan.leaf_count() + RefitPlan::leaf_block - 1) / RefitPlan::leaf_block + 1;
  CHECK(plan.bytes() == 4 * (plan.id_count() + plan.leaf_count() + bvh.node_count()) + 8 * (blocks + 2 + 2));
}

TEST_CASE("refit plan: NaN values drop only their own cells, also over pieces and a piece without values", "[bvh]") {
  auto const tets = generate_tets(3000, 11);
  auto const hexes = generate_hexes(1000, 12);
  std::vector<float> nan_tets = tets.field_t1, nan_hexes = hexes.field;
  for (size_t v = 0; v < nan_tets.size(); v += 7) nan_tets[v] = std::numeric_limits<float>::quiet_NaN();
  for (size_t v = 3; v < nan_hexes.size(); v += 11) nan_hexes[v] = std::numeric_limits<float>::quiet_NaN();
  auto const t = tets.mesh();
  auto const h = hexes.mesh();
  auto const tn = t.with_values(view(nan_tets));
  auto const hn = h.with_values(view(nan_hexes));
  HexMesh const bare{view(hexes.xyz), view(hexes.cells)};
  for (BvhBuilder b : all_builders) {
    CAPTURE(builder_name(b));
    MinMaxBvh const bvh = build_minmax_bvh({t, h}, with(b));
    RefitPlan const plan = make_refit_plan(bvh, {t, h});
    check_plan_contents(bvh, plan, {MeshPiece(t), MeshPiece(h)});
    ValueRanges r;
    refit_ranges(bvh, plan, {tn, hn}, r);
    check_bvh(bvh, {MeshPiece(tn), MeshPiece(hn)}, 7, &r);
    CHECK(r == refit_ranges(bvh, {tn, hn}));
    refit_ranges(bvh, plan, {tn, bare}, r);  // the hexes have no values: empty ranges there
    check_bvh(bvh, {MeshPiece(tn), MeshPiece(bare)}, 7, &r);
    // One mesh without values: every range empty.
    MinMaxBvh const hb = build_minmax_bvh(h, with(b));
    refit_ranges(hb, make_refit_plan(hb, bare), bare, r);
    REQUIRE(r.size() == hb.node_count());
    bool all_empty = true;
    for (uint64_t i = 0; i < r.size(); ++i) all_empty = all_empty && r[i].vmin > r[i].vmax;
    CHECK(all_empty);
  }
}

TEST_CASE("refit plan: empty mesh, and plans that do not match the tree or mesh are rejected", "[bvh]") {
  std::vector<float> none;
  std::vector<uint32_t> no_cells;
  TetMesh const empty{view(none), view(no_cells)};
  MinMaxBvh const e = build_minmax_bvh(empty);
  ValueRanges r;
  refit_ranges(e, make_refit_plan(e, empty), empty, r);
  REQUIRE(r.size() == 1);
  CHECK(r[0].vmin > r[0].vmax);

  auto const a = generate_tets(1000, 1);
  auto const c = generate_tets(2000, 2);
  MinMaxBvh const bvh = build_minmax_bvh(a.mesh());
  MinMaxBvh const other = build_minmax_bvh(c.mesh());
  RefitPlan const plan = make_refit_plan(bvh, a.mesh());
  CHECK_THROWS_AS(refit_ranges(bvh, RefitPlan{}, a.mesh(), r), InvalidArgument);
  CHECK_THROWS_AS(refit_ranges(other, plan, c.mesh(), r), InvalidArgument);
  CHECK_THROWS_AS(refit_ranges(bvh, plan, c.mesh(), r), InvalidArgument);
  CHECK_THROWS_AS(make_refit_plan(bvh, c.mesh()), InvalidArgument);
  // Same cells, another vertex count (one unused vertex appended).
  std::vector<float> xyz = a.xyz, val = a.field;
  xyz.insert(xyz.end(), {0.f, 0.f, 0.f});
  val.push_back(0.f);
  TetMesh const more{view(xyz), view(a.cells), view(val)};
  CHECK_THROWS_AS(refit_ranges(bvh, plan, more, r), InvalidArgument);
}

}  // namespace test_bvh_refit_plan
