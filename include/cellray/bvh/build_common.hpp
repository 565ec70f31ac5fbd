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
#include <cstring>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <type_traits>
#include <tuple>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>
#include <xsimd/xsimd.hpp>

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
  /// Bins per axis of the SAH builder, 2..64: ranges binned from a sample
  /// (over 256 items) use twice as many (at most 64), ranges of n <= 256
  /// items min(sah_bins, max(4, n / 4)).
  uint32_t sah_bins = 16;
  /// Store 64-bit item ids even when 32 bits would do (tests of the wide path).
  bool wide_items = false;
  /// ISA for the per-cell boxes of a mesh build; default `default_isa()`.
  std::optional<Isa> isa;
};

namespace detail {

/// Writes a built tree into a MinMaxBvh (its only writer besides set_ranges).
struct BvhAccess {
  static NodeVector& nodes(MinMaxBvh& b) { return b.nodes_; }
  static ValueRanges& ranges(MinMaxBvh& b) { return b.ranges_; }
  static LargeVector<uint32_t>& items32(MinMaxBvh& b) { return b.items32_; }
  static LargeVector<uint64_t>& items64(MinMaxBvh& b) { return b.items64_; }
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
/// Ranges of at least this many items are partitioned in fixed blocks (in
/// parallel), smaller ones sequentially in one pass. The block partition
/// moves about 1.45x the bytes (every block, then the strays between
/// blocks), so it pays only where too few subtrees run side by side: the
/// top one or two levels of a 1M-item build (below them, 4+ subtrees keep
/// the cores busy). Depends on the range size only (determinism).
inline constexpr uint64_t parallel_partition_items = uint64_t(1) << 18;
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

/// The 8 floats of an item box: lo xyz, vmin, hi xyz, vmax.
inline void load8(ItemBox const& b, float* v) noexcept { std::memcpy(v, &b, sizeof(ItemBox)); }

/// Centroid of an item box times two (lo + hi): halving changes no decision.
inline void centroid2(ItemBox const& b, float* c) noexcept {
  float v[8];
  load8(b, v);
  for (int k = 0; k < 3; ++k) c[k] = v[k] + v[4 + k];
}

/// Four float lanes for the builders' inner loops (min/max of lo xyz + vmin
/// and hi xyz + vmax, bin indices). The builders run in the host's own
/// translation units, not in the ISA units, so this is the baseline ISA:
/// SSE2 on x86-64 (every x86-64 CPU has it), plain floats elsewhere. GCC 12
/// does not vectorise the scalar form (measured: 8 minss per box update).
struct F4 {
#if XSIMD_WITH_SSE2
  xsimd::batch<float, xsimd::sse2> x;

  static F4 load(float const* p) noexcept { return {xsimd::batch<float, xsimd::sse2>::load_unaligned(p)}; }
  static F4 splat(float v) noexcept { return {xsimd::batch<float, xsimd::sse2>(v)}; }
  void store(float* p) const noexcept { x.store_unaligned(p); }
  friend F4 operator+(F4 a, F4 b) noexcept { return {a.x + b.x}; }
  friend F4 operator-(F4 a, F4 b) noexcept { return {a.x - b.x}; }
  friend F4 operator*(F4 a, F4 b) noexcept { return {a.x * b.x}; }
  /// Lane-wise a < b ? a : b (b when either is NaN): SSE minps, one instruction.
  friend F4 min(F4 a, F4 b) noexcept { return {xsimd::min(a.x, b.x)}; }
  /// Lane-wise a > b ? a : b (b when either is NaN): SSE maxps.
  friend F4 max(F4 a, F4 b) noexcept { return {xsimd::max(a.x, b.x)}; }
  /// Truncation to int of lanes known to lie in [0, 2^31).
  void to_int(int32_t* out) const noexcept { xsimd::batch_cast<int32_t>(x).store_unaligned(out); }
  /// Lane L (a shuffle, no store).
  template <int L> float lane() const noexcept {
    __m128 const v = x;
    return _mm_cvtss_f32(_mm_shuffle_ps(v, v, L * 0x55));
  }
  /// Lane L truncated to int, for a lane known to lie in [0, 2^31) (a shuffle and a convert, no store).
  template <int L> int32_t lane_int() const noexcept {
    __m128 const v = x;
    return _mm_cvttss_si32(_mm_shuffle_ps(v, v, L * 0x55));
  }
  /// lanes 0-2: a0 * b0 + a1 * b1 + a2 * b2, lane 3 ignored; no store.
  friend float dot3(F4 a, F4 b) noexcept {
    __m128 const t = (a.x * b.x);
    __m128 const s = _mm_add_ss(t, _mm_movehl_ps(t, t));           // t0 + t2
    return _mm_cvtss_f32(_mm_add_ss(s, _mm_shuffle_ps(t, t, 0x55)));  // + t1
  }
  /// Lanes rotated: (x1, x2, x0, x3).
  F4 yzx() const noexcept {
    __m128 const v = x;
    return {xsimd::batch<float, xsimd::sse2>(_mm_shuffle_ps(v, v, _MM_SHUFFLE(3, 0, 2, 1)))};
  }
  /// Bit k set when lane k of `lo` and `hi` is finite and lo <= hi (x - x
  /// is 0 for finite x, NaN for inf and NaN).
  friend int finite_ordered(F4 lo, F4 hi) noexcept {
    auto const zero = xsimd::batch<float, xsimd::sse2>(0.f);
    return _mm_movemask_ps((lo.x - lo.x == zero) && (hi.x - hi.x == zero) && (lo.x <= hi.x));
  }
#else
  float x[4];

