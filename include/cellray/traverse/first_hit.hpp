#pragma once
// First isosurface hit over the min-max BVH: packet, SPMD and hybrid
// traversal of W rays (Rathke 2015 §5.5, §6). Subtrees whose value range
// holds none of the isovalues are skipped; all isovalues are tested in one
// traversal (§6.1). ISA units only.

#include <algorithm>
#include <cstdint>
#include <limits>

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

/// Uniform cell range test from the corner values (NaN: never).
template <int N> inline bool cell_range_has_iso(CellMesh<N> const& mesh, uint64_t cell, IsoSet const& isos) {
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (int k = 0; k < N; ++k) {
    float const v = mesh.value(mesh.vertex(cell, k));
    if (!(v == v)) return false;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  return isos.overlaps(lo, hi);
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

  void leaf(uint64_t first, uint32_t count, vmask<A> const& m) {
    for (uint64_t i = first; i < first + count; ++i) {
      uint64_t const cell = tree.item(i);
      if (!cell_range_has_iso(mesh, cell, isos)) continue;
      CellCorners<A, N> const c = broadcast_corners<A, N>(mesh, cell);
      CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, m, r.tmin, hit.t, isos.values, isos.count, method);
      if (simd::any(h.hit)) update(h.hit, h.t, h.iso_index, vint<A>(int32_t(i)));
    }
  }

  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    alignas(64) int32_t s[width<A>], cells[width<A>];
    simd::store(s, slots);
    for (int l = 0; l < width<A>; ++l) cells[l] = 0;
    for (uint32_t b = simd::movemask(m); b; b &= b - 1) {
      int const l = __builtin_ctz(b);
      cells[l] = int32_t(uint32_t(tree.item(uint64_t(uint32_t(s[l])))));
    }
    CellCorners<A, N> const c = gather_corners<A, N>(mesh, simd::load<A>(cells), m);
    CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, m, r.tmin, hit.t, isos.values, isos.count, method);
    update(h.hit, h.t, h.iso_index, slots);
  }


};

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
