#pragma once
// Build options and the machinery every builder shares: the parallel
// top-down driver, deterministic partitioning, assembly of the node array,
// and the bottom-up pass that fits bounds and value ranges.
//
// Determinism (the same tree, byte for byte, whatever the thread count):
// every decision depends on the data and on range sizes only. Reductions
// are min/max and integer sums (exact in any order); partitions of large
// ranges are stable over fixed blocks, small ones use sequential
// std::partition; subtrees are built into private buffers and laid out in a
// fixed depth-first order afterwards.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include "../mesh/cell_boxes.hpp"
#include "node.hpp"

namespace cellray {

/// Constants of the surface-area heuristic (MacDonald & Booth 1990): the
/// expected cost of a ray through a node is `traversal` per inner node it
/// visits plus `item` per item in a leaf it visits, a node being visited
/// with probability (its box surface) / (root box surface). Used by the SAH
/// builder (plane choice and termination), by the spatial-median termination
/// criterion and by `BvhStats::sah_cost`. Only the ratio matters for the
/// build. Default 3 : 1: at 1 : 1 the termination splits hexahedra (whose
/// boxes barely overlap) down to 1-2 cells per leaf, 44-48 B/cell; at 3 : 1
/// hex leaves hold about 4 cells, 21-24 B/cell, for a 1 : 1 SAH cost only 7%
/// higher (binned SAH, 200k hexes; tets are unaffected: 6 per leaf either
/// way). A node visit also streams 40 B, which the 1 : 1 model ignores.
struct SahCosts {
  float traversal = 3.f;  ///< cost of one inner-node visit (two child box tests)
  float item = 1.f;       ///< cost of one item (cell) test in a leaf
};

/// What to build and how. Defaults: binned SAH, leaves of at most 7 items
/// (the paper's bound).
struct BuildOptions {
  BvhBuilder builder = BvhBuilder::binned_sah;
  /// Largest leaf, 1..Node::max_leaf_items. Ranges above it are always split;
  /// at or below it the SAH termination criterion decides (morton: always a leaf).
  uint32_t max_leaf_size = 7;
  SahCosts sah{};
  /// Bins per axis of the SAH builder, 2..64.
  uint32_t sah_bins = 16;
  /// Store 64-bit item ids even when 32 bits would do (tests of the wide path).
  bool wide_items = false;
  /// ISA for the per-cell boxes of a mesh build; default `default_isa()`.
  std::optional<Isa> isa;
};

namespace detail {

/// Writes a built tree into a MinMaxBvh (its only writer besides set_ranges).
struct BvhAccess {
  static std::vector<Node>& nodes(MinMaxBvh& b) { return b.nodes_; }
  static ValueRanges& ranges(MinMaxBvh& b) { return b.ranges_; }
  static std::vector<uint32_t>& items32(MinMaxBvh& b) { return b.items32_; }
  static std::vector<uint64_t>& items64(MinMaxBvh& b) { return b.items64_; }
  static std::vector<uint64_t>& piece_offsets(MinMaxBvh& b) { return b.piece_offsets_; }
  static void set_info(MinMaxBvh& b, bool wide, BvhBuilder builder, uint32_t leaf, uint32_t depth) {
    b.wide_ = wide;
    b.builder_ = builder;
    b.max_leaf_size_ = leaf;
    b.depth_ = depth;
  }
  static void set_seconds(MinMaxBvh& b, double s) { b.build_seconds_ = s; }
};

inline constexpr float inf_f = std::numeric_limits<float>::infinity();

/// Ranges of at most this many items are built sequentially into a private buffer.
inline constexpr uint64_t local_build_items = 4096;
/// Ranges of at least this many items are scanned / partitioned in parallel.
inline constexpr uint64_t parallel_scan_items = uint64_t(1) << 15;
/// Past this depth the SAH and median builders split at the object median,
/// which bounds the depth by guard + log2(items) < MinMaxBvh::max_depth.
inline constexpr uint32_t depth_guard = 64;
/// Fixed block size of parallel scans (a data-independent, thread-count-independent split).
inline constexpr uint64_t scan_block = uint64_t(1) << 13;

struct Box3 {
  float lo[3] = {inf_f, inf_f, inf_f};
  float hi[3] = {-inf_f, -inf_f, -inf_f};