  static F4 load(float const* p) noexcept { return {{p[0], p[1], p[2], p[3]}}; }
  static F4 splat(float v) noexcept { return {{v, v, v, v}}; }
  void store(float* p) const noexcept { std::copy(x, x + 4, p); }
  template <class Op> static F4 map(F4 a, F4 b, Op op) noexcept {
    return {{op(a.x[0], b.x[0]), op(a.x[1], b.x[1]), op(a.x[2], b.x[2]), op(a.x[3], b.x[3])}};
  }
  friend F4 operator+(F4 a, F4 b) noexcept { return map(a, b, [](float u, float v) { return u + v; }); }
  friend F4 operator-(F4 a, F4 b) noexcept { return map(a, b, [](float u, float v) { return u - v; }); }
  friend F4 operator*(F4 a, F4 b) noexcept { return map(a, b, [](float u, float v) { return u * v; }); }
  friend F4 min(F4 a, F4 b) noexcept { return map(a, b, [](float u, float v) { return u < v ? u : v; }); }
  friend F4 max(F4 a, F4 b) noexcept { return map(a, b, [](float u, float v) { return u > v ? u : v; }); }
  void to_int(int32_t* out) const noexcept {
    for (int k = 0; k < 4; ++k) out[k] = int32_t(x[k]);
  }
  template <int L> float lane() const noexcept { return x[L]; }
  template <int L> int32_t lane_int() const noexcept { return int32_t(x[L]); }
  friend float dot3(F4 a, F4 b) noexcept { return a.x[0] * b.x[0] + a.x[2] * b.x[2] + a.x[1] * b.x[1]; }
  F4 yzx() const noexcept { return {{x[1], x[2], x[0], x[3]}}; }
  friend int finite_ordered(F4 lo, F4 hi) noexcept {
    int m = 0;
    for (int k = 0; k < 4; ++k)
      m |= (std::isfinite(lo.x[k]) && std::isfinite(hi.x[k]) && lo.x[k] <= hi.x[k]) << k;
    return m;
  }
#endif
};

/// Half the surface area of the box [lo, hi] (lanes 0-2); 0 when empty.
inline float half_area(F4 lo, F4 hi) noexcept {
  alignas(16) float d[4];
  (hi - lo).store(d);
  if (!(d[0] >= 0.f && d[1] >= 0.f && d[2] >= 0.f)) return 0.f;
  return d[0] * d[1] + d[1] * d[2] + d[2] * d[0];
}

/// Half the surface area of a box [lo, hi] known to be non-empty (lanes
/// 0-2), in registers: dx dy + dz dx + dy dz. For the SAH sweeps, where it
/// runs once per bin and plane; the result may differ from `half_area` in
/// the last bit (another summation order), which only the sweeps compare.
inline float half_area_nonempty(F4 lo, F4 hi) noexcept {
  F4 const d = hi - lo;
  return dot3(d, d.yzx());
}

/// Grows the 8 floats `acc` (lo xyz + vmin, hi xyz + vmax) by the 8 floats
/// `v` of an item box or another accumulator: one 4-wide min and one max.
inline void grow8(float* acc, float const* v) noexcept {
  min(F4::load(v), F4::load(acc)).store(acc);
  max(F4::load(v + 4), F4::load(acc + 4)).store(acc + 4);
}

/// Bounds and value range in four lanes each, laid out like an ItemBox:
/// v = lo xyz, vmin, hi xyz, vmax. Plain data (no initialiser, so arrays of
/// bins cost nothing until reset); `empty()` is the empty box and range.
struct alignas(16) Bounds4 {
  float v[8];

