#pragma once
// What a built BVH looks like: sizes, depth, leaf sizes, SAH cost, bytes.

#include <cstdint>
#include <iomanip>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include "build_common.hpp"
#include "node.hpp"

namespace cellray {

/// Statistics of one MinMaxBvh. Bytes count what the tree owns for one time
/// step: nodes + item list + one ValueRanges.
struct BvhStats {
  BvhBuilder builder = BvhBuilder::binned_sah;
  uint64_t items = 0;
  uint64_t nodes = 0;
  uint64_t leaves = 0;
  uint32_t max_depth = 0;          ///< deepest leaf, root = 0
  double mean_leaf_depth = 0;      ///< over leaves, unweighted
  double mean_leaf_items = 0;      ///< items / leaves
  std::vector<uint64_t> leaf_size_histogram;  ///< [k] = number of leaves with k items
  SahCosts costs;                  ///< the constants `sah_cost` uses
  /// Expected cost of a ray through the root (MacDonald & Booth):
  /// sum over inner nodes of traversal * A(n)/A(root) + sum over leaves of
  /// item * items(n) * A(n)/A(root), A = box surface area.
  double sah_cost = 0;
  uint64_t node_bytes = 0;         ///< 32 per node
  uint64_t range_bytes = 0;        ///< 8 per node (one ValueRanges)
  uint64_t item_bytes = 0;         ///< 4 or 8 per item
  double bytes_per_cell = 0;       ///< (node + range + item bytes) / items
  double build_ms = 0;

  /// Multi-line human-readable summary.
  std::string to_string() const {
    std::ostringstream s;
    s << std::fixed << std::setprecision(2);
    s << builder_name(builder) << ": " << items << " items, " << nodes << " nodes, " << leaves << " leaves\n"
      << "  depth max " << max_depth << ", mean leaf depth " << mean_leaf_depth << ", mean leaf size "
      << mean_leaf_items << "\n  leaf sizes:";
    for (size_t k = 0; k < leaf_size_histogram.size(); ++k)
      if (leaf_size_histogram[k]) s << " " << k << ":" << leaf_size_histogram[k];
    s << "\n  SAH cost " << sah_cost << " (traversal " << costs.traversal << ", item " << costs.item << ")\n"
      << "  bytes: nodes " << node_bytes << " + ranges " << range_bytes << " + items " << item_bytes << " = "
      << bytes_per_cell << " B/cell\n  build " << build_ms << " ms";
    return s.str();
  }
  friend std::ostream& operator<<(std::ostream& os, BvhStats const& st) { return os << st.to_string(); }
};

/// Walks the tree once (sequential, O(nodes)).
inline BvhStats bvh_stats(MinMaxBvh const& bvh, SahCosts costs = {}) {
  BvhStats st;
  st.builder = bvh.builder();
  st.items = bvh.item_count();
  st.nodes = bvh.node_count();
  st.costs = costs;
  st.node_bytes = st.nodes * sizeof(Node);
  st.range_bytes = bvh.ranges().bytes();
  st.item_bytes = st.items * (bvh.wide_items() ? 8 : 4);
  st.bytes_per_cell = st.items ? double(st.node_bytes + st.range_bytes + st.item_bytes) / double(st.items) : 0.0;
  st.build_ms = bvh.build_seconds() * 1e3;

  auto area = [&](Node const& n) {
    detail::Box3 b;
    b.grow(n.lo, n.hi);
    return double(b.half_area());
  };
  double const root_area = area(bvh.root());
  struct Entry {
    uint64_t node;
    uint32_t depth;
  };
  std::vector<Entry> stack{{0, 0}};
  double depth_sum = 0;
  while (!stack.empty()) {
    Entry const e = stack.back();
    stack.pop_back();
    Node const& n = bvh.node(e.node);
    double const p = root_area > 0 ? area(n) / root_area : 1.0;
    if (n.is_leaf()) {
      ++st.leaves;
      depth_sum += e.depth;
      st.max_depth = std::max(st.max_depth, e.depth);
      uint32_t const k = n.item_count();
      if (st.leaf_size_histogram.size() <= k) st.leaf_size_histogram.resize(k + 1, 0);
      ++st.leaf_size_histogram[k];
      st.sah_cost += double(costs.item) * k * p;
    } else {
      st.sah_cost += double(costs.traversal) * p;
      stack.push_back({n.right(), e.depth + 1});
      stack.push_back({n.left(), e.depth + 1});
    }
  }
  st.mean_leaf_depth = st.leaves ? depth_sum / double(st.leaves) : 0.0;
  st.mean_leaf_items = st.leaves ? double(st.items) / double(st.leaves) : 0.0;
  return st;
}

}  // namespace cellray
