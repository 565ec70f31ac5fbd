#pragma once
// The cell operations the traversals call, per cell type, over the kernels
// of cells/ (tet.hpp, hex.hpp). One place maps "clip, iso roots, locate,
// gradient, the field along a segment" to the tet or hex kernel, and says
// what a type's field allows (linear_on_ray, keeps_param), so that the
// traversals and integrators ask about properties, not about a type.

#include <limits>

#include "../cells/hex.hpp"
#include "../cells/queries.hpp"
#include "../cells/tet.hpp"
#include "packet.hpp"
#include "tree_view.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

template <class A> inline RayBatch<A> ray_batch(RayPacket<A> const& r) { return {r.ox, r.oy, r.oz, r.dx, r.dy, r.dz}; }

template <class A, int N> struct CellOps;

template <class A> struct CellOps<A, 4> {
  using Clip = CellClip<A>;
  /// The field is linear along a ray: a clip's end values bound it on the
  /// segment and give it anywhere on it (no point location).
  static constexpr bool linear_on_ray = true;
  /// A hit or located point has no cell coordinates worth keeping.
  static constexpr bool keeps_param = false;
  static Clip clip(RayBatch<A> const& r, CellCorners<A, 4> const& c) { return clip_tet(r, c); }
  /// The clip narrowed to [t_lo, t_hi]; `exit_face`, if given, receives the
  /// face (mesh face order, FaceNeighbours') the ray leaves through.
  static Clip clip_window(RayBatch<A> const& r, CellCorners<A, 4> const& c, vmask<A> const& lanes,
                          vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face = nullptr) {
    return clip_tet_window(r, c, lanes, t_lo, t_hi, exit_face);
  }
  /// A march's next cell shares a face's corners with the last one: the
  /// march gathers only the one it does not share (CellMarch::next_corners).
  static constexpr bool march_reuses_corners = true;
  /// Grouped occlusion queries clip (cell, ray) pairs, W per kernel call,
  /// instead of each cell against every packet that meets it: a tet's clip
  /// is cheap against its broadcast (TetPairs in occlusion.hpp, tets only).
  static constexpr bool occlusion_in_pairs = true;
  /// `param` is for hexes (hit coordinates); tets leave it alone.
  /// `t_from` is for hexes too: a tet holds one crossing per isovalue.
  static CellIsoHit<A> iso(RayBatch<A> const& r, Clip const& k, CellCorners<A, 4> const& c, float const* isos,
                           int count, CellIsoOptions const& o, Vec3<A>* /*param*/ = nullptr,
                           vfloat<A> const* /*t_from*/ = nullptr) {
    return o.method == CellIsoMethod::exact ? iso_root_tet(k, c, isos, count)
                                            : iso_root_tet_neubauer(r, k, c, isos, count, o.neubauer_steps);
  }
  static Located<A> locate(PointBatch<A> const& p, CellCorners<A, 4> const& c) { return locate_tet(p, c); }
  static Located<A> locate(PointBatch<A> const& p, CellCorners<A, 4> const& c, vmask<A> const& /*lanes*/) {
    return locate_tet(p, c);
  }
  /// Lanes that `locate` left outside by at most `tol` in the cell's own
  /// coordinates, with a finite value: a probe's fallback where rounding put
  /// a point on a shared edge or vertex outside every cell (probe.hpp).
  /// Comparisons, not a min: a flat tet's NaN weights must fail.
  static vmask<A> nearly_inside(Located<A> const& loc, float tol) {
    Vec3<A> const& w = loc.param;
    vfloat<A> const w0 = vfloat<A>(1.f) - (w.x + w.y + w.z), t(-tol);
    return w0 >= t && w.x >= t && w.y >= t && w.z >= t &&
           simd::abs(loc.value) <= vfloat<A>(std::numeric_limits<float>::max());
  }
  static Vec3<A> gradient(CellCorners<A, 4> const& c, Vec3<A> const& p, GradientMethod m, float h) {
    return m != GradientMethod::central ? gradient_tet(c) : gradient_central_tet(c, p, h);
  }
  /// The analytic gradient at a point of the cell given by its coordinates
  /// (keeps_param; a tet's is one per cell and ignores them).
  static Vec3<A> gradient_at(CellCorners<A, 4> const& c, Vec3<A> const& /*param*/) { return gradient_tet(c); }
  /// The shape functions at a located point's coordinates (locate's param:
  /// barycentric 1 to 3), one per corner in the located corners' order.
  static void shape_weights(Vec3<A> const& param, vfloat<A> (&w)[4]) {
    w[1] = param.x, w[2] = param.y, w[3] = param.z;
    w[0] = vfloat<A>(1.f) - w[1] - w[2] - w[3];
  }
  /// The field on the clip's segment as a cubic in lambda = (t - t_in) /
  /// (t_out - t_in) (here the line between its end values) and, if `g` is
  /// given, its world-space gradient as three (here the cell's constant one).
  static void segment_field(RayBatch<A> const& /*r*/, CellCorners<A, 4> const& c, Clip const& k,
                            vmask<A> const& /*lanes*/, isa_detail::Cubic<A>& f, isa_detail::Cubic<A>* g) {
    vfloat<A> const zero(0.f);
    f = {k.s_in, k.s_out - k.s_in, zero, zero};
    if (g) {
      Vec3<A> const d = gradient_tet(c);
      g[0] = {d.x, zero, zero, zero}, g[1] = {d.y, zero, zero, zero}, g[2] = {d.z, zero, zero, zero};
    }
  }
};

