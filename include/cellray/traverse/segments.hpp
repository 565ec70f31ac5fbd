#pragma once
// Cell segments along rays: the cells a ray crosses inside a window
// [t_lo, t_hi], with their [t_in, t_out] and the scalar field along each
// segment, front to back, so a renderer can integrate cell by cell (exact
// cell boundaries) instead of point sampling. Not in the paper. ISA units
// only.
//
// The field along a segment, as a function of lambda = (t - t_in) /
// (t_out - t_in) in [0, 1]:
// * tets: linear between the clip's entry and exit values (exact);
// * hexes: the cubic through the field's values on the ray at lambda = 0,
//   1/3, 2/3, 1 (ends: the clip's canonical face values; interior: trilinear
//   inversions warm-started on the parametric segment, as the exact iso root
//   of cells/hex.hpp does). Exact for parallelepipeds (the field along a ray
//   is then a cubic); for general hexes the field along a ray is smooth but
//   not a polynomial, and the cubic's error is measured against the
//   reference renderer (tests/test_render_dvr.cpp, docs/accuracy.md). The
//   chord between entry and exit values, used before, plateaued at 0.18/255
//   RMSE on disk_out_ref.
// Optionally the world-space gradient along the segment too (DVR gradient
// shading): tets constant, hexes the cubic through the analytic gradients
// (J^-T grad_uvw) at the same four points, again exact for parallelepipeds
// (a quadratic in lambda there).

#include <algorithm>
#include <array>
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

/// A cell segment with the field along it (see the file comment). A type of
/// the ISA unit, so containers and sorts instantiated for it are too (ODR).
struct FieldSegment {
  CellSegment s;
  float value[4];        ///< value(lambda) = value[0] + lambda (value[1] + lambda (value[2] + lambda value[3]))
  float gradient[3][4];  ///< per world axis, same form; filled only when the query asks for gradients

  /// lambda of t on this segment (0 for an empty segment).
  float lambda(float t) const {
    float const len = s.t_out - s.t_in;
    return len > 0.f ? (t - s.t_in) / len : 0.f;
  }
  float value_at(float lam) const { return value[0] + lam * (value[1] + lam * (value[2] + lam * value[3])); }
  void gradient_at(float lam, float g[3]) const {
    for (int k = 0; k < 3; ++k)
      g[k] = gradient[k][0] + lam * (gradient[k][1] + lam * (gradient[k][2] + lam * gradient[k][3]));
  }
};

