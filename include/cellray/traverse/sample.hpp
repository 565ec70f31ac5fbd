#pragma once
// Volume samples along rays (Rathke 2015 §7): the value at t0 + g * step for
// g in [0, G), located through the BVH with a backtracking stack; the G
// samples of a ray share one traversal (§7.2). Samples outside the mesh (or
// in cells with NaN values) stay NaN. ISA units only.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "cell_ops.hpp"
#include "traverse.hpp"
#include "tree_view.hpp"

namespace cellray {

inline constexpr int max_sample_group = 32;

inline namespace CELLRAY_ISA_NS {

/// Packet leaves can drop a cell whose box the rays cross between two samples
/// (SampleQuery::sample_in_box). That pays where samples are sparser than
/// cells (DVR of a generated 5M-tet mesh at the target's step: half the frame
/// time) and costs where cells are longer than the step (nearly every box
/// holds a sample: component8 3-4% slower with it always on). So it is
/// measured: on for the first `trial` cells whose box the rays meet, then
/// kept only if it dropped at least a quarter of them. The samples found are
/// the same either way.
struct SampleCull {
  static constexpr uint32_t trial = 256;
  bool on = true;
  uint32_t tested = 0, dropped = 0;
  void count(bool drop) {
    ++tested;
    dropped += drop;
    if (tested == trial) on = dropped * 4 >= tested;
  }
};

/// One group of G samples per lane: t_g = t0 + g * step.
template <class A, int N> struct SampleQuery {
  static constexpr int W = width<A>;
  TreeView const& tree;
  CellMesh<N> const& mesh;
  RayPacket<A> const& r;
  ValueWindows const& windows;
  vfloat<A> t0;      ///< first sample of the group, per lane
  float step;
  int group;         ///< G, 1..32
  vfloat<A> t_first, t_last;  ///< search interval (first and last pending sample)
  alignas(64) float values[max_sample_group][W];
  uint32_t pending[max_sample_group];  ///< lanes still looking for sample g
  /// Optional outputs for a renderer (off by default; set before traversal).
  /// `want_interval`: the ray's clip interval [cell_in, cell_out] of the cell
  /// each sample was found in (DVR clips the step at the mesh boundary with
  /// it); `want_gradient`: the analytic world-space gradient there (tets:
  /// constant; hexes: J^-T grad_uvw at the located coordinates).
  bool want_interval = false, want_gradient = false;
  alignas(64) float cell_in[max_sample_group][W], cell_out[max_sample_group][W];
  alignas(64) float grad[3][max_sample_group][W];
  /// Whether packet leaves drop cells that hold none of the samples (see
  /// SampleCull); a renderer shares one across the queries of a tile.
  SampleCull* cull = nullptr;
  SampleCull own_cull;

  SampleQuery(TreeView const& t, CellMesh<N> const& m, RayPacket<A> const& rays, ValueWindows const& w,
              vfloat<A> const& first_t, float s, int g, vmask<A> const& active)
      : tree(t), mesh(m), r(rays), windows(w), t0(first_t), step(s), group(g) {
    uint32_t const bits = simd::movemask(active);
    for (int k = 0; k < group; ++k) {
      pending[k] = bits;
      for (int l = 0; l < W; ++l) values[k][l] = std::numeric_limits<float>::quiet_NaN();
    }
    t_first = t0;
    t_last = t0 + vfloat<A>(step * float(group - 1));
  }

  bool done() const {
    uint32_t any = 0;
    for (int k = 0; k < group; ++k) any |= pending[k];
    return any == 0;
  }
  bool node_relevant(float vmin, float vmax) const { return vmin <= vmax && windows.overlaps(vmin, vmax); }
  vmask<A> relevant(vfloat<A> const& vmin, vfloat<A> const& vmax) const { return windows_overlap<A>(windows, vmin, vmax); }
  vfloat<A> t_lo() const { return t_first; }
  vfloat<A> t_hi() const { return t_last; }

  /// Samples of the lanes in `m` that fall in cell c (one cell per lane).
  /// Single points: containment and value from point location (the
  /// kernels' face rule gives a point on a shared face to exactly one cell).
  /// Groups (and DVR's intervals) clip the ray first. Tets then take the
  /// samples in [t_in, t_out) of the clip with the field linear between the
  /// clip's end values (exact for a tet; neighbours compute bit-identical t
  /// for a shared face, so a sample on it still lands in exactly one cell,
  /// and no point location is needed: 11% fewer instructions per DVR frame,
  /// callgrind AVX2, component8 d400). Hexes locate each sample inside the
  /// widened clip interval.
  void visit(CellCorners<A, N> const& c, vmask<A> m) {
    using Ops = CellOps<A, N>;
    m = m && !has_nan_value(c);
    vfloat<A> t_in(-std::numeric_limits<float>::infinity()), t_out(std::numeric_limits<float>::infinity());
    vfloat<A> clip_in = t_in, clip_out = t_out;
    vfloat<A> s_in(0.f), s_slope(0.f);  // tets: the field along the ray, s_in + (t - clip_in) s_slope
    bool const by_clip = Ops::linear_on_ray && (group > 1 || want_interval);
    if (group > 1 || want_interval) {
      typename Ops::Clip const k = Ops::clip(ray_batch(r), c);
      if (by_clip) {
        vfloat<A> const len = k.t_out - k.t_in;
        s_in = k.s_in;
        s_slope = simd::select(len > vfloat<A>(0.f), (k.s_out - k.s_in) / len, vfloat<A>(0.f));
      }
      vfloat<A> const margin = vfloat<A>(1e-4f) * simd::abs(k.t_out - k.t_in) + vfloat<A>(1e-30f);
      clip_in = k.t_in, clip_out = k.t_out;
      t_in = k.t_in - margin;
      t_out = k.t_out + margin;
      m = m && k.hit && t_out >= t_first && t_in <= t_last;
    }
    uint32_t const mb = simd::movemask(m);
    if (!mb) return;
    // Only the samples some lane's widened clip interval can hold (one more
    // on each side for the rounding of the division; the test below decides).
    int g_first = 0, g_last = group - 1;
    if (group > 1) {
      vfloat<A> const inv(1.f / step);
      auto const lo_g = simd::to_array<A>((t_in - t0) * inv), hi_g = simd::to_array<A>((t_out - t0) * inv);
      float a = std::numeric_limits<float>::infinity(), b = -a;
      for (uint32_t bits = mb; bits; bits &= bits - 1) {
        int const l = __builtin_ctz(bits);
        a = std::min(a, lo_g[size_t(l)]), b = std::max(b, hi_g[size_t(l)]);
      }
      if (!(a <= float(group)) || !(b >= -1.f)) return;  // (NaN only when every lane's is)
      g_first = std::max(0, int(std::floor(std::max(a, -2.f))) - 1);
      g_last = std::min(group - 1, int(std::ceil(std::min(b, float(group)))) + 1);
    }
    for (int g = g_first; g <= g_last; ++g) {
      if (!(pending[g] & mb)) continue;
      vfloat<A> const t = t0 + vfloat<A>(step * float(g));
      alignas(64) float v[W];
      uint32_t found;
      Located<A> loc;
      if (by_clip) {
        // A tet holds the samples in [t_in, t_out) of its clip: the
        // neighbour across a face computes the same t for it, so a sample on
        // a shared face belongs to exactly one cell, as with locate_tet.
        found = simd::movemask(m && simd::mask_from_bits<A>(pending[g]) && t >= clip_in && t < clip_out);
        if (!found) continue;
        simd::store(v, s_in + (t - clip_in) * s_slope);
      } else {
        vmask<A> in = m && simd::mask_from_bits<A>(pending[g]) && t >= t_in && t <= t_out;
        if (simd::none(in)) continue;
        loc = Ops::locate(PointBatch<A>{r.ox + t * r.dx, r.oy + t * r.dy, r.oz + t * r.dz}, c);
        found = simd::movemask(in && loc.inside);
        if (!found) continue;
        simd::store(v, loc.value);
      }
      for (uint32_t b = found; b; b &= b - 1) values[g][__builtin_ctz(b)] = v[__builtin_ctz(b)];
      pending[g] &= ~found;
      if (want_interval) store_lanes(found, clip_in, cell_in[g]), store_lanes(found, clip_out, cell_out[g]);
      if (want_gradient) {
        Vec3<A> const gr = Ops::gradient_at(c, by_clip ? Vec3<A>{} : loc.param);
        store_lanes(found, gr.x, grad[0][g]), store_lanes(found, gr.y, grad[1][g]), store_lanes(found, gr.z, grad[2][g]);
      }
    }
  }

  static void store_lanes(uint32_t lanes, vfloat<A> const& x, float* out) {
    alignas(64) float tmp[W];
    simd::store(tmp, x);
    for (uint32_t b = lanes; b; b &= b - 1) out[__builtin_ctz(b)] = tmp[__builtin_ctz(b)];
  }

  // As in segments.hpp: a cell whose corner values all map to zero opacity
  // holds no visible sample (a sample there would count as transparent, as
  // the node-level value skip already treats whole subtrees), and a cell
  // whose box no lane's search interval meets (or, with SampleCull on, no
  // lane's sample lies in) holds none of the group: both are dropped before
  // the cell is clipped.
  void leaf(uint64_t first, uint32_t count, vmask<A> const& m) {
    for (uint64_t i = first; i < first + count; ++i) {
      ScalarCorners<N> k;
      read_corner_values(mesh, tree.item(i), k);
      if (!windows.overlaps(k.lo, k.hi)) continue;  // false for NaN
      order_corners(mesh.vertex_count(), k);
      CellCorners<A, N> const c = broadcast<A, N>(mesh, k);
      vmask<A> in_box;
      SampleCull& sc = cull ? *cull : own_cull;
      if (sc.on) {
        vmask<A> box;
        in_box = m && sample_in_box(c, box);
        if (simd::any(m && box)) sc.count(simd::none(in_box));
      } else {
        in_box = m && cell_box_hit<A, N>(r, c, t_first, t_last);
      }
      if (simd::any(in_box)) visit(c, in_box);
    }
  }

  /// Lanes for which a sample t0 + g * step (0 <= g < G) lies in the part
  /// of the ray inside the cell's box, widened for rounding (a sample in
  /// the cell is in its box; a wider interval only clips more); `box`: the
  /// lanes whose search interval meets the box (cell_box_hit's test).
  vmask<A> sample_in_box(CellCorners<A, N> const& c, vmask<A>& box) const {
    vfloat<A> lo[3], hi[3];
    cell_box(c, lo, hi);
    vfloat<A> const ax = (lo[0] - r.ox) * r.rx, bx = (hi[0] - r.ox) * r.rx;
    vfloat<A> const ay = (lo[1] - r.oy) * r.ry, by = (hi[1] - r.oy) * r.ry;
    vfloat<A> const az = (lo[2] - r.oz) * r.rz, bz = (hi[2] - r.oz) * r.rz;
    vfloat<A> const tn = simd::max(simd::max(simd::min(ax, bx), simd::min(ay, by)), simd::min(az, bz));
    vfloat<A> const tf = simd::min(simd::min(simd::max(ax, bx), simd::max(ay, by)), simd::max(az, bz));
    // Widening: far more than the rounding of the clip's t against the slab
    // test's, and than the hex visit's own widening (1e-4 of the clip).
    vfloat<A> const margin =
        vfloat<A>(1e-3f) * simd::abs(tf - tn) + vfloat<A>(1e-5f) * simd::max(simd::abs(tn), simd::abs(tf));
    vfloat<A> const inv(1.f / step);
    vfloat<A> const a = simd::max((tn - margin - t0) * inv, vfloat<A>(-1.f));
    vfloat<A> const b = simd::min((tf + margin - t0) * inv, vfloat<A>(float(group)));
    // A sample index g in [max(a, 0), min(b, G - 1)]: ceil(a) <= floor(b).
    vfloat<A> const g_lo = simd::max(simd::ceil(a), vfloat<A>(0.f));
    vfloat<A> const g_hi = simd::min(simd::floor(b), vfloat<A>(float(group - 1)));
    vfloat<A> const slack(1.f + 4.f * std::numeric_limits<float>::epsilon());  // as box_hit's exit
    box = simd::max(tn, t_first) <= simd::min(tf, t_last) * slack;
    return box && g_lo <= g_hi;
  }

  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    visit(gather_corners<A, N>(mesh, slot_cells<A>(tree, slots, m), m), m);
  }


};

/// Runs one group for the lanes in `active` with the chosen traversal.
template <class A, int N>
inline void sample_group(SampleQuery<A, N>& q, vmask<A> const& active, Traversal how, int hybrid_threshold) {
  switch (how) {
    case Traversal::packet: traverse_packet<A>(q.tree, q.r, active, q); break;
    case Traversal::hybrid: traverse_packet<A>(q.tree, q.r, active, q, 0, hybrid_threshold); break;
    case Traversal::spmd: traverse_spmd<A>(q.tree, q.r, active, q); break;
  }
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
