#pragma once
// Binned SAH builder (Wald 2007, "On fast construction of SAH-based bounding
// volume hierarchies"): per range, bin the item centroids into `sah_bins`
// equal slabs per axis and take the plane of least SAH cost.

#include <cstring>

#include "build_common.hpp"

namespace cellray {
namespace detail {

inline constexpr uint32_t max_sah_bins = 64;
/// Ranges larger than this are binned along all three axes, smaller ones along the widest.
inline constexpr uint64_t all_axes_items = 4096;

template <class Index> struct SahSplitter {
  ItemBox const* boxes;
  Index* items;
  Index* scratch;
  uint32_t max_leaf;
  SahCosts costs;
  uint32_t bins;

  /// Plain data so a Binning is not initialised up front: only the first
  /// `bins` entries per axis are reset and read. Four lanes (the fourth is
  /// the item's vmin/vmax, ignored) so that min/max compile to vector ops.
  struct alignas(16) Bin {
    float lo[4], hi[4];
    uint64_t count;

    void reset() noexcept {
      for (int k = 0; k < 4; ++k) lo[k] = inf_f, hi[k] = -inf_f;
      count = 0;
    }
    void add(float const* l, float const* h) noexcept {
      for (int k = 0; k < 4; ++k) lo[k] = l[k] < lo[k] ? l[k] : lo[k];
      for (int k = 0; k < 4; ++k) hi[k] = h[k] > hi[k] ? h[k] : hi[k];
      ++count;
    }
    void merge(Bin const& o) noexcept {
      add(o.lo, o.hi);
      count += o.count - 1;
    }
  };
  struct Binning {
    Bin axis[3][max_sah_bins];
  };

  /// Bin of a doubled centroid coordinate; the one function binning and
  /// partitioning share, so both put every item in the same bin.
  static int bin_of(float c, float lo, float scale, int nbins) noexcept {
    // Clamp in float: an out-of-range or NaN float-to-int conversion is UB.
    float const t = (c - lo) * scale;
    return t >= 0.f ? (t < float(nbins) ? int(t) : nbins - 1) : 0;
  }

  Split split(uint64_t b, uint64_t e, uint32_t depth, Box3 const& cb) {
    uint64_t const n = e - b;
    Split const leaf{e, cb, cb};
    if (n <= 1) return leaf;
    int const wide = widest_axis(cb);
    if (!(cb.hi[wide] - cb.lo[wide] > 0.f)) return leaf_or_halve(b, e, max_leaf, cb);
    if (depth >= depth_guard) return n <= max_leaf ? leaf : object_median_split(boxes, items, b, e, wide);

    // Small ranges get fewer bins: the sweep per split, not the binning,
    // dominates there, and a few items need no fine planes.
    int const nb = int(std::min<uint64_t>(bins, std::max<uint64_t>(4, n / 2)));
    // Ranges of a private subtree bin the widest axis only: a third of the
    // work, for about 1% more SAH cost (BvhStats, bench_bvh).
    bool const all_axes = n > all_axes_items;
    float scale[3];
    for (int k = 0; k < 3; ++k) {
      float const ext = cb.hi[k] - cb.lo[k];
      scale[k] = ext > 0.f && (all_axes || k == wide) ? float(nb) / ext : 0.f;
    }
    Binning binning;
    for (int k = 0; k < 3; ++k)
      if (scale[k] != 0.f)
        for (int j = 0; j < nb; ++j) binning.axis[k][j].reset();
    auto const bin_range = [&](uint64_t lo, uint64_t hi, Binning& acc) {
      for (uint64_t i = lo; i < hi; ++i) {
        float box[8];  // lo xyz, vmin, hi xyz, vmax
        std::memcpy(box, &boxes[items[i]], sizeof(box));
        for (int k = 0; k < 3; ++k) {
          if (scale[k] == 0.f) continue;
          acc.axis[k][bin_of(box[k] + box[4 + k], cb.lo[k], scale[k], nb)].add(box, box + 4);
        }
      }
    };
    if (n < parallel_scan_items) {
      bin_range(b, e, binning);
    } else {
      // One binning per fixed block, merged in block order.
      uint64_t const blocks = (n + scan_block - 1) / scan_block;
      std::vector<Binning> part(blocks);
      tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
        for (uint64_t q = r.begin(); q < r.end(); ++q) {
          for (int k = 0; k < 3; ++k)
            if (scale[k] != 0.f)
              for (int j = 0; j < nb; ++j) part[q].axis[k][j].reset();
          bin_range(b + q * scan_block, std::min(e, b + (q + 1) * scan_block), part[q]);
        }
      });
      for (uint64_t q = 0; q < blocks; ++q)
        for (int k = 0; k < 3; ++k)
          if (scale[k] != 0.f)
            for (int j = 0; j < nb; ++j) binning.axis[k][j].merge(part[q].axis[k][j]);
    }

    Box3 all;
    for (int j = 0; j < nb; ++j) all.grow(binning.axis[wide][j].lo, binning.axis[wide][j].hi);
    int best_axis = -1, best_plane = 0;
    float best = inf_f;  // sum over children of (half area x items)
    for (int k = 0; k < 3; ++k) {
      if (scale[k] == 0.f) continue;
      auto const& bk = binning.axis[k];
      float right_cost[max_sah_bins];
      uint64_t right_count[max_sah_bins];
      Box3 r;
      uint64_t nr = 0;
      for (int j = nb - 1; j > 0; --j) {
        r.grow(bk[j].lo, bk[j].hi);
        nr += bk[j].count;
        right_cost[j] = r.half_area() * float(nr);
        right_count[j] = nr;
      }
      Box3 l;
      uint64_t nl = 0;
      for (int p = 1; p < nb; ++p) {  // plane p: bins [0, p) left, [p, nb) right
        l.grow(bk[p - 1].lo, bk[p - 1].hi);
        nl += bk[p - 1].count;
        if (nl == 0 || right_count[p] == 0) continue;
        float const cost = l.half_area() * float(nl) + right_cost[p];
        if (cost < best) best = cost, best_axis = k, best_plane = p;
      }
    }
    if (best_axis < 0) return n <= max_leaf ? leaf : object_median_split(boxes, items, b, e, wide);
    if (n <= max_leaf) {
      float const a = all.half_area();
      float const split_cost = costs.traversal + costs.item * (a > 0.f ? best / a : float(n));
      if (!(split_cost < costs.item * float(n))) return leaf;
    }
    int const k = best_axis;
    float const lo = cb.lo[k], sc = scale[k];
    return partition_items(boxes, items, scratch, b, e, [k, lo, sc, nb, best_plane](float const* c) {
      return bin_of(c[k], lo, sc, nb) < best_plane;
    });
  }
};

}  // namespace detail
}  // namespace cellray
