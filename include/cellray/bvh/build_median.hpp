#pragma once
// The paper's builder (Rathke 2015 §5.3): split the widest axis of the
// centroid bounds in the middle; ranges of at most max_leaf_size items
// become a leaf unless the SAH says a split pays.

#include "build_common.hpp"

namespace cellray {
namespace detail {

template <class Index> struct MedianSplitter {
  Slots<Index> slots;
  uint32_t max_leaf;
  SahCosts costs;

  Bounds4 leaf_fit(uint64_t b, uint64_t e) const noexcept {
    Bounds4 f = Bounds4::empty();
    for (uint64_t i = b; i < e; ++i) f.grow(slots.box[i]);
    return f;
  }

  Split split(uint64_t b, uint64_t e, uint32_t depth, Box3 const& cb) {
    uint64_t const n = e - b;
    Split const leaf{e, cb, cb};
    if (n <= 1) return leaf;
    int const axis = widest_axis(cb);
    float const extent = cb.hi[axis] - cb.lo[axis];
    if (!(extent > 0.f)) return leaf_or_halve(b, e, max_leaf, cb);
    if (depth >= depth_guard) return n <= max_leaf ? leaf : object_median_split(slots, b, e, axis);
    float const mid = cb.lo[axis] + 0.5f * extent;
    auto const goes_left = [axis, mid](float const* c) { return c[axis] < mid; };
    // The partition's predicate reads a lane fixed at compile time.
    auto const partition = [&](auto lane) {
      constexpr int k = decltype(lane)::value;
      return partition_slots(slots, b, e, [mid](F4 p) { return p.lane<k>() < mid; });
    };
    if (n <= max_leaf) {
      Box3 all, l, r;
      uint64_t nl = 0;
      for (uint64_t i = b; i < e; ++i) {
        ItemBox const& ib = slots.box[i];
        float c[3];
        centroid2(ib, c);
        all.grow(ib);
        if (goes_left(c)) l.grow(ib), ++nl;
        else r.grow(ib);
      }
      if (nl == 0 || nl == n || !split_pays(costs, all, l, nl, r, n - nl)) return leaf;
    }
    Split const sp = axis == 0   ? partition(std::integral_constant<int, 0>{})
                     : axis == 1 ? partition(std::integral_constant<int, 1>{})
                                 : partition(std::integral_constant<int, 2>{});
    // mid rounds onto lo when the extent is a few ulps: fall back to counts.
    if (sp.m == b || sp.m == e) return n <= max_leaf ? leaf : object_median_split(slots, b, e, axis);
    return sp;
  }
};

}  // namespace detail
}  // namespace cellray