template <class A> struct CellOps<A, 8> {
  using Clip = HexClip<A>;
  /// Trilinear: the field along a ray may exceed its end values.
  static constexpr bool linear_on_ray = false;
  /// Hits and located points keep their trilinear coordinates: the
  /// gradient and any per-vertex weights there need no second inversion.
  static constexpr bool keeps_param = true;
  static Clip clip(RayBatch<A> const& r, CellCorners<A, 8> const& c) { return clip_hex(r, c); }
  static Clip clip_window(RayBatch<A> const& r, CellCorners<A, 8> const& c, vmask<A> const& lanes,
                          vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face = nullptr) {
    return clip_hex_window(r, c, lanes, t_lo, t_hi, exit_face);
  }
  static constexpr bool march_reuses_corners = false;
  static constexpr bool occlusion_in_pairs = false;
  /// `param`, if given, receives the trilinear coordinates of the hit in
  /// hit lanes (iso_root_hex's; for Neubauer one inversion at the root).
  /// `t_from`: the exact method's search start (see iso_root_hex);
  /// Neubauer, which misses pairs of crossings in a cell anyway, ignores it.
  static CellIsoHit<A> iso(RayBatch<A> const& r, Clip const& k, CellCorners<A, 8> const& c, float const* isos,
                           int count, CellIsoOptions const& o, Vec3<A>* param = nullptr,
                           vfloat<A> const* t_from = nullptr) {
    if (o.method == CellIsoMethod::exact) return iso_root_hex(r, k, c, isos, count, o.refine_steps, param, t_from);
    CellIsoHit<A> const h = iso_root_hex_neubauer(r, k, c, isos, count, o.neubauer_steps);
    if (param && simd::any(h.hit)) {
      vfloat<A> const dt = k.t_out - k.t_in;
      vfloat<A> const lam = simd::select(h.hit, (h.t - k.t_in) / dt, vfloat<A>(0.f));
      vmask<A> conv;
      Vec3<A> const u = isa_detail::invert_hex(c, r.origin() + simd::select(h.hit, h.t, k.t_in) * r.dir(),
                                           k.u_in + lam * (k.u_out - k.u_in), h.hit, hex_newton_cap, conv);
      *param = select<A>(h.hit, u, *param);
    }
    return h;
  }
  static Located<A> locate(PointBatch<A> const& p, CellCorners<A, 8> const& c) { return locate_hex(p, c); }
  /// Only the lanes in `lanes` (the iteration ends when they converge).
  static Located<A> locate(PointBatch<A> const& p, CellCorners<A, 8> const& c, vmask<A> const& lanes) {
    return locate_hex(p, c, lanes);
  }
  /// None: locate_hex's containment is widened already (hex_inside_tolerance).
  static vmask<A> nearly_inside(Located<A> const& /*loc*/, float /*tol*/) { return simd::no_lanes<A>(); }
  static Vec3<A> gradient(CellCorners<A, 8> const& c, Vec3<A> const& p, GradientMethod m, float h) {
    Located<A> const l = locate_hex(PointBatch<A>{p.x, p.y, p.z}, c);
    return m != GradientMethod::central ? gradient_hex(c, l.param) : gradient_central_hex(c, p, l.param, h);
  }
  static Vec3<A> gradient_at(CellCorners<A, 8> const& c, Vec3<A> const& param) { return gradient_hex(c, param); }
  /// Trilinear, in VTK corner order (the mesh's own, as the kernels keep it).
  static void shape_weights(Vec3<A> const& param, vfloat<A> (&w)[8]) { trilinear_weights<A>(param, w); }
  /// Kept coordinates that can stand for a located point (see hex_param_in_cell).
  static vmask<A> param_in_cell(Vec3<A> const& param) { return hex_param_in_cell<A>(param); }

  /// The field on the ray at lambda of the clip's segment: its value, and
  /// its trilinear coordinates in `u`. A lane whose inversion neither
  /// converges nor stays near the cell keeps the parametric guess (never a
  /// wild value).
  static vfloat<A> field_on_ray(RayBatch<A> const& ray, CellCorners<A, 8> const& c, Clip const& k,
                                vmask<A> const& lanes, float lam, Vec3<A>& u) {
    vfloat<A> const l(lam);
    Vec3<A> const guess = k.u_in + l * (k.u_out - k.u_in);
    vmask<A> conv;
    u = isa_detail::invert_hex(c, ray.origin() + (k.t_in + l * (k.t_out - k.t_in)) * ray.dir(), guess, lanes, 6, conv);
    u = select<A>(conv || isa_detail::in_unit_cube<A>(u, 0.05f), u, guess);
    return isa_detail::trilerp<A>(c.s, u);
  }

  /// The field on the clip's segment (see the tet's): the cubic through its
  /// values at lambda = 0, 1/3, 2/3, 1 (the ends: the clip's face values;
  /// inside: inversions warm-started on the parametric segment), and the
  /// gradient as the cubic through the analytic gradients there. Exact for
  /// parallelepipeds.
  static void segment_field(RayBatch<A> const& ray, CellCorners<A, 8> const& c, Clip const& k,
                            vmask<A> const& lanes, isa_detail::Cubic<A>& f, isa_detail::Cubic<A>* g) {
    Vec3<A> u1, u2;
    vfloat<A> const v1 = field_on_ray(ray, c, k, lanes, 1.f / 3.f, u1);
    vfloat<A> const v2 = field_on_ray(ray, c, k, lanes, 2.f / 3.f, u2);
    f = isa_detail::cubic_through<A>(k.s_in, v1, v2, k.s_out);
    if (g) {
      Vec3<A> const g0 = isa_detail::hex_world_gradient(c, k.u_in), g1 = isa_detail::hex_world_gradient(c, u1);
      Vec3<A> const g2 = isa_detail::hex_world_gradient(c, u2), g3 = isa_detail::hex_world_gradient(c, k.u_out);
      g[0] = isa_detail::cubic_through<A>(g0.x, g1.x, g2.x, g3.x);
      g[1] = isa_detail::cubic_through<A>(g0.y, g1.y, g2.y, g3.y);
      g[2] = isa_detail::cubic_through<A>(g0.z, g1.z, g2.z, g3.z);
    }
  }
};

