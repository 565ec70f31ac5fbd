#pragma once
// What the traversals build on CellOps<A, N> (cells/cell_ops.hpp, one
// specialization in each type's file): a packet's rays as a RayBatch, cell
// boxes, the leaf cells worth a kernel call, and an isovalue crossing in a
// window. Written once for every type; they ask CellOps about properties.

#include <limits>
#include <type_traits>

#include "../cells/hex.hpp"
#include "../cells/queries.hpp"
#include "../cells/tet.hpp"
#include "packet.hpp"
#include "tree_view.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

template <class A> inline RayBatch<A> ray_batch(RayPacket<A> const& r) { return {r.ox, r.oy, r.oz, r.dx, r.dy, r.dz}; }

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
/// A packet misses most cells of a leaf it reaches. A visitor that also
/// takes a FoldedTet gets the type's tets in disguise that way
/// (CellOps::holds_folded_tets): 4 corners broadcast instead of 8, for
/// the tet kernels.
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
    using TakesFolded = std::is_invocable<Visit&, FoldedTet<A> const&, vmask<A> const&, uint64_t, uint64_t>;
    if constexpr (std::conjunction_v<std::bool_constant<CellOps<A, N>::holds_folded_tets>, TakesFolded>) {
      if (CellOps<A, N>::is_folded_tet(k.key)) {
        visit(CellOps<A, N>::broadcast_folded_tet(xyz, k), in_box, i, cell);
        continue;
      }
    }
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