  static Bounds4 empty() noexcept { return {{inf_f, inf_f, inf_f, inf_f, -inf_f, -inf_f, -inf_f, -inf_f}}; }
  void grow(float const* x) noexcept { grow8(v, x); }
  void grow(Bounds4 const& o) noexcept { grow8(v, o.v); }
  void grow(ItemBox const& b) noexcept { grow8(v, reinterpret_cast<float const*>(&b)); }
  Box3 box() const noexcept {
    Box3 b;
    b.grow(v, v + 4);
    return b;
  }
  /// Writes the bounds into `n` and returns the value range.
  NodeRange store(Node& n) const noexcept {
    for (int k = 0; k < 3; ++k) n.lo[k] = v[k], n.hi[k] = v[4 + k];
    return {v[3], v[7]};
  }
};

/// The item slots of a build: slot s holds item `id[s]` whose box is
/// `box[s]`. The SAH and median builders reorder both arrays together, in
/// place, so every pass reads the boxes of a range contiguously; when the
/// build ends `id` is the item list and a leaf's boxes are its slots'.
template <class Index> struct Slots {
  ItemBox* box;
  Index* id;

  void swap(uint64_t i, uint64_t j) const noexcept {
    std::swap(box[i], box[j]);
    std::swap(id[i], id[j]);
  }
};

/// Bounds of the doubled centroids of slots [b, e); parallel for large ranges.
inline Box3 centroid_bounds(ItemBox const* boxes, uint64_t b, uint64_t e) {
  auto body = [&](uint64_t lo, uint64_t hi, Box3 acc) {
    for (uint64_t i = lo; i < hi; ++i) {
      float c[3];
      centroid2(boxes[i], c);
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

/// A split of slots [b, e): children [b, m) and [m, e) with the bounds of
/// their doubled centroids; m == e means "make a leaf".
struct Split {
  uint64_t m;
  Box3 left, right;
};

/// Bounds of points in four lanes (the fourth is carried along, never read).
struct PointBounds4 {
  F4 lo = F4::splat(inf_f), hi = F4::splat(-inf_f);

  void grow(F4 p) noexcept { lo = min(p, lo), hi = max(p, hi); }
  Box3 box() const noexcept {
    alignas(16) float l[4], h[4];
    lo.store(l);
    hi.store(h);
    Box3 b;
    b.grow(l, h);
    return b;
  }
};

/// Doubled centroid of an item box in lanes 0-2 (lane 3: vmin + vmax).
inline F4 centroid4(ItemBox const& b) noexcept {
  float const* v = reinterpret_cast<float const*>(&b);
  return F4::load(v) + F4::load(v + 4);
}

/// Two-ended in-place partition of slots [b, e) (sequential): those whose
/// doubled centroid p (lanes 0-2) satisfies `goes_left(p)` come first.
template <class Index, class Pred>
Split partition_sequential(Slots<Index> const& s, uint64_t b, uint64_t e, Pred const& pred) {
  // Local copies: the swaps' stores could alias `s` and the predicate's
  // captures, which GCC would then reload for every item.
  ItemBox* const box = s.box;
  Index* const id = s.id;
  Pred const goes_left = pred;
  PointBounds4 left, right;
  uint64_t i = b, j = e;  // [b, i) go left, [j, e) go right
  while (true) {
    while (i < j) {
      F4 const p = centroid4(box[i]);
      if (!goes_left(p)) {
        right.grow(p);  // slot i goes right; find a left one behind it
        break;
      }
      left.grow(p);
      ++i;
    }
    if (i == j) break;
    bool swapped = false;
    while (--j > i) {
      F4 const p = centroid4(box[j]);
      if (goes_left(p)) {
        left.grow(p);
        std::swap(box[i], box[j]);
        std::swap(id[i], id[j]);
        ++i;
        swapped = true;
        break;
      }
      right.grow(p);
    }
    if (!swapped) break;  // j == i: everything from i on goes right
  }
  return {i, left.box(), right.box()};
}

/// Reorders slots [b, e) so that those whose doubled centroid satisfies
/// `goes_left(p)` (p: F4, lanes 0-2) come first; returns the split with both sides' centroid
/// bounds (so children never rescan for them). In place. Large ranges: every
/// fixed block is partitioned on its own (in parallel), then the right-goers
/// left of the split point are swapped, in order, with the left-goers right
/// of it, the k-th with the k-th; the result depends on the block size only,
/// never on the thread count.
template <class Index, class Pred>
Split partition_slots(Slots<Index> const& s, uint64_t b, uint64_t e, Pred const& goes_left) {
  uint64_t const n = e - b;
  if (n < parallel_partition_items) return partition_sequential(s, b, e, goes_left);
  uint64_t const blocks = (n + scan_block - 1) / scan_block;
  std::vector<Split> part(blocks);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t k = r.begin(); k < r.end(); ++k)
      part[k] = partition_sequential(s, b + k * scan_block, std::min(e, b + (k + 1) * scan_block), goes_left);
  });
  Split out{b, {}, {}};
  for (uint64_t k = 0; k < blocks; ++k) {
    out.m += part[k].m - (b + k * scan_block);
    out.left.grow(part[k].left);
    out.right.grow(part[k].right);
  }
  uint64_t const mid = out.m;
  // Misplaced runs, in slot order: right-goers in [b, mid), left-goers in [mid, e).
  struct Run {
    uint64_t begin, before;  ///< first slot; misplaced slots in earlier runs
  };
  std::vector<Run> wrong_left, wrong_right;
  uint64_t nl = 0, nr = 0;
  for (uint64_t k = 0; k < blocks; ++k) {
    uint64_t const lo = b + k * scan_block, hi = std::min(e, lo + scan_block), m = part[k].m;
    uint64_t const r0 = m, r1 = std::min(hi, mid);  // right-goers left of mid
    if (r0 < r1) wrong_left.push_back({r0, nl}), nl += r1 - r0;
    uint64_t const l0 = std::max(lo, mid), l1 = m;  // left-goers right of mid
    if (l0 < l1) wrong_right.push_back({l0, nr}), nr += l1 - l0;
  }
  if (nl == 0) return out;  // nl == nr: both sides hold as many strays
  auto slot_of = [](std::vector<Run> const& runs, uint64_t k) {
    auto it = std::upper_bound(runs.begin(), runs.end(), k, [](uint64_t x, Run const& r) { return x < r.before; });
    --it;
    return std::make_pair(size_t(it - runs.begin()), it->begin + (k - it->before));
  };
  auto run_end = [](std::vector<Run> const& runs, size_t r, uint64_t total) {
    return runs[r].begin + ((r + 1 < runs.size() ? runs[r + 1].before : total) - runs[r].before);
  };
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nl, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
    auto [ri, i] = slot_of(wrong_left, r.begin());
    auto [rj, j] = slot_of(wrong_right, r.begin());
    uint64_t iend = run_end(wrong_left, ri, nl), jend = run_end(wrong_right, rj, nr);
    for (uint64_t k = r.begin(); k < r.end(); ++k) {
      if (i == iend) ++ri, i = wrong_left[ri].begin, iend = run_end(wrong_left, ri, nl);
      if (j == jend) ++rj, j = wrong_right[rj].begin, jend = run_end(wrong_right, rj, nr);
      s.swap(i++, j++);
    }
  });
  return out;
}