  void grow(float const* l, float const* h) noexcept {
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], l[k]), hi[k] = std::max(hi[k], h[k]);
  }
  void grow(Box3 const& o) noexcept { grow(o.lo, o.hi); }
  void grow(ItemBox const& b) noexcept {
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], b.lo[k]), hi[k] = std::max(hi[k], b.hi[k]);
  }
  void grow_point(float const* p) noexcept { grow(p, p); }
  /// Half the surface area; 0 for an empty or degenerate box.
  float half_area() const noexcept {
    float const dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
    if (!(dx >= 0.f && dy >= 0.f && dz >= 0.f)) return 0.f;
    return dx * dy + dy * dz + dz * dx;
  }
};

/// Centroid of an item box times two (lo + hi): halving changes no decision.
inline void centroid2(ItemBox const& b, float* c) noexcept {
  c[0] = b.lo.x + b.hi.x;
  c[1] = b.lo.y + b.hi.y;
  c[2] = b.lo.z + b.hi.z;
}

/// Bounds of the doubled centroids of items [b, e); parallel for large ranges.
template <class Index>
Box3 centroid_bounds(ItemBox const* boxes, Index const* items, uint64_t b, uint64_t e) {
  auto body = [&](uint64_t lo, uint64_t hi, Box3 acc) {
    for (uint64_t i = lo; i < hi; ++i) {
      float c[3];
      centroid2(boxes[items[i]], c);
      acc.grow_point(c);
    }
    return acc;
  };
  if (e - b < parallel_scan_items) return body(b, e, Box3{});
  return tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(b, e, scan_block), Box3{},
      [&](tbb::blocked_range<uint64_t> const& r, Box3 acc) { return body(r.begin(), r.end(), acc); },
      [](Box3 x, Box3 const& y) {
        x.grow(y);
        return x;
      });
}

/// Box of items [b, e), sequential (small ranges only).
template <class Index> Box3 item_bounds(ItemBox const* boxes, Index const* items, uint64_t b, uint64_t e) {
  Box3 box;
  for (uint64_t i = b; i < e; ++i) box.grow(boxes[items[i]]);
  return box;
}

/// A split of items [b, e): children [b, m) and [m, e) with the bounds of
/// their doubled centroids; m == e means "make a leaf".
struct Split {
  uint64_t m;
  Box3 left, right;
};

