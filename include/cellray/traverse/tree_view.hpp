#pragma once
// What the traversals read of a min-max BVH: raw pointers, no ownership.
// Built from a MinMaxBvh and the ValueRanges of the scalar array in use
// (bvh/), so one tree serves any time step.

#include <cstdint>
#include <limits>

#include "../bvh/node.hpp"
#include "../cells/queries.hpp"

namespace cellray {

/// The pointers a traversal reads: the tree's nodes and item list and the
/// value ranges of the scalar array being rendered (any ValueRanges of the
/// tree: time steps share the tree). Item-list slots must fit 31 bits.
struct TreeView {
  Node const* nodes = nullptr;
  float const* ranges = nullptr;  ///< 2 floats per node: vmin, vmax (empty: vmin > vmax)
  uint32_t const* items32 = nullptr;
  uint64_t const* items64 = nullptr;
  uint64_t node_count = 0;

  TreeView() = default;
  TreeView(MinMaxBvh const& bvh, ValueRanges const& r)
      : nodes(bvh.nodes()),
        ranges(&r.data()->vmin),
        items32(bvh.items32()),
        items64(bvh.items64()),
        node_count(bvh.empty() ? 0 : bvh.node_count()) {
    if (r.size() != bvh.node_count()) throw InvalidArgument("value ranges do not belong to this BVH");
    if (bvh.item_count() >= (uint64_t(1) << 31))
      throw InvalidArgument("traversal supports up to 2^31 - 1 cells per BVH");
  }
  explicit TreeView(MinMaxBvh const& bvh) : TreeView(bvh, bvh.ranges()) {}

  bool empty() const { return node_count == 0; }
  uint64_t item(uint64_t i) const { return items32 ? uint64_t(items32[i]) : items64[i]; }
};

/// Up to 8 isovalues tested in one traversal (Rathke 2015 §6.1).
struct IsoSet {
  static constexpr int max_count = 8;
  float values[max_count] = {};
  int count = 0;

  bool overlaps(float vmin, float vmax) const {
    for (int k = 0; k < count; ++k)
      if (values[k] >= vmin && values[k] <= vmax) return true;
    return false;
  }
};

/// Value intervals a sampling traversal may skip outside of: a subtree whose
/// range [vmin, vmax] overlaps none of them holds nothing visible (e.g. the
/// transfer function is transparent there: empty-space skipping).
struct ValueWindows {
  static constexpr int max_count = 16;
  float lo[max_count] = {-std::numeric_limits<float>::infinity()};
  float hi[max_count] = {std::numeric_limits<float>::infinity()};
  int count = 1;  ///< default: everything

  bool overlaps(float vmin, float vmax) const {
    for (int k = 0; k < count; ++k)
      if (vmin <= hi[k] && vmax >= lo[k]) return true;
    return false;
  }
};

}  // namespace cellray
