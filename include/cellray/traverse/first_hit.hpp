#pragma once
// First isosurface hit over the min-max BVH: packet, SPMD and hybrid
// traversal of W rays (Rathke 2015 §5.5, §6). Subtrees whose value range
// holds none of the isovalues are skipped; all isovalues are tested in one
// traversal (§6.1). ISA units only.

#include <cstdint>

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
/// holds an isovalue (no NaN corner value), else false and `c` untouched:
/// the values are read and tested before positions are loaded or corners
/// ordered. `mesh` must have values.
template <class A, int N>
inline bool broadcast_corners_if_iso(CellMesh<N> const& mesh, uint64_t cell, IsoSet const& isos,
                                     CellCorners<A, N>& c) {
  ScalarCorners<N> k;
  read_corner_values(mesh, cell, k);
  if (!isos.overlaps(k.lo, k.hi)) return false;  // false for NaN
  order_corners(mesh.vertex_count(), k);
  c = broadcast<A, N>(mesh, k);
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
  /// Hexes: also keep, in `grad`, the analytic field gradient (world space)
  /// at each lane's hit, computed once per cell for all its hit lanes (the
  /// shading normal's source, instead of locating each hit point again).
  /// Tets ignore it. Lanes without a hit: unspecified.
  bool want_gradient = false;
  Vec3<A> grad{};

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
    if (!mesh.values()) return;  // NaN everywhere: no cell can hold a crossing
    for (uint64_t i = first; i < first + count; ++i) {
      CellCorners<A, N> c;
      if (!broadcast_corners_if_iso<A, N>(mesh, tree.item(i), isos, c)) continue;
      if (simd::none(m && cell_box_hit<A, N>(r, c, r.tmin, hit.t))) continue;
      if constexpr (N == 8) {
        if (want_gradient) {
          hex_cell_with_gradient(c, m, vint<A>(int32_t(i)));
          continue;
        }
      }
      CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, m, r.tmin, hit.t, isos.values, isos.count, method);
      if (simd::any(h.hit)) update(h.hit, h.t, h.iso_index, vint<A>(int32_t(i)));
    }
  }

  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    if (!mesh.values()) return;
    vint<A> const cells = slot_cells<A>(tree, slots, m);
    // Each lane's value range first, as packet leaves do: most cells a lane
    // reaches hold no isovalue, and they then cost no position gathers and
    // no clip.
    alignas(64) int32_t cell[width<A>];
    simd::store(cell, cells);
    uint32_t keep = 0;
    for (uint32_t b = simd::movemask(m); b; b &= b - 1) {
      int const l = __builtin_ctz(b);
      ScalarCorners<N> k;
      read_corner_values(mesh, uint64_t(uint32_t(cell[l])), k);
      if (isos.overlaps(k.lo, k.hi)) keep |= 1u << l;  // false for NaN
    }
    if (!keep) return;
    vmask<A> const live = simd::mask_from_bits<A>(keep);
    CellCorners<A, N> const c = gather_corners<A, N>(mesh, cells, live);
    if constexpr (N == 8) {
      if (want_gradient) {
        hex_cell_with_gradient(c, live, slots);
        return;
      }
    }
    CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, live, r.tmin, hit.t, isos.values, isos.count, method);
    update(h.hit, h.t, h.iso_index, slots);
  }

  /// Iso roots in one hex per lane (item-list slots `slots`) for lanes `m`,
  /// keeping the gradient at each hit.
  void hex_cell_with_gradient(CellCorners<A, N> const& c, vmask<A> const& m, vint<A> const& slots) {
    Vec3<A> u{};
    CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, m, r.tmin, hit.t, isos.values, isos.count, method, &u);
    if (simd::none(h.hit)) return;
    update(h.hit, h.t, h.iso_index, slots);
    if constexpr (N == 8) grad = select<A>(h.hit, gradient_hex(c, u), grad);
  }
};

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
