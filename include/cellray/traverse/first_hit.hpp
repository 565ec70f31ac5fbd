#pragma once
// First isosurface hit over the min-max BVH: packet, SPMD and hybrid
// traversal of W rays (Rathke 2015 §5.5, §6). Subtrees whose value range
// holds none of the isovalues are skipped; all isovalues are tested in one
// traversal (§6.1). ISA units only.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <utility>

#include "cell_ops.hpp"
#include "packet.hpp"
#include "traverse.hpp"
#include "tree_view.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

/// Per-lane state of a first-hit query. `item` is the item-list slot of
/// the hit cell (-1 none); t starts at tmax and only shrinks.
template <class A> struct HitPacket {
  vfloat<A> t;
  vint<A> item;
  vint<A> iso;
};

/// broadcast_corners<A, N>(mesh, cell) into `c` when the cell's value range
/// holds an isovalue (no NaN corner value), else false and `c` untouched.
/// Reads each index and value once, and orders tet corners with a scalar
/// sorting network on the vertex ids (the same network and key as
/// detail::sort_tet_corners, so the same corner order) before broadcasting,
/// instead of sorting five vectors. `mesh` must have values.
template <class A, int N>
inline bool broadcast_corners_if_iso(CellMesh<N> const& mesh, uint64_t cell, IsoSet const& isos,
                                     CellCorners<A, N>& c) {
  float const* xyz = mesh.positions();
  float const* val = mesh.values();
  uint64_t v[N];
  float s[N];
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (int k = 0; k < N; ++k) {
    v[k] = mesh.vertex(cell, k);
    s[k] = val[v[k]];
    if (!(s[k] == s[k])) return false;
    lo = std::min(lo, s[k]);
    hi = std::max(hi, s[k]);
  }
  if (!isos.overlaps(lo, hi)) return false;
  int32_t keys[N];  // the canonical corner key of broadcast_corners (64-bit safe)
  corner_keys<N>(mesh.vertex_count(), v, keys);
  int order[N];
  for (int k = 0; k < N; ++k) order[k] = k;
  if constexpr (N == 4) {
    auto key = [&](int k) { return keys[order[k]]; };
    auto swap_if = [&](int i, int j) {
      if (key(i) > key(j)) std::swap(order[i], order[j]);
    };
    swap_if(0, 1), swap_if(2, 3), swap_if(0, 2), swap_if(1, 3), swap_if(1, 2);
  }
  for (int i = 0; i < N; ++i) {
    uint64_t const vi = v[order[i]];
    c.x[i] = vfloat<A>(xyz[3 * vi]);
    c.y[i] = vfloat<A>(xyz[3 * vi + 1]);
    c.z[i] = vfloat<A>(xyz[3 * vi + 2]);
    c.s[i] = vfloat<A>(s[order[i]]);
    c.id[i] = vint<A>(keys[order[i]]);
  }
  return true;
}

/// The first-hit query for the traversal skeletons (traverse.hpp).
template <class A, int N> struct FirstHitQuery {
  TreeView const& tree;
  CellMesh<N> const& mesh;
  RayPacket<A> const& r;
  IsoSet const& isos;
  CellIsoOptions const& method;
  HitPacket<A> hit;

  bool node_relevant(float vmin, float vmax) const { return isos.overlaps(vmin, vmax); }
  vmask<A> relevant(vfloat<A> const& vmin, vfloat<A> const& vmax) const {
    vmask<A> m(false);
    for (int k = 0; k < isos.count; ++k) m = m || (vfloat<A>(isos.values[k]) >= vmin && vfloat<A>(isos.values[k]) <= vmax);
    return m;
  }
  bool done() const { return false; }
  vfloat<A> t_lo() const { return r.tmin; }
  vfloat<A> t_hi() const { return hit.t; }

  void update(vmask<A> const& f, vfloat<A> const& t, vint<A> const& iso, vint<A> const& slot) {
    hit.t = simd::select(f, t, hit.t);
    hit.iso = simd::select(simd::to_int_mask(f), iso, hit.iso);
    hit.item = simd::select(simd::to_int_mask(f), slot, hit.item);
  }

  /// Slab test of the lanes against the cell's bounding box: a cheap cull
  /// before the clip, conservative like the BVH node test (same box_hit).
  bool cell_box_hit(CellCorners<A, N> const& c, vmask<A> const& m) const {
    vfloat<A> lo[3] = {c.x[0], c.y[0], c.z[0]}, hi[3] = {c.x[0], c.y[0], c.z[0]};
    for (int k = 1; k < N; ++k) {
      lo[0] = simd::min(lo[0], c.x[k]), hi[0] = simd::max(hi[0], c.x[k]);
      lo[1] = simd::min(lo[1], c.y[k]), hi[1] = simd::max(hi[1], c.y[k]);
      lo[2] = simd::min(lo[2], c.z[k]), hi[2] = simd::max(hi[2], c.z[k]);
    }
    vfloat<A> tn;
    return simd::any(m && box_hit_varying(r, lo, hi, r.tmin, hit.t, tn));
  }

  void leaf(uint64_t first, uint32_t count, vmask<A> const& m) {
    if (!mesh.values()) return;  // NaN everywhere: no cell can hold a crossing
    for (uint64_t i = first; i < first + count; ++i) {
      CellCorners<A, N> c;
      if (!broadcast_corners_if_iso<A, N>(mesh, tree.item(i), isos, c)) continue;
      if (!cell_box_hit(c, m)) continue;
      CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, m, r.tmin, hit.t, isos.values, isos.count, method);
      if (simd::any(h.hit)) update(h.hit, h.t, h.iso_index, vint<A>(int32_t(i)));
    }
  }

  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    CellCorners<A, N> const c = gather_corners<A, N>(mesh, slot_cells<A>(tree, slots, m), m);
    CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, m, r.tmin, hit.t, isos.values, isos.count, method);
    update(h.hit, h.t, h.iso_index, slots);
  }


};

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
