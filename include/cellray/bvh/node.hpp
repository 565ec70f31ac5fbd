#pragma once
// The min-max BVH (Rathke 2015 §5): node layout, per-node value ranges, and
// the `MinMaxBvh` that owns a built tree. Knows items only as "bounds and
// value range of item i"; what an item id means is up to the caller.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "../error.hpp"
#include "../memory.hpp"
#include "../mesh/span.hpp"

namespace cellray {

/// One node of the tree: geometry and topology only. The value range lives in
/// a separate `ValueRanges` array (indexed like the nodes) so renders of
/// different time steps can share one tree. 32 B, two per 64-B cache line:
///   [ 0,12) lo[3]  box min xyz (float), tight over the cells below
///   [12,16) first  inner: index of the left child; the right child is first + 1
///                  leaf:  low 32 bits of the first item-list slot
///   [16,28) hi[3]  box max xyz
///   [28,32) count  inner: `Node::inner` (0xFFFFFFFF)
///                  leaf:  bits [0,8) item count (1..max_leaf_size; 0 only for
///                         the root of an empty BVH), bits [8,32) the slot's
///                         bits 32..55 (zero below 2^32 items)
/// Paper §5.2 has 40 B with the range inside; here 32 B + 8 B of NodeRange.
/// Access: `n.is_leaf()`, `n.left()`, `n.right()`, `n.item_count()`,
/// `n.first_item()`; leaf items are the item-list slots
/// [first_item(), first_item() + item_count()).
struct alignas(32) Node {
  static constexpr uint32_t inner = 0xFFFFFFFFu;  ///< `count` of an inner node
  static constexpr uint32_t max_leaf_items = 128;  ///< largest leaf the encoding allows (< 255)

  float lo[3];
  uint32_t first;
  float hi[3];
  uint32_t count;

  bool is_leaf() const noexcept { return count != inner; }
  uint32_t left() const noexcept { return first; }
  uint32_t right() const noexcept { return first + 1; }
  uint32_t item_count() const noexcept { return count & 0xFFu; }
  uint64_t first_item() const noexcept { return uint64_t(first) | (uint64_t(count >> 8) << 32); }

  void set_inner(uint32_t left_child) noexcept {
    first = left_child;
    count = inner;
  }
  void set_leaf(uint64_t first_slot, uint32_t items) noexcept {
    first = uint32_t(first_slot);
    count = items | uint32_t(first_slot >> 32) << 8;
  }
};
static_assert(sizeof(Node) == 32, "Node is documented as 32 bytes");

namespace detail {
/// The node array of a tree: a resize leaves the nodes unset (the builders
/// write every one; zeroing was 2-3% of a Morton build of 1M cells) and a
/// large array is advised as huge pages (memory.hpp).
using NodeVector = LargeVector<Node>;
}  // namespace detail

/// Value range of one node: the smallest and largest vertex value of every
/// cell below it (leaf: exactly the min/max over its cells). Empty range
/// (+inf, -inf) when every cell below has a NaN value or no values. 8 B.
struct NodeRange {
  float vmin;
  float vmax;
};
static_assert(sizeof(NodeRange) == 8, "NodeRange is documented as 8 bytes");

/// One value range per node of one `MinMaxBvh`, for one scalar array (one
/// time step). Built with the tree or by `refit_ranges`; any number of them
/// can exist for one tree and be read by concurrent renders.
class ValueRanges {
 public:
  ValueRanges() = default;
  explicit ValueRanges(uint64_t nodes) { detail::resize_zeroed(r_, nodes); }

  uint64_t size() const noexcept { return r_.size(); }
  NodeRange const* data() const noexcept { return r_.data(); }
  NodeRange* data() noexcept { return r_.data(); }
  NodeRange const& operator[](uint64_t node) const noexcept { return r_[node]; }
  NodeRange& operator[](uint64_t node) noexcept { return r_[node]; }
  void resize(uint64_t nodes) { detail::resize_zeroed(r_, nodes); }
  uint64_t bytes() const noexcept { return r_.size() * sizeof(NodeRange); }
  friend bool operator==(ValueRanges const& a, ValueRanges const& b) {
    return a.r_.size() == b.r_.size() &&
           std::equal(a.r_.begin(), a.r_.end(), b.r_.begin(), [](NodeRange const& x, NodeRange const& y) {
             return x.vmin == y.vmin && x.vmax == y.vmax;
           });
  }
  friend bool operator!=(ValueRanges const& a, ValueRanges const& b) { return !(a == b); }