/// The cell's bounding box per lane.
template <class A, int N>
CELLRAY_FORCE_INLINE void cell_box(CellCorners<A, N> const& c, vfloat<A> lo[3], vfloat<A> hi[3]) {
  lo[0] = hi[0] = c.x[0], lo[1] = hi[1] = c.y[0], lo[2] = hi[2] = c.z[0];
  for (int k = 1; k < N; ++k) {
    lo[0] = simd::min(lo[0], c.x[k]), hi[0] = simd::max(hi[0], c.x[k]);
    lo[1] = simd::min(lo[1], c.y[k]), hi[1] = simd::max(hi[1], c.y[k]);
    lo[2] = simd::min(lo[2], c.z[k]), hi[2] = simd::max(hi[2], c.z[k]);
  }
}

/// Lanes whose ray meets the cell's bounding box within [t_lo, t_hi]: a
/// cheap cull before a clip, conservative like the BVH node test (same
/// box_hit_varying).
template <class A, int N>
CELLRAY_FORCE_INLINE vmask<A> cell_box_hit(RayPacket<A> const& r, CellCorners<A, N> const& c, vfloat<A> const& t_lo,
                             vfloat<A> const& t_hi) {
  vfloat<A> lo[3], hi[3];
  cell_box(c, lo, hi);
  vfloat<A> tn;
  return box_hit_varying(r, lo, hi, t_lo, t_hi, tn);
}