/// Reorders items[b, e) so that those whose doubled centroid satisfies
/// `goes_left(c)` come first; returns the split with both sides' centroid
/// bounds (so children never rescan for them). Large ranges: stable,
/// parallel over fixed blocks, through `scratch[b, e)`. Small ranges: an
/// in-place two-ended partition (sequential).
template <class Index, class Pred>
Split partition_items(ItemBox const* boxes, Index* items, Index* scratch, uint64_t b, uint64_t e,
                      Pred const& goes_left) {
  uint64_t const n = e - b;
  Split out{b, {}, {}};
  if (n < parallel_scan_items) {
    uint64_t i = b, j = e;  // [b, i) go left, [j, e) go right
    float c[3];
    while (true) {
      while (i < j) {
        centroid2(boxes[items[i]], c);
        if (!goes_left(c)) break;
        out.left.grow_point(c);
        ++i;
      }
      if (i == j) break;
      out.right.grow_point(c);  // items[i] goes right; find a left one behind it
      bool swapped = false;
      while (--j > i) {
        centroid2(boxes[items[j]], c);
        if (goes_left(c)) {
          out.left.grow_point(c);
          std::swap(items[i], items[j]);
          ++i;
          swapped = true;
          break;
        }
        out.right.grow_point(c);
      }
      if (!swapped) break;  // j == i: everything from i on goes right
    }
    out.m = i;
    return out;
  }
  uint64_t const blocks = (n + scan_block - 1) / scan_block;
  std::vector<uint64_t> left(blocks + 1, 0);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t k = r.begin(); k < r.end(); ++k) {
      uint64_t const lo = b + k * scan_block, hi = std::min(e, lo + scan_block);
      uint64_t cnt = 0;
      float c[3];
      for (uint64_t i = lo; i < hi; ++i) {
        centroid2(boxes[items[i]], c);
        cnt += goes_left(c) ? 1 : 0;
      }
      left[k + 1] = cnt;
    }
  });
  for (uint64_t k = 0; k < blocks; ++k) left[k + 1] += left[k];
  uint64_t const total_left = left[blocks];
  std::vector<Box3> lbox(blocks), rbox(blocks);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t k = r.begin(); k < r.end(); ++k) {
      uint64_t const lo = b + k * scan_block, hi = std::min(e, lo + scan_block);
      uint64_t l = b + left[k], g = b + total_left + (k * scan_block - left[k]);
      float c[3];
      for (uint64_t i = lo; i < hi; ++i) {
        Index const id = items[i];
        centroid2(boxes[id], c);
        if (goes_left(c)) scratch[l++] = id, lbox[k].grow_point(c);
        else scratch[g++] = id, rbox[k].grow_point(c);
      }
    }
  });
  tbb::parallel_for(tbb::blocked_range<uint64_t>(b, e, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
    std::copy(scratch + r.begin(), scratch + r.end(), items + r.begin());
  });
  for (uint64_t k = 0; k < blocks; ++k) out.left.grow(lbox[k]), out.right.grow(rbox[k]);
  out.m = b + total_left;
  return out;
}

/// Object-median split of items [b, e) along `axis` of the doubled centroids
/// (ties by id, so the order is total); sequential nth_element. Used for
/// degenerate and very deep ranges only.
template <class Index>
Split object_median_split(ItemBox const* boxes, Index* items, uint64_t b, uint64_t e, int axis) {
  uint64_t const m = b + (e - b) / 2;
  std::nth_element(items + b, items + m, items + e, [&](Index x, Index y) {
    float cx[3], cy[3];
    centroid2(boxes[x], cx);
    centroid2(boxes[y], cy);
    return cx[axis] < cy[axis] || (cx[axis] == cy[axis] && x < y);
  });
  return {m, centroid_bounds(boxes, items, b, m), centroid_bounds(boxes, items, m, e)};
}

/// A leaf, or (more than `max_leaf` items) a split in the middle keeping the
/// order: for ranges whose centroids all coincide, where no plane separates.
inline Split leaf_or_halve(uint64_t b, uint64_t e, uint32_t max_leaf, Box3 const& cb) {
  if (e - b <= max_leaf) return {e, cb, cb};
  return {b + (e - b) / 2, cb, cb};
}

/// SAH termination criterion (Rathke 2015 §5.3): does splitting `all` into
/// (l, nl) and (r, nr) cost less than one leaf? Degenerate (zero-area)
/// boxes count as hit with probability 1, so they never pay for a split.
inline bool split_pays(SahCosts const& c, Box3 const& all, Box3 const& l, uint64_t nl, Box3 const& r, uint64_t nr) {
  float const a = all.half_area();
  float const pl = a > 0.f ? l.half_area() / a : 1.f, pr = a > 0.f ? r.half_area() / a : 1.f;
  return c.traversal + c.item * (pl * float(nl) + pr * float(nr)) < c.item * float(nl + nr);
}

inline int widest_axis(Box3 const& b) noexcept {
  float const d[3] = {b.hi[0] - b.lo[0], b.hi[1] - b.lo[1], b.hi[2] - b.lo[2]};
  return d[0] >= d[1] && d[0] >= d[2] ? 0 : (d[1] >= d[2] ? 1 : 2);
}

