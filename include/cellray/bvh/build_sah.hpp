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
/// Ranges of at least this many items bin into two alternating binnings.
inline constexpr uint64_t two_binnings_items = 256;
/// Ranges over twice this many items bin a sample of at least this many
/// (every (n / sample_items)-th slot), with twice the bins. Against binning
/// every item of ranges up to 2048 (and 16 bins): 11% fewer instructions
/// for the whole build; with the partition change of the same round (see
/// parallel_partition_items) SAH cost 1M tets 1271.34 -> 1273.05 (+0.1%),
/// 1M hexes +0.7%, component8 (608k tets) +0.4%, boxturb 0%.
inline constexpr uint64_t sample_items = 128;

/// Bins and their item counts for the three axes. Plain data so that a
/// Binning is not initialised up front: only the first `nb` entries per axis
/// are reset and read.
struct Binning {
  Bounds4 box[3][max_sah_bins];  ///< lanes 3 (vmin/vmax) are carried along, never read
  uint64_t count[3][max_sah_bins];

  void reset(int nb, int axis_begin, int axis_end) noexcept {
    for (int k = axis_begin; k < axis_end; ++k)
      for (int j = 0; j < nb; ++j) box[k][j] = Bounds4::empty(), count[k][j] = 0;
  }
  void merge(Binning const& o, int nb, int axis_begin, int axis_end) noexcept {
    for (int k = axis_begin; k < axis_end; ++k)
      for (int j = 0; j < nb; ++j) box[k][j].grow(o.box[k][j]), count[k][j] += o.count[k][j];
  }
};

/// How a range maps doubled centroids to bins: bin = (c - lo) * scale,
/// clamped to [0, nb - 1]. The one mapping binning and partitioning share,
/// so both put every item in the same bin.
struct BinMap {
  float lo[4];     ///< lane 3 unused (0)
  float scale[4];  ///< 0 for an axis of zero extent (every item in bin 0); lane 3: 0
  float last;      ///< nb - 1

  int bin(float c, int k) const noexcept {
    // Clamp in float (t > 0 is false for NaN): an out-of-range or NaN
    // float-to-int conversion is UB. Same operations as `bins4`.
    float t = (c - lo[k]) * scale[k];
    t = t > 0.f ? t : 0.f;
    t = t < last ? t : last;
    return int(t);
  }
};

/// Adds slots [b, e) to the bins of axes [ka, kb). Consecutive slots go to
/// two alternating binnings: neighbours in space often share a bin, and one
/// binning would chain every update on the previous one's store.
template <int ka, int kb>
void bin_slots(ItemBox const* box, uint64_t b, uint64_t e, BinMap const& map, Binning& even, Binning& odd,
               uint64_t stride = 1) {
  F4 const lo = F4::load(map.lo), scale = F4::load(map.scale), zero = F4::splat(0.f), last = F4::splat(map.last);
  auto add = [&](ItemBox const& item, Binning& acc) {
    float const* v = reinterpret_cast<float const*>(&item);
    F4 const l = F4::load(v), h = F4::load(v + 4);
    F4 const t = min(max((l + h - lo) * scale, zero), last);
    auto grow_bin = [&](int k, int32_t j) {
      float* acc_box = acc.box[k][j].v;
      min(l, F4::load(acc_box)).store(acc_box);
      max(h, F4::load(acc_box + 4)).store(acc_box + 4);
      ++acc.count[k][j];
    };
    if constexpr (kb == ka + 1) {
      grow_bin(ka, t.template lane_int<ka>());  // one axis: its lane, no store and reload
    } else {
      alignas(16) int32_t j[4];
      t.to_int(j);
      for (int k = ka; k < kb; ++k) grow_bin(k, j[k]);
    }
  };
  uint64_t i = b;
  for (; i + stride < e; i += 2 * stride) {
    add(box[i], even);
    add(box[i + stride], odd);
  }
  if (i < e) add(box[i], even);
}