/// The cells of packet-leaf items [first, first + n) worth a kernel call,
/// cheapest test first: the corner values (`keep(lo, hi)` on their range,
/// false for a NaN cell), then the cell's box in scalar against [t_lo,
/// t_hi()] for the lanes `m` (t_hi re-read per cell: a query's interval
/// shrinks as it finds cells); only then are the corners ordered and
/// broadcast for `visit(corners, lanes in the box, item slot, cell id)`.
/// A packet misses most cells of a leaf it reaches.
template <class A, int N, class Keep, class THi, class Visit>
CELLRAY_FORCE_INLINE void for_each_leaf_cell(TreeView const& tree, CellMesh<N> const& mesh, RayPacket<A> const& r,
                                             uint64_t first, uint32_t n, vmask<A> const& m, vfloat<A> const& t_lo,
                                             Keep const& keep, THi const& t_hi, Visit&& visit) {
  float const* xyz = mesh.positions();
  for (uint64_t i = first; i < first + n; ++i) {
    uint64_t const cell = tree.item(i);
    ScalarCorners<N> k;
    read_corner_values(mesh, cell, k);
    if (!keep(k.lo, k.hi)) continue;
    float lo[3], hi[3];
    corner_box(xyz, k, lo, hi);
    vfloat<A> tn;
    vmask<A> const in_box = m && box_hit(r, lo, hi, t_lo, t_hi(), tn);
    if (simd::none(in_box)) continue;
    order_corners(mesh.vertex_count(), k);
    visit(broadcast<A, N>(mesh, k), in_box, i, cell);
  }
}

/// Nearest crossing of any isovalue with t in [t_lo, t_hi] (per lane) in one
/// cell per lane, on the cell's clip `k` (computed for the lanes with any
/// window that holds the cell's part of [t_lo, t_hi]: iso_in_window clips
/// with that window; a march has clipped the cell already). When the cell's
/// interval pokes out of the window (a ray continuing behind a transparent
/// surface, a shadow or AO ray leaving a surface, or the current nearest
/// hit), a crossing before t_lo must not hide a later one: where the field
/// is not linear on the ray (several crossings of one isovalue) the exact
/// method searches from t_lo (CellOps::iso's t_from); the others try the
/// isovalues one by one (a linear field crosses each once).
/// `param` (keeps_param): the hit's cell coordinates in hit lanes, see
/// CellOps<A, 8>::iso.
template <class A, int N>
inline CellIsoHit<A> iso_in_clip(RayBatch<A> const& r, typename CellOps<A, N>::Clip const& k,
                                 CellCorners<A, N> const& c, vfloat<A> const& t_lo, vfloat<A> const& t_hi,
                                 float const* isos, int count, CellIsoOptions const& o, Vec3<A>* param = nullptr) {
  using Ops = CellOps<A, N>;
  constexpr float inf = std::numeric_limits<float>::infinity();
  CellIsoHit<A> best{vfloat<A>(inf), vint<A>(-1), simd::no_lanes<A>()};
  if (simd::none(k.hit)) return best;
  if (simd::all(!k.hit || (k.t_in >= t_lo && k.t_out <= t_hi))) return Ops::iso(r, k, c, isos, count, o, param);
  if constexpr (!Ops::linear_on_ray) {
    if (o.method == CellIsoMethod::exact) {
      Vec3<A> u = param ? *param : Vec3<A>{};
      CellIsoHit<A> h = Ops::iso(r, k, c, isos, count, o, param ? &u : nullptr, &t_lo);
      h.hit = h.hit && h.t >= t_lo && h.t <= t_hi;
      if (param) *param = select<A>(h.hit, u, *param);
      h.t = simd::select(h.hit, h.t, best.t);
      h.iso_index = simd::select(simd::to_int_mask(h.hit), h.iso_index, best.iso_index);
      return h;
    }
  }
  for (int i = 0; i < count; ++i) {
    Vec3<A> u = param ? *param : Vec3<A>{};
    CellIsoHit<A> const h = Ops::iso(r, k, c, isos + i, 1, o, param ? &u : nullptr);
    vmask<A> const take = h.hit && h.t >= t_lo && h.t <= t_hi && h.t < best.t;
    if (param) *param = select<A>(take, u, *param);
    best.t = simd::select(take, h.t, best.t);
    best.iso_index = simd::select(simd::to_int_mask(take), vint<A>(i), best.iso_index);
    best.hit = best.hit || take;
  }
  return best;
}

/// iso_in_clip after clipping the cell to [t_lo, t_hi] for `lanes`.
template <class A, int N>
inline CellIsoHit<A> iso_in_window(RayBatch<A> const& r, CellCorners<A, N> const& c, vmask<A> const& lanes,
                                   vfloat<A> const& t_lo, vfloat<A> const& t_hi, float const* isos, int count,
                                   CellIsoOptions const& o, Vec3<A>* param = nullptr) {
  return iso_in_clip<A, N>(r, CellOps<A, N>::clip_window(r, c, lanes, t_lo, t_hi), c, t_lo, t_hi, isos, count, o,
                           param);
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