/// A subtree under construction: either a private node buffer (root at 0,
/// children at local indices) or an upper node with two subtrees.
struct Subtree {
  std::vector<Node> nodes;
  std::unique_ptr<Subtree> child[2];
  uint64_t total = 0;
};

// Splitter interface: `Split split(b, e, depth, cb)`, cb = bounds of the
// doubled centroids of items [b, e), returns m in (b, e) after reordering
// items[b, e) so [b, m) and [m, e) are the children (with their centroid
// bounds), or m = e to make [b, e) a leaf. It must split every range larger
// than the leaf size.
template <class Splitter>
void build_local(Splitter& s, uint64_t b, uint64_t e, uint32_t depth, Box3 const& cb, uint32_t self,
                 std::vector<Node>& out) {
  Split const sp = s.split(b, e, depth, cb);
  if (sp.m == e) {
    out[self].set_leaf(b, uint32_t(e - b));
    return;
  }
  auto const c = uint32_t(out.size());
  out.resize(out.size() + 2);
  out[self].set_inner(c);
  build_local(s, b, sp.m, depth + 1, sp.left, c, out);
  build_local(s, sp.m, e, depth + 1, sp.right, c + 1, out);
}

template <class Splitter>
std::unique_ptr<Subtree> build_upper(Splitter& s, uint64_t b, uint64_t e, uint32_t depth, Box3 const& cb) {
  auto t = std::make_unique<Subtree>();
  if (e - b <= local_build_items) {
    t->nodes.resize(1);
    build_local(s, b, e, depth, cb, 0, t->nodes);
    return t;
  }
  Split const sp = s.split(b, e, depth, cb);  // never a leaf: e - b > local_build_items >= max leaf
  tbb::parallel_invoke([&] { t->child[0] = build_upper(s, b, sp.m, depth + 1, sp.left); },
                       [&] { t->child[1] = build_upper(s, sp.m, e, depth + 1, sp.right); });
  return t;
}

inline uint64_t count_nodes(Subtree& t) {
  if (!t.nodes.empty()) return t.total = t.nodes.size();
  return t.total = 1 + count_nodes(*t.child[0]) + count_nodes(*t.child[1]);
}

struct PlaceJob {
  Subtree const* tree;
  uint64_t self;  ///< final index of the subtree's root
  uint64_t next;  ///< first final index of its other nodes
};

/// Depth-first layout: a root at `self`, its two children at next and
/// next + 1, then the left subtree's other nodes, then the right one's.
inline void place(Subtree const& t, uint64_t self, uint64_t next, Node* out, std::vector<PlaceJob>& jobs) {
  if (!t.nodes.empty()) {
    jobs.push_back({&t, self, next});
    return;
  }
  out[self].set_inner(uint32_t(next));
  uint64_t const left_rest = next + 2, right_rest = left_rest + (t.child[0]->total - 1);
  place(*t.child[0], next, left_rest, out, jobs);
  place(*t.child[1], next + 1, right_rest, out, jobs);
}

/// The final node array of a built subtree (bounds not yet set).
inline std::vector<Node> assemble(Subtree& root) {
  uint64_t const total = count_nodes(root);
  if (total >= uint64_t(Node::inner)) throw Error("BVH would need more than 2^32 - 2 nodes");
  std::vector<Node> nodes(total);
  std::vector<PlaceJob> jobs;
  place(root, 0, 1, nodes.data(), jobs);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, jobs.size(), 1), [&](tbb::blocked_range<size_t> const& r) {
    for (size_t j = r.begin(); j < r.end(); ++j) {
      PlaceJob const& job = jobs[j];
      std::vector<Node> const& local = job.tree->nodes;
      for (size_t i = 0; i < local.size(); ++i) {
        Node n = local[i];
        if (!n.is_leaf()) n.set_inner(uint32_t(job.next + n.first - 1));
        nodes[i == 0 ? job.self : job.next + i - 1] = n;
      }
    }
  });
  return nodes;
}