/// Object-median split of slots [b, e) along `axis` of the doubled
/// centroids (ties by id, so the order is total); sequential. Used for
/// degenerate and very deep ranges only.
template <class Index> Split object_median_split(Slots<Index> const& s, uint64_t b, uint64_t e, int axis) {
  uint64_t const n = e - b, half = n / 2;
  std::vector<uint64_t> order(n);
  for (uint64_t i = 0; i < n; ++i) order[i] = b + i;
  std::nth_element(order.begin(), order.begin() + int64_t(half), order.end(), [&](uint64_t x, uint64_t y) {
    float cx[3], cy[3];
    centroid2(s.box[x], cx);
    centroid2(s.box[y], cy);
    return cx[axis] < cy[axis] || (cx[axis] == cy[axis] && s.id[x] < s.id[y]);
  });
  std::vector<ItemBox> boxes(n);
  std::vector<Index> ids(n);
  for (uint64_t i = 0; i < n; ++i) boxes[i] = s.box[order[i]], ids[i] = s.id[order[i]];
  std::copy(boxes.begin(), boxes.end(), s.box + b);
  std::copy(ids.begin(), ids.end(), s.id + b);
  uint64_t const m = b + half;
  return {m, centroid_bounds(s.box, b, m), centroid_bounds(s.box, m, e)};
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
/// children at local indices, bounds and ranges set) or an upper node with
/// two subtrees. `fit` is the subtree root's bounds and value range,
/// `depth` the absolute depth of its deepest leaf.
struct Subtree {
  Node const* nodes = nullptr;  ///< a private buffer's `count` nodes (in a SubtreePool), or none
  NodeRange const* ranges = nullptr;
  uint64_t count = 0;
  std::unique_ptr<Subtree> child[2];
  Bounds4 fit = Bounds4::empty();
  uint32_t depth = 0;
  uint64_t total = 0;
};

/// Where the private buffers of the subtrees live until `assemble` copies
/// them out: each is built in its thread's scratch vectors (reused, so warm
/// after the first) and then copied into 4 MB blocks of huge pages, filled
/// one after another. In a fresh process this touches as few new pages as
/// the nodes need; a vector per subtree took ~500-2,500 first-write faults
/// on a 600k-cell tree (PROFILE.md: ~15 us each). A thread's scratch is safe
/// to reuse because a local build makes no TBB call (ranges of at most
/// local_build_items are split sequentially): no other task can run on the
/// thread in the middle of one.
class SubtreePool {
 public:
  struct Scratch {
    NodeVector nodes;
    std::vector<NodeRange> ranges;
  };
  Scratch& scratch() { return scratch_.local(); }

  /// Copies `n` nodes and ranges into the pool; returns where they are.
  std::pair<Node const*, NodeRange const*> keep(Node const* nodes, NodeRange const* ranges, uint64_t n) {
    Node* to = nullptr;
    NodeRange* to_ranges = nullptr;
    {
      std::lock_guard<std::mutex> lock(m_);
      if (blocks_.empty() || used_ + n > blocks_.back().nodes.size()) {
        Block b;
        b.nodes.resize(std::max<uint64_t>(block_nodes, n));
        b.ranges.resize(b.nodes.size());
        blocks_.push_back(std::move(b));
        used_ = 0;
      }
      to = blocks_.back().nodes.data() + used_;
      to_ranges = blocks_.back().ranges.data() + used_;
      used_ += n;
    }
    // Map the pages this copy writes in one call each (not a fresh block's
    // whole 4 MB: the last block is mostly unused, a small mesh's too).
    populate_pages(to, n * sizeof(Node));
    populate_pages(to_ranges, n * sizeof(NodeRange));
    std::copy(nodes, nodes + n, to);
    std::copy(ranges, ranges + n, to_ranges);
    return {to, to_ranges};
  }

 private:
  static constexpr uint64_t block_nodes = large_buffer_bytes / sizeof(Node);  // advised as huge pages
  struct Block {
    NodeVector nodes;
    LargeVector<NodeRange> ranges;
  };
  std::mutex m_;
  std::deque<Block> blocks_;
  uint64_t used_ = 0;
  tbb::enumerable_thread_specific<Scratch> scratch_;
};

// Splitter interface: `Split split(b, e, depth, cb)`, cb = bounds of the
// doubled centroids of slots [b, e), returns m in (b, e) after reordering
// slots [b, e) so [b, m) and [m, e) are the children (with their centroid
// bounds), or m = e to make [b, e) a leaf. It must split every range larger
// than the leaf size. `Bounds4 leaf_fit(b, e)`: bounds and range of the
// items in slots [b, e). Optional `void prepare(b, e) const`: called once
// before the private subtree of slots [b, e) is built (e.g. to prefetch).

/// Builds the subtree of slots [b, e) into `nodes`/`ranges` at `self`,
/// fitting bounds and ranges on the way back up; returns its deepest leaf's depth.
template <class Splitter>
uint32_t build_local(Splitter& s, uint64_t b, uint64_t e, uint32_t depth, Box3 const& cb, uint32_t self,
                     NodeVector& nodes, std::vector<NodeRange>& ranges, Bounds4& fit) {
  Split const sp = s.split(b, e, depth, cb);
  if (sp.m == e) {
    fit = s.leaf_fit(b, e);
    nodes[self].set_leaf(b, uint32_t(e - b));
    ranges[self] = fit.store(nodes[self]);
    return depth;
  }
  auto const c = uint32_t(nodes.size());
  // emplace_back, not resize: resize is an out-of-line call per node pair.
  nodes.emplace_back(), nodes.emplace_back();
  ranges.emplace_back(), ranges.emplace_back();
  nodes[self].set_inner(c);
  Bounds4 r;  // set by the callee
  uint32_t const dl = build_local(s, b, sp.m, depth + 1, sp.left, c, nodes, ranges, fit);
  uint32_t const dr = build_local(s, sp.m, e, depth + 1, sp.right, c + 1, nodes, ranges, r);
  fit.grow(r);
  ranges[self] = fit.store(nodes[self]);
  return std::max(dl, dr);
}

/// Whether a splitter has `prepare(b, e)`, called before a private subtree of slots [b, e) is built.
template <class S, class = void> struct has_prepare : std::false_type {};
template <class S>
struct has_prepare<S, std::void_t<decltype(std::declval<S const&>().prepare(uint64_t(0), uint64_t(0)))>>
    : std::true_type {};

template <class Splitter>
std::unique_ptr<Subtree> build_upper(Splitter& s, uint64_t b, uint64_t e, uint32_t depth, Box3 const& cb,
                                     SubtreePool& pool) {
  auto t = std::make_unique<Subtree>();
  if (e - b <= local_build_items) {
    SubtreePool::Scratch& scratch = pool.scratch();
    // About 2 (e - b) / leaf nodes: reserve so the recursion rarely reallocates.
    scratch.nodes.reserve(2 * (e - b) / 3 + 8);
    scratch.ranges.reserve(2 * (e - b) / 3 + 8);
    scratch.nodes.resize(1);
    scratch.ranges.resize(1);
    if constexpr (has_prepare<Splitter>::value) s.prepare(b, e);
    t->depth = build_local(s, b, e, depth, cb, 0, scratch.nodes, scratch.ranges, t->fit);
    t->count = scratch.nodes.size();
    std::tie(t->nodes, t->ranges) = pool.keep(scratch.nodes.data(), scratch.ranges.data(), t->count);
    scratch.nodes.clear();
    scratch.ranges.clear();
    return t;
  }
  Split const sp = s.split(b, e, depth, cb);  // never a leaf: e - b > local_build_items >= max leaf
  tbb::parallel_invoke([&] { t->child[0] = build_upper(s, b, sp.m, depth + 1, sp.left, pool); },
                       [&] { t->child[1] = build_upper(s, sp.m, e, depth + 1, sp.right, pool); });
  t->fit = t->child[0]->fit;
  t->fit.grow(t->child[1]->fit);
  t->depth = std::max(t->child[0]->depth, t->child[1]->depth);
  return t;
}

inline uint64_t count_nodes(Subtree& t) {
  if (t.nodes) return t.total = t.count;
  return t.total = 1 + count_nodes(*t.child[0]) + count_nodes(*t.child[1]);
}

struct PlaceJob {
  Subtree const* tree;
  uint64_t self;  ///< final index of the subtree's root
  uint64_t next;  ///< first final index of its other nodes
};

/// Depth-first layout: a root at `self`, its two children at next and
/// next + 1, then the left subtree's other nodes, then the right one's.
inline void place(Subtree const& t, uint64_t self, uint64_t next, Node* out, NodeRange* ranges,
                  std::vector<PlaceJob>& jobs) {
  if (t.nodes) {
    jobs.push_back({&t, self, next});
    return;
  }
  out[self].set_inner(uint32_t(next));
  ranges[self] = t.fit.store(out[self]);
  uint64_t const left_rest = next + 2, right_rest = left_rest + (t.child[0]->total - 1);
  place(*t.child[0], next, left_rest, out, ranges, jobs);
  place(*t.child[1], next + 1, right_rest, out, ranges, jobs);
}

/// The final node and range arrays of a built subtree.
inline void assemble(Subtree& root, NodeVector& nodes, ValueRanges& ranges) {
  uint64_t const total = count_nodes(root);
  if (total >= uint64_t(Node::inner)) throw Error("BVH would need more than 2^32 - 2 nodes");
  nodes.resize(total);
  populate_parallel(nodes.data(), total * sizeof(Node));  // every node is written below
  ranges.resize(total);
  std::vector<PlaceJob> jobs;
  place(root, 0, 1, nodes.data(), ranges.data(), jobs);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, jobs.size(), 1), [&](tbb::blocked_range<size_t> const& r) {
    for (size_t j = r.begin(); j < r.end(); ++j) {
      PlaceJob const& job = jobs[j];
      Node const* local = job.tree->nodes;
      NodeRange const* local_ranges = job.tree->ranges;
      for (size_t i = 0; i < job.tree->count; ++i) {
        Node n = local[i];
        if (!n.is_leaf()) n.set_inner(uint32_t(job.next + n.first - 1));
        uint64_t const at = i == 0 ? job.self : job.next + i - 1;
        nodes[at] = n;
        ranges[at] = local_ranges[i];
      }
    }
  });
}

