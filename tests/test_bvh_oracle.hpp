#pragma once
// Oracle for the BVH tests: per-cell boxes and ranges by brute force from
// the mesh arrays, and a full structural check of a MinMaxBvh against them.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <vector>

#include <cellray/bvh/bvh.hpp>

namespace cellray::test {

/// Build options for `b` with leaves of at most `leaf` cells.
inline BuildOptions with(BvhBuilder b, uint32_t leaf = 7) {
  BuildOptions o;
  o.builder = b;
  o.max_leaf_size = leaf;
  return o;
}

inline constexpr BvhBuilder all_builders[] = {BvhBuilder::spatial_median, BvhBuilder::binned_sah, BvhBuilder::morton};

/// Brute-force oracle: box and value range of every global item, straight
/// from the mesh arrays (NaN value anywhere in a cell: empty range).
inline std::vector<ItemBox> oracle_boxes(std::vector<MeshPiece> const& pieces) {
  std::vector<ItemBox> out;
  for (auto const& p : pieces)
    p.visit([&](auto const& mesh) {
      constexpr int N = std::decay_t<decltype(mesh)>::corners;
      for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
        float const inf = std::numeric_limits<float>::infinity();
        ItemBox b{{inf, inf, inf}, inf, {-inf, -inf, -inf}, -inf};
        bool nan = !mesh.has_values();
        for (int k = 0; k < N; ++k) {
          uint64_t const v = mesh.vertex(c, k);
          for (int d = 0; d < 3; ++d) {
            b.lo[d] = std::min(b.lo[d], mesh.positions()[3 * v + d]);
            b.hi[d] = std::max(b.hi[d], mesh.positions()[3 * v + d]);
          }
          if (mesh.has_values()) {
            float const x = mesh.value(v);
            nan = nan || std::isnan(x);
            b.vmin = std::min(b.vmin, x);
            b.vmax = std::max(b.vmax, x);
          }
        }
        if (nan) b.vmin = inf, b.vmax = -inf;
        out.push_back(b);
      }
    });
  return out;
}

/// Checks the BVH against the oracle: every item in exactly one leaf, leaves
/// cover the item list once, leaf sizes within bounds, every node reachable
/// once and within the depth bound, leaf bounds and ranges equal to the
/// union over their cells (tight), inner bounds and ranges equal to the
/// union of their children (so they contain every cell and vertex value
/// below). `ranges` replaces bvh.ranges() when given (a refit).
inline void check_bvh(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces, uint32_t max_leaf,
               ValueRanges const* ranges = nullptr) {
  std::vector<ItemBox> const truth = oracle_boxes(pieces);
  ValueRanges const& vr = ranges ? *ranges : bvh.ranges();
  REQUIRE(bvh.item_count() == truth.size());
  REQUIRE(vr.size() == bvh.node_count());
  std::vector<int> item_seen(truth.size(), 0), slot_seen(truth.size(), 0), node_seen(bvh.node_count(), 0);
  struct Entry {
    uint64_t node;
    uint32_t depth;
  };
  std::vector<Entry> stack{{0, 0}};
  uint32_t max_depth = 0;
  bool ok = true;
  auto fail = [&](char const* what, uint64_t node) {
    if (ok) FAIL_CHECK(what << " at node " << node);
    ok = false;
  };
  while (!stack.empty()) {
    Entry const e = stack.back();
    stack.pop_back();
    if (e.node >= bvh.node_count()) {
      fail("child index out of range", e.node);
      continue;
    }
    if (node_seen[e.node]++) fail("node reached twice", e.node);
    max_depth = std::max(max_depth, e.depth);
    Node const& n = bvh.node(e.node);
    if (n.is_leaf()) {
      if (n.item_count() < 1 || n.item_count() > max_leaf) fail("leaf size out of range", e.node);
      float const inf = std::numeric_limits<float>::infinity();
      float lo[3] = {inf, inf, inf}, hi[3] = {-inf, -inf, -inf}, vmin = inf, vmax = -inf;
      for (uint64_t s = n.first_item(); s < n.first_item() + n.item_count(); ++s) {
        if (s >= truth.size()) {
          fail("item slot out of range", e.node);
          break;
        }
        ++slot_seen[s];
        uint64_t const id = bvh.item(s);
        if (id >= truth.size()) {
          fail("item id out of range", e.node);
          break;
        }
        ++item_seen[id];
        for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], truth[id].lo[d]), hi[d] = std::max(hi[d], truth[id].hi[d]);
        vmin = std::min(vmin, truth[id].vmin);
        vmax = std::max(vmax, truth[id].vmax);
      }
      for (int d = 0; d < 3; ++d)
        if (n.lo[d] != lo[d] || n.hi[d] != hi[d]) fail("leaf bounds are not the union of its cells", e.node);
      if (vr[e.node].vmin != vmin || vr[e.node].vmax != vmax) fail("leaf range is not tight", e.node);
    } else {
      uint64_t const l = n.left(), r = n.right();
      if (r >= bvh.node_count()) {
        fail("child index out of range", e.node);
        continue;
      }
      Node const& a = bvh.node(l);
      Node const& b = bvh.node(r);
      for (int d = 0; d < 3; ++d)
        if (n.lo[d] != std::min(a.lo[d], b.lo[d]) || n.hi[d] != std::max(a.hi[d], b.hi[d]))
          fail("inner bounds are not the union of its children", e.node);
      if (vr[e.node].vmin != std::min(vr[l].vmin, vr[r].vmin) || vr[e.node].vmax != std::max(vr[l].vmax, vr[r].vmax))
        fail("inner range is not the union of its children", e.node);
      stack.push_back({l, e.depth + 1});
      stack.push_back({r, e.depth + 1});
    }
  }
  CHECK(ok);
  CHECK(std::all_of(node_seen.begin(), node_seen.end(), [](int c) { return c == 1; }));
  CHECK(std::all_of(item_seen.begin(), item_seen.end(), [](int c) { return c == 1; }));
  CHECK(std::all_of(slot_seen.begin(), slot_seen.end(), [](int c) { return c == 1; }));
  CHECK(max_depth == bvh.depth());
  CHECK(max_depth <= MinMaxBvh::max_depth);
}

}  // namespace cellray::test