/// Subtrees at most this deep below the root are fitted as parallel tasks.
inline constexpr uint32_t parallel_fit_depth = 10;

/// Sets the bounds and value range of node `i` and everything below from
/// the item boxes; returns the depth of its deepest leaf.
template <class Index>
uint32_t fit_bounds_and_ranges(Node* nodes, NodeRange* ranges, ItemBox const* boxes, Index const* items, uint64_t i,
                               uint32_t depth) {
  Node& n = nodes[i];
  if (n.is_leaf()) {
    Box3 box;
    NodeRange r{inf_f, -inf_f};
    uint64_t const first = n.first_item();
    for (uint64_t s = first; s < first + n.item_count(); ++s) {
      ItemBox const& ib = boxes[items[s]];
      box.grow(ib);
      r.vmin = std::min(r.vmin, ib.vmin);
      r.vmax = std::max(r.vmax, ib.vmax);
    }
    std::copy(box.lo, box.lo + 3, n.lo);
    std::copy(box.hi, box.hi + 3, n.hi);
    ranges[i] = r;
    return depth;
  }
  uint64_t const l = n.left(), rgt = n.right();
  uint32_t dl = 0, dr = 0;
  if (depth < parallel_fit_depth) {
    tbb::parallel_invoke([&] { dl = fit_bounds_and_ranges(nodes, ranges, boxes, items, l, depth + 1); },
                         [&] { dr = fit_bounds_and_ranges(nodes, ranges, boxes, items, rgt, depth + 1); });
  } else {
    dl = fit_bounds_and_ranges(nodes, ranges, boxes, items, l, depth + 1);
    dr = fit_bounds_and_ranges(nodes, ranges, boxes, items, rgt, depth + 1);
  }
  for (int k = 0; k < 3; ++k) {
    n.lo[k] = std::min(nodes[l].lo[k], nodes[rgt].lo[k]);
    n.hi[k] = std::max(nodes[l].hi[k], nodes[rgt].hi[k]);
  }
  ranges[i] = {std::min(ranges[l].vmin, ranges[rgt].vmin), std::max(ranges[l].vmax, ranges[rgt].vmax)};
  return std::max(dl, dr);
}

/// Sets the value range of node `i` and everything below from
/// `item_range(id)` (a NodeRange per item id); bounds and topology untouched.
template <class Index, class ItemRange>
void fit_ranges(Node const* nodes, NodeRange* ranges, ItemRange const& item_range, Index const* items, uint64_t i,
                uint32_t depth) {
  Node const& n = nodes[i];
  if (n.is_leaf()) {
    NodeRange r{inf_f, -inf_f};
    uint64_t const first = n.first_item();
    for (uint64_t s = first; s < first + n.item_count(); ++s) {
      NodeRange const x = item_range(items[s]);
      r.vmin = std::min(r.vmin, x.vmin);
      r.vmax = std::max(r.vmax, x.vmax);
    }
    ranges[i] = r;
    return;
  }
  uint64_t const l = n.left(), rgt = n.right();
  if (depth < parallel_fit_depth) {
    tbb::parallel_invoke([&] { fit_ranges(nodes, ranges, item_range, items, l, depth + 1); },
                         [&] { fit_ranges(nodes, ranges, item_range, items, rgt, depth + 1); });
  } else {
    fit_ranges(nodes, ranges, item_range, items, l, depth + 1);
    fit_ranges(nodes, ranges, item_range, items, rgt, depth + 1);
  }
  ranges[i] = {std::min(ranges[l].vmin, ranges[rgt].vmin), std::max(ranges[l].vmax, ranges[rgt].vmax)};
}

}  // namespace detail
}  // namespace cellray