/// Subtrees this deep below the root are fitted as parallel tasks (64).
inline constexpr uint32_t parallel_fit_depth = 6;

/// The value range of a leaf from `slot_range(s)` (the NodeRange of item-list slot s).
template <class SlotRange> struct SlotLeafRange {
  SlotRange const& slot_range;

  NodeRange operator()(uint64_t /*node*/, Node const& n) const {
    NodeRange r{inf_f, -inf_f};
    uint64_t const first = n.first_item();
    for (uint64_t s = first; s < first + n.item_count(); ++s) {
      NodeRange const x = slot_range(s);
      r.vmin = std::min(r.vmin, x.vmin);
      r.vmax = std::max(r.vmax, x.vmax);
    }
    return r;
  }
};

/// Value range of node `i`: `leaf_range(i, node)` for a leaf, else the union of its children's.
template <class LeafRange>
inline void fit_node(Node const* nodes, NodeRange* ranges, LeafRange const& leaf_range, uint64_t i) {
  Node const& n = nodes[i];
  if (n.is_leaf()) {
    ranges[i] = leaf_range(i, n);
    return;
  }
  uint64_t const l = n.left(), rgt = n.right();
  ranges[i] = {std::min(ranges[l].vmin, ranges[rgt].vmin), std::max(ranges[l].vmax, ranges[rgt].vmax)};
}