template <class A, int N> struct SegmentQuery {
  static constexpr int W = width<A>;
  TreeView const* tree_;
  CellMesh<N> const* mesh_;
  RayPacket<A> r;  ///< a copy: the query outlives a packet (reset binds the next)
  ValueWindows const& windows;
  vfloat<A> lo, hi;  ///< window per lane
  /// min(hi, cut) per lane: a cell entered at or beyond it cannot be kept,
  /// so the traversal's t_hi() and the cell culls stop there (a full list
  /// prunes the subtrees behind its cut).
  vfloat<A> limit;
  bool gradients;    ///< fill FieldSegment::gradient
  int count[W];
  alignas(64) float cut[W];  ///< smallest t_in that did not fit (inf: none)
  FieldSegment seg[W][max_segments];
  float key[W][max_segments];  ///< seg[l][i].s.t_in, contiguous for the farthest-segment scan
  uint8_t order[W][max_segments];  ///< after sort(): seg[l][order[l][i]] front to back

  SegmentQuery(TreeView const& t, CellMesh<N> const& m, RayPacket<A> const& rays, ValueWindows const& w,
               vfloat<A> const& t_lo, vfloat<A> const& t_hi, bool want_gradients = false)
      : tree_(&t), mesh_(&m), r(rays), windows(w), lo(t_lo), hi(t_hi), limit(t_hi), gradients(want_gradients) {
    for (int l = 0; l < W; ++l) count[l] = 0, cut[l] = std::numeric_limits<float>::infinity();
  }

  /// Another packet, window or part: what the constructor does, without a
  /// new allocation (a renderer keeps one query per tile).
  void reset(TreeView const& t, CellMesh<N> const& m, RayPacket<A> const& rays, vfloat<A> const& t_lo,
             vfloat<A> const& t_hi) {
    tree_ = &t, mesh_ = &m, r = rays, lo = t_lo, hi = t_hi, limit = t_hi;
    for (int l = 0; l < W; ++l) count[l] = 0, cut[l] = std::numeric_limits<float>::infinity();
  }
  TreeView const& tree() const { return *tree_; }
  CellMesh<N> const& mesh() const { return *mesh_; }

  bool done() const { return false; }
  bool node_relevant(float vmin, float vmax) const { return vmin <= vmax && windows.overlaps(vmin, vmax); }
  vmask<A> relevant(vfloat<A> const& vmin, vfloat<A> const& vmax) const { return windows_overlap<A>(windows, vmin, vmax); }
  vfloat<A> t_lo() const { return lo; }
  vfloat<A> t_hi() const { return limit; }

  /// Keeps the `max_segments` segments with the smallest t_in per lane;
  /// `cut` becomes the smallest t_in of those dropped, so every segment with
  /// t_in < cut is kept (arrival order is the traversal's, not t's).
  void add(int l, FieldSegment const& s) {
    if (int const i = slot(l, s.s.t_in); i >= 0) seg[l][i] = s;
  }

  /// Where lane l keeps a segment entered at t_in (add's rule), its key
  /// already set; -1: not kept. The caller fills seg[l][slot] in place.
  int slot(int l, float t_in) {
    if (t_in >= cut[l]) return -1;
    if (count[l] < max_segments) {
      key[l][count[l]] = t_in;
      return count[l]++;
    }
    int far = 0;
    for (int i = 1; i < max_segments; ++i)
      if (key[l][i] > key[l][far]) far = i;
    if (t_in >= key[l][far]) {
      cut[l] = t_in;  // t_in < cut here
      return -1;
    }
    cut[l] = std::min(cut[l], key[l][far]);
    key[l][far] = t_in;
    return far;
  }

  /// `m`: the lanes whose window may cross the cell (its value range is
  /// visible there; see leaf and leaf_items).
  void visit(CellCorners<A, N> const& c, vmask<A> m, vint<A> const& cells) {
    using Ops = CellOps<A, N>;
    RayBatch<A> const ray = ray_batch(r);
    // The window clip: most cells of a leaf miss every lane, and it skips
    // the face-value interpolation for them (bit-identical where it hits).
    typename Ops::Clip const k = Ops::clip_window(ray, c, m, lo, t_hi());
    m = k.hit && !has_nan_value(c);
    uint32_t const mb = simd::movemask(m);
    if (!mb) return;
    isa_detail::Cubic<A> f, g[3];
    Ops::segment_field(ray, c, k, m, f, gradients ? g : nullptr);
    auto const tin = simd::to_array<A>(k.t_in), tout = simd::to_array<A>(k.t_out);
    auto const sin = simd::to_array<A>(k.s_in), sout = simd::to_array<A>(k.s_out);
    auto const cell = simd::to_array<A>(cells);
    auto coefficients = [](isa_detail::Cubic<A> const& p, std::array<float, W> (&out)[4]) {
      out[0] = simd::to_array<A>(p.c0), out[1] = simd::to_array<A>(p.c1);
      out[2] = simd::to_array<A>(p.c2), out[3] = simd::to_array<A>(p.c3);
    };
    std::array<float, W> va[4], ga[3][4];
    coefficients(f, va);
    if (gradients)
      for (int a = 0; a < 3; ++a) coefficients(g[a], ga[a]);
    bool cut_fell = false;
    for (uint32_t b = mb; b; b &= b - 1) {
      int const l = __builtin_ctz(b);
      float const vmin = std::min(sin[l], sout[l]), vmax = std::max(sin[l], sout[l]);
      // Tets are linear along the ray: the segment's values lie between its
      // end values, so a transparent range is skipped here too. Hexes may
      // exceed their end values inside; they are always kept.
      if (Ops::linear_on_ray && !windows.overlaps(vmin, vmax)) continue;
      float const before = cut[l];
      int const i = slot(l, tin[l]);
      cut_fell = cut_fell || cut[l] < before;
      if (i < 0) continue;
      FieldSegment& fs = seg[l][i];  // written in place: 88 bytes, the gradient only when asked for
      fs.s = CellSegment{tin[l], tout[l], sin[l], sout[l], 0, uint64_t(uint32_t(cell[l]))};
      for (int k = 0; k < 4; ++k) fs.value[k] = va[k][size_t(l)];
      if (gradients)
        for (int a = 0; a < 3; ++a)
          for (int k = 0; k < 4; ++k) fs.gradient[a][k] = ga[a][k][size_t(l)];
    }
    if (cut_fell) limit = simd::min(hi, simd::load<A>(cut));
  }

  // A cell whose corner values all map to zero opacity is transparent
  // throughout (tet: linear; hex: trilinear, a convex combination of its
  // corners), so it is dropped before the clip: empty-space skipping per
  // cell, not only per node. Packet leaves test it on the scalar values
  // before loading positions, then cull on the cell's box computed in
  // scalar (45% of the cells a component8 DVR packet reads are missed by
  // every lane: they are not ordered and broadcast; 0.97x frame time there,
  // boxturb 0.98x, a generated 2M-tet mesh 1.015x).
  void leaf(uint64_t first, uint32_t n, vmask<A> const& m) {
    for_each_leaf_cell<A, N>(
        *tree_, *mesh_, r, first, n, m, lo, [this](float vmin, float vmax) { return windows.overlaps(vmin, vmax); },
        [this] { return t_hi(); },
        [this](CellCorners<A, N> const& c, vmask<A> const& in_box, uint64_t, uint64_t cell) {
          visit(c, in_box, vint<A>(int32_t(cell)));
        });
  }
  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    vint<A> const cv = slot_cells<A>(*tree_, slots, m);
    CellCorners<A, N> const c = gather_corners<A, N>(*mesh_, cv, m);
    vfloat<A> vmin = c.s[0], vmax = c.s[0];
    for (int i = 1; i < N; ++i) vmin = simd::min(vmin, c.s[i]), vmax = simd::max(vmax, c.s[i]);
    vmask<A> const visible = m && windows_overlap<A>(windows, vmin, vmax);
    if (simd::any(visible)) visit(c, visible, cv);
  }

  /// Orders each lane's segments front to back: seg[l][order[l][i]] is the
  /// i-th by t_in. An insertion sort of one-byte indices on the keys: the
  /// traversal delivers segments nearly in order, and nothing large moves.
  void sort() {
    for (int l = 0; l < W; ++l) {
      float const* k = key[l];
      uint8_t* o = order[l];
      for (int i = 0; i < count[l]; ++i) {
        int j = i;
        while (j > 0 && k[o[j - 1]] > k[i]) o[j] = o[j - 1], --j;
        o[j] = uint8_t(i);
      }
    }
  }
};

template <class A, int N>
inline void collect_segments(SegmentQuery<A, N>& q, vmask<A> const& active, Traversal how, int threshold) {
  switch (how) {
    case Traversal::packet: traverse_packet<A>(q.tree(), q.r, active, q); break;
    case Traversal::hybrid: traverse_packet<A>(q.tree(), q.r, active, q, 0, threshold); break;
    case Traversal::spmd: traverse_spmd<A>(q.tree(), q.r, active, q); break;
  }
  q.sort();
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