template <class Index> struct SahSplitter {
  Slots<Index> slots;
  uint32_t max_leaf;
  SahCosts costs;
  uint32_t bins;

  Bounds4 leaf_fit(uint64_t b, uint64_t e) const noexcept {
    Bounds4 f = Bounds4::empty();
    for (uint64_t i = b; i < e; ++i) f.grow(slots.box[i]);
    return f;
  }

  /// Whether any split of slots [b, e) could cost less than a leaf. Every
  /// child box contains the boxes of its items, so any split costs at least
  /// traversal + item x (sum of item areas) / (range area): when even that
  /// bound is no cheaper than the leaf, the binned search below would make
  /// a leaf too and is skipped (1M tets: 99.8% of the ranges of 4-7 items,
  /// 1M hexes 82%; same trees). The 1e-5 margin covers the rounding by
  /// which a computed plane cost may undercut the exact bound.
  bool split_can_pay(uint64_t b, uint64_t e) const noexcept {
    F4 lo = F4::splat(inf_f), hi = F4::splat(-inf_f);
    float item_areas = 0.f;
    for (uint64_t i = b; i < e; ++i) {
      float const* v = reinterpret_cast<float const*>(slots.box + i);
      F4 const l = F4::load(v), h = F4::load(v + 4);
      lo = min(l, lo), hi = max(h, hi);
      item_areas += half_area_nonempty(l, h);
    }
    float const all = half_area(lo, hi);
    if (!(all > 0.f)) return false;  // the search's leaf rule for a degenerate box
    return costs.traversal + costs.item * (item_areas / all) * (1.f - 1e-5f) < costs.item * float(e - b);
  }

  /// Bins slots [b, e) along axes [ka, kb): in fixed blocks (in parallel)
  /// for large ranges, merged in block order (min, max and integer sums,
  /// exact in any order).
  template <int ka, int kb>
  void bin_range(uint64_t b, uint64_t e, BinMap const& map, int nb, Binning& out, uint64_t stride = 1) const {
    uint64_t const n = e - b;
    if (n < parallel_scan_items * stride) {
      out.reset(nb, ka, kb);
      if (n < two_binnings_items * stride) {
        bin_slots<ka, kb>(slots.box, b, e, map, out, out, stride);
        return;
      }
      Binning odd;
      odd.reset(nb, ka, kb);
      bin_slots<ka, kb>(slots.box, b, e, map, out, odd, stride);
      out.merge(odd, nb, ka, kb);
      return;
    }
    uint64_t const block = scan_block * stride;  // a multiple of the stride: samples stay every stride-th slot
    uint64_t const blocks = (n + block - 1) / block;
    std::vector<Binning> part(blocks);
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t q = r.begin(); q < r.end(); ++q)
        bin_range<ka, kb>(b + q * block, std::min(e, b + (q + 1) * block), map, nb, part[q], stride);
    });
    out = part[0];
    for (uint64_t q = 1; q < blocks; ++q) out.merge(part[q], nb, ka, kb);
  }

  Split split(uint64_t b, uint64_t e, uint32_t depth, Box3 const& cb) {
    uint64_t const n = e - b;
    Split const leaf{e, cb, cb};
    if (n <= 1) return leaf;
    // A split costs at least `traversal`: at or below traversal / item
    // items (3 by default) no plane can pay, so no binning is needed.
    if (n <= max_leaf && !(costs.traversal < costs.item * float(n))) return leaf;
    if (n <= max_leaf && !split_can_pay(b, e)) return leaf;
    int const wide = widest_axis(cb);
    if (!(cb.hi[wide] - cb.lo[wide] > 0.f)) return leaf_or_halve(b, e, max_leaf, cb);
    if (depth >= depth_guard) return n <= max_leaf ? leaf : object_median_split(slots, b, e, wide);

    // Sampled ranges (see below) get twice the bins: the binning costs the
    // same, the planes are finer (1M tets with 128-item samples: SAH 1279 at
    // 16 bins, 1269 at 32). Small ranges get n / 4 bins: the sweep per
    // split, not the binning, dominates there, and a few items need no fine
    // planes (n / 2 bins: 3.5% more instructions, component8 SAH -0.2%).
    bool const sampled = n > 2 * sample_items;
    int const nb = sampled ? int(std::min<uint32_t>(2 * bins, max_sah_bins))
                           : int(std::min<uint64_t>(bins, std::max<uint64_t>(4, n / 4)));
    // Ranges of a private subtree bin the widest axis only: a third of the
    // work, for about 1% more SAH cost (BvhStats, bench_bvh).
    bool const all_axes = n > all_axes_items;
    BinMap map{{0.f, 0.f, 0.f, 0.f}, {0.f, 0.f, 0.f, 0.f}, float(nb - 1)};
    for (int k = 0; k < 3; ++k) {
      float const ext = cb.hi[k] - cb.lo[k];
      map.lo[k] = cb.lo[k];
      map.scale[k] = ext > 0.f ? float(nb) / ext : 0.f;
    }
    int const ka = all_axes ? 0 : wide, kb = all_axes ? 3 : wide + 1;
    // Ranges over 2 x sample_items items bin every stride-th slot only (at
    // least sample_items of them): the plane costs are estimated from a
    // sample (see sample_items for the cost). The stride depends on n alone, so the
    // tree stays deterministic. A sample that finds no plane (all in one
    // bin: outliers missed) falls back to every slot.
    uint64_t const stride = std::max<uint64_t>(1, n / sample_items);
    Plane best = find_plane(b, e, map, nb, ka, kb, wide, stride);
    if (best.axis < 0 && stride > 1) best = find_plane(b, e, map, nb, ka, kb, wide, 1);
    if (best.axis < 0) return n <= max_leaf ? leaf : object_median_split(slots, b, e, wide);
    if (n <= max_leaf) {
      float const a = best.all_area;
      float const split_cost = costs.traversal + costs.item * (a > 0.f ? best.cost / a : float(n));
      if (!(split_cost < costs.item * float(n))) return leaf;
    }
    // bin(c) < plane as one float compare: t = (c - lo) * scale is clamped
    // to [0, nb - 1] and truncated by `bin`, so bin(c) < plane (1 <= plane
    // <= nb - 1) exactly when t < plane or t is NaN (bin 0).
    int const k = best.axis;
    float const lo = map.lo[k], scale = map.scale[k], plane = float(best.plane);
    auto const partition = [&](auto lane) {  // the predicate reads a lane fixed at compile time
      constexpr int axis = decltype(lane)::value;
      return partition_slots(slots, b, e, [lo, scale, plane](F4 p) { return !((p.lane<axis>() - lo) * scale >= plane); });
    };
    if (k == 0) return partition(std::integral_constant<int, 0>{});
    if (k == 1) return partition(std::integral_constant<int, 1>{});
    return partition(std::integral_constant<int, 2>{});
  }

  /// The best plane of a binning: cost = sum over both children of (half
  /// area x items); axis -1 when no plane has items on both sides.
  struct Plane {
    float cost = inf_f;
    int axis = -1, plane = 0;
    float all_area = 0.f;  ///< half area of the range's box (from the widest axis' bins)
  };

  /// Bins slots [b, e) (every stride-th) along axes [ka, kb) and sweeps the bins.
  Plane find_plane(uint64_t b, uint64_t e, BinMap const& map, int nb, int ka, int kb, int wide, uint64_t stride) const {
    Binning binning;
    if (kb - ka == 3) bin_range<0, 3>(b, e, map, nb, binning, stride);
    else if (wide == 0) bin_range<0, 1>(b, e, map, nb, binning, stride);
    else if (wide == 1) bin_range<1, 2>(b, e, map, nb, binning, stride);
    else bin_range<2, 3>(b, e, map, nb, binning, stride);
    Plane best;
    for (int k = ka; k < kb; ++k) {
      auto const& bk = binning.box[k];
      auto const& ck = binning.count[k];
      float right_cost[max_sah_bins];
      uint64_t right_count[max_sah_bins];
      F4 lo = F4::splat(inf_f), hi = F4::splat(-inf_f);
      uint64_t nr = 0;
      for (int j = nb - 1; j > 0; --j) {
        lo = min(F4::load(bk[j].v), lo);
        hi = max(F4::load(bk[j].v + 4), hi);
        nr += ck[j];
        // An empty side (nr == 0) gives inf or NaN here; its planes are skipped below.
        right_cost[j] = half_area_nonempty(lo, hi) * float(int64_t(nr));
        right_count[j] = nr;
      }
      if (k == wide) best.all_area = half_area(min(F4::load(bk[0].v), lo), max(F4::load(bk[0].v + 4), hi));
      if (map.scale[k] == 0.f) continue;
      lo = F4::splat(inf_f), hi = F4::splat(-inf_f);
      uint64_t nl = 0;
      for (int p = 1; p < nb; ++p) {  // plane p: bins [0, p) left, [p, nb) right
        lo = min(F4::load(bk[p - 1].v), lo);
        hi = max(F4::load(bk[p - 1].v + 4), hi);
        nl += ck[p - 1];
        if (nl == 0 || right_count[p] == 0) continue;
        float const cost = half_area_nonempty(lo, hi) * float(int64_t(nl)) + right_cost[p];
        if (cost < best.cost) best.cost = cost, best.axis = k, best.plane = p;
      }
    }
    return best;
  }
};

}  // namespace detail
}  // namespace cellray