/// One past the last index of the nodes below inner node `i`. Every layout
/// the builders write (build_local, assemble) puts a node's children and all
/// their descendants in one block [left(i), end) after it: the children
/// pair, then the left child's block, then the right child's; so the block
/// ends where the right child's does, or the left child's when the right one
/// is a leaf.
inline uint64_t subtree_end(Node const* nodes, uint64_t i) {
  for (;;) {
    uint64_t const l = nodes[i].left(), r = l + 1;
    if (!nodes[r].is_leaf()) i = r;
    else if (!nodes[l].is_leaf()) i = l;
    else return l + 2;
  }
}

/// Sets the value range of node `i` and everything below, a leaf's from
/// `leaf_range(node, Node const&)` (see SlotLeafRange); bounds and topology
/// untouched. Below the task depth a subtree is one reverse sweep over its
/// block of nodes (children come after their parent), no recursion; leaves
/// cover consecutive slots, so a slot-ordered source is read in order.
template <class LeafRange>
void fit_ranges(Node const* nodes, NodeRange* ranges, LeafRange const& leaf_range, uint64_t i, uint32_t depth) {
  Node const& n = nodes[i];
  if (!n.is_leaf()) {
    if (depth < parallel_fit_depth) {
      tbb::parallel_invoke([&] { fit_ranges(nodes, ranges, leaf_range, n.left(), depth + 1); },
                           [&] { fit_ranges(nodes, ranges, leaf_range, n.right(), depth + 1); });
    } else {
      for (uint64_t k = subtree_end(nodes, i); k-- > n.left();) fit_node(nodes, ranges, leaf_range, k);
    }
  }
  fit_node(nodes, ranges, leaf_range, i);
}

}  // namespace detail
}  // namespace cellray