 private:
  detail::LargeVector<NodeRange> r_;
};

/// The builders (see build.hpp). All are parallel and deterministic.
enum class BvhBuilder {
  spatial_median,  ///< paper §5.3: split the widest centroid axis in the middle, SAH termination
  binned_sah,      ///< binned surface-area heuristic: best traversal speed
  morton,          ///< LBVH over 30-bit Morton codes: fastest build, for rebuild-every-frame use
};

/// "spatial_median", "binned_sah" or "morton".
constexpr char const* builder_name(BvhBuilder b) noexcept {
  switch (b) {
    case BvhBuilder::spatial_median: return "spatial_median";
    case BvhBuilder::binned_sah: return "binned_sah";
    case BvhBuilder::morton: return "morton";
  }
  return "?";
}

/// Where a global item id points: cell `cell` of piece `piece`.
struct PieceCell {
  uint32_t piece;
  uint64_t cell;
};

namespace detail {
struct BvhAccess;
}

/// A binary min-max BVH over items 0..item_count()-1 (Rathke 2015 §5).
/// Owns its nodes, its item list (item ids, 32-bit when the item count fits,
/// else 64-bit) and the `ValueRanges` of the scalar array it was built with.
/// It never refers to the mesh it was built from: the caller passes the mesh
/// again to a traversal. Node 0 is the root; a default-constructed or
/// zero-item BVH has one leaf root with no items, empty bounds (lo = +inf,
/// hi = -inf) and an empty range, so any traversal finds nothing in it.
/// Depth (root = 0) is at most `max_depth`. Immutable after the build apart
/// from `set_ranges`; safe to read from any number of threads.
class MinMaxBvh {
 public:
  /// Guaranteed bound on the depth of any leaf: traversal stacks of this size never overflow.
  static constexpr uint32_t max_depth = 128;

  MinMaxBvh() { make_empty(); }

  uint64_t node_count() const noexcept { return nodes_.size(); }
  Node const* nodes() const noexcept { return nodes_.data(); }
  Node const& node(uint64_t i) const noexcept { return nodes_[i]; }
  Node const& root() const noexcept { return nodes_[0]; }

  /// Value ranges of the array the tree was built with (or last `set_ranges`).
  ValueRanges const& ranges() const noexcept { return ranges_; }
  /// Replaces the owned ranges (e.g. a refit for another time step; a move,
  /// no copy). @throws InvalidArgument when `r` is not sized for this tree.
  void set_ranges(ValueRanges r) {
    if (r.size() != nodes_.size())
      throw InvalidArgument("value ranges for " + std::to_string(r.size()) + " nodes given to a BVH of " +
                            std::to_string(nodes_.size()) + " nodes");
    ranges_ = std::move(r);
  }

  /// Number of items (cells over all pieces); each is in exactly one leaf.
  uint64_t item_count() const noexcept { return wide_ ? items64_.size() : items32_.size(); }
  bool empty() const noexcept { return item_count() == 0; }
  /// True when the item list holds 64-bit ids (more than 2^32 - 1 items, or forced).
  bool wide_items() const noexcept { return wide_; }
  /// The item list for fast paths: exactly one of these is non-null (unless empty).
  uint32_t const* items32() const noexcept { return wide_ ? nullptr : items32_.data(); }
  uint64_t const* items64() const noexcept { return wide_ ? items64_.data() : nullptr; }
  /// Global item id at item-list slot `slot`.
  uint64_t item(uint64_t slot) const noexcept { return wide_ ? items64_[slot] : uint64_t(items32_[slot]); }

  /// Piece table: piece p holds global ids [piece_offsets()[p], piece_offsets()[p+1]).
  /// One piece (offsets {0, n}) for a single mesh or a box span.
  std::vector<uint64_t> const& piece_offsets() const noexcept { return piece_offsets_; }
  uint32_t piece_count() const noexcept { return uint32_t(piece_offsets_.size() - 1); }
  /// Decodes a global item id (binary search over the piece table).
  PieceCell locate(uint64_t id) const noexcept {
    auto it = std::upper_bound(piece_offsets_.begin(), piece_offsets_.end(), id);
    auto p = uint32_t(it - piece_offsets_.begin() - 1);
    return {p, id - piece_offsets_[p]};
  }

  BvhBuilder builder() const noexcept { return builder_; }
  uint32_t max_leaf_size() const noexcept { return max_leaf_size_; }
  /// Depth of the deepest leaf (root = 0).
  uint32_t depth() const noexcept { return depth_; }
  /// Wall time of the build in seconds (box computation for a mesh included).
  double build_seconds() const noexcept { return build_seconds_; }

  /// Bytes the tree owns: nodes + item list + one ValueRanges.
  uint64_t memory_bytes() const noexcept {
    return nodes_.size() * sizeof(Node) + ranges_.bytes() +
           (wide_ ? items64_.size() * sizeof(uint64_t) : items32_.size() * sizeof(uint32_t));
  }

 private:
  friend struct detail::BvhAccess;

  void make_empty() {
    constexpr float inf = std::numeric_limits<float>::infinity();
    Node n{{inf, inf, inf}, 0, {-inf, -inf, -inf}, 0};
    n.set_leaf(0, 0);
    nodes_.assign(1, n);
    ranges_.resize(1);
    ranges_[0] = {inf, -inf};
    piece_offsets_ = {0, 0};
  }

  detail::NodeVector nodes_;
  ValueRanges ranges_;
  detail::LargeVector<uint32_t> items32_;
  detail::LargeVector<uint64_t> items64_;
  std::vector<uint64_t> piece_offsets_;
  bool wide_ = false;
  BvhBuilder builder_ = BvhBuilder::binned_sah;
  uint32_t max_leaf_size_ = 0;
  uint32_t depth_ = 0;
  double build_seconds_ = 0;
};

}  // namespace cellray
