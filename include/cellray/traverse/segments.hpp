#pragma once
// Cell segments along rays: the cells a ray crosses inside a window
// [t_lo, t_hi], with their [t_in, t_out] and entry/exit values, front to
// back, so a renderer can integrate cell by cell (exact cell boundaries)
// instead of point sampling. Not in the paper. ISA units only.

#include <algorithm>
#include <cstdint>
#include <limits>

#include "cell_ops.hpp"
#include "sample.hpp"
#include "traverse.hpp"
#include "tree_view.hpp"

namespace cellray {

/// Segments kept per ray and window; a fuller window is cut short at the
/// first segment that did not fit, so nothing is lost (see SegmentQuery).
inline constexpr int max_segments = 48;

inline namespace CELLRAY_ISA_NS {

template <class A, int N> struct SegmentQuery {
  static constexpr int W = width<A>;
  TreeView const& tree;
  CellMesh<N> const& mesh;
  RayPacket<A> const& r;
  ValueWindows const& windows;
  vfloat<A> lo, hi;  ///< window per lane
  int count[W];
  float cut[W];  ///< smallest t_in that did not fit (inf: none)
  CellSegment seg[W][max_segments];

  SegmentQuery(TreeView const& t, CellMesh<N> const& m, RayPacket<A> const& rays, ValueWindows const& w,
               vfloat<A> const& t_lo, vfloat<A> const& t_hi)
      : tree(t), mesh(m), r(rays), windows(w), lo(t_lo), hi(t_hi) {
    for (int l = 0; l < W; ++l) count[l] = 0, cut[l] = std::numeric_limits<float>::infinity();
  }

  bool done() const { return false; }
  bool node_relevant(float vmin, float vmax) const { return vmin <= vmax && windows.overlaps(vmin, vmax); }
  vmask<A> relevant(vfloat<A> const& vmin, vfloat<A> const& vmax) const { return windows_overlap<A>(windows, vmin, vmax); }
  vfloat<A> t_lo() const { return lo; }
  vfloat<A> t_hi() const { return hi; }

  /// Keeps the `max_segments` segments with the smallest t_in per lane.
  void add(int l, CellSegment const& s) {
    if (s.t_in >= cut[l]) return;
    if (count[l] < max_segments) {
      seg[l][count[l]++] = s;
      return;
    }
    int far = 0;
    for (int i = 1; i < max_segments; ++i)
      if (seg[l][i].t_in > seg[l][far].t_in) far = i;
    float const dropped = std::min(s.t_in, seg[l][far].t_in);
    if (s.t_in < seg[l][far].t_in) seg[l][far] = s;
    cut[l] = std::min(cut[l], dropped);
  }

  void visit(CellCorners<A, N> const& c, vmask<A> m, vint<A> const& cells) {
    using Ops = CellOps<A, N>;
    typename Ops::Clip const k = Ops::clip(ray_batch(r), c);
    m = m && k.hit && !has_nan_value(c) && k.t_out >= lo && k.t_in <= hi;
    uint32_t const mb = simd::movemask(m);
    if (!mb) return;
    auto const tin = simd::to_array<A>(k.t_in), tout = simd::to_array<A>(k.t_out);
    auto const sin = simd::to_array<A>(k.s_in), sout = simd::to_array<A>(k.s_out);
    auto const cell = simd::to_array<A>(cells);
    for (uint32_t b = mb; b; b &= b - 1) {
      int const l = __builtin_ctz(b);
      float const vmin = std::min(sin[l], sout[l]), vmax = std::max(sin[l], sout[l]);
      // Tets are linear along the ray: the segment's values lie between its
      // end values, so a transparent range is skipped here too. Hexes may
      // exceed their end values inside; they are always kept.
      if (N == 4 && !windows.overlaps(vmin, vmax)) continue;
      add(l, CellSegment{tin[l], tout[l], sin[l], sout[l], 0, uint64_t(uint32_t(cell[l]))});
    }
  }

  void leaf(uint64_t first, uint32_t n, vmask<A> const& m) {
    for (uint64_t i = first; i < first + n; ++i) {
      uint64_t const cell = tree.item(i);
      visit(broadcast_corners<A, N>(mesh, cell), m, vint<A>(int32_t(cell)));
    }
  }
  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    vint<A> const cv = slot_cells<A>(tree, slots, m);
    visit(gather_corners<A, N>(mesh, cv, m), m, cv);
  }

  /// Sorts each lane's segments front to back.
  void sort() {
    for (int l = 0; l < W; ++l)
      std::sort(seg[l], seg[l] + count[l], [](CellSegment const& a, CellSegment const& b) { return a.t_in < b.t_in; });
  }
};

template <class A, int N>
inline void collect_segments(SegmentQuery<A, N>& q, vmask<A> const& active, Traversal how, int threshold) {
  switch (how) {
    case Traversal::packet: traverse_packet<A>(q.tree, q.r, active, q); break;
    case Traversal::hybrid: traverse_packet<A>(q.tree, q.r, active, q, 0, threshold); break;
    case Traversal::spmd: traverse_spmd<A>(q.tree, q.r, active, q); break;
  }
  q.sort();
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
