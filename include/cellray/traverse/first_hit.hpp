#pragma once
// First isosurface hit over the min-max BVH: packet, SPMD and hybrid
// traversal of W rays (Rathke 2015 §5.5, §6). Subtrees whose value range
// holds none of the isovalues are skipped; all isovalues are tested in one
// traversal (§6.1). ISA units only.

#include <cstdint>
#include <type_traits>

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

/// Lanes of `m` whose cell (`cells`, one per lane) has a value range holding
/// one of the isovalues, as bits: SPMD leaves test this in scalar before
/// gathering positions, as packet leaves do, because most cells a lane
/// reaches hold no isovalue (NaN cells never pass).
template <class A, int N>
CELLRAY_FORCE_INLINE uint32_t lanes_holding_iso(CellMesh<N> const& mesh, vint<A> const& cells, vmask<A> const& m,
                                                IsoSet const& isos) {
  alignas(64) int32_t cell[width<A>];
  simd::store(cell, cells);
  uint32_t keep = 0;
  for (uint32_t b = simd::movemask(m); b; b &= b - 1) {
    int const l = __builtin_ctz(b);
    ScalarCorners<N> k;
    read_corner_values(mesh, uint64_t(uint32_t(cell[l])), k);
    if (isos.overlaps(k.lo, k.hi)) keep |= 1u << l;
  }
  return keep;
}

/// The first-hit query for the traversal skeletons (traverse.hpp).
template <class A, int N> struct FirstHitQuery {
  TreeView const& tree;
  CellMesh<N> const& mesh;
  RayPacket<A> const& r;
  IsoSet const& isos;
  CellIsoOptions const& method;
  HitPacket<A> hit;
  /// Also keep, in `grad`, the analytic field gradient (world space) at each
  /// lane's hit, computed once per cell for all its hit lanes from the
  /// corners already loaded (the shading normal's source, instead of loading
  /// and locating each hit again): gradient_tet (constant per cell) or
  /// gradient_hex at the root's trilinear coordinates (no second point
  /// location). Lanes without a hit: unspecified.
  bool want_gradient = false;
  Vec3<A> grad{};
  /// Hexahedra: also keep, in `param`, each hit lane's trilinear
  /// coordinates from the root search (iso_root_hex's), so that shading
  /// interpolates at the hit without inverting the cell again.
  bool want_param = false;
  Vec3<A> param{};

  /// A constructor, not aggregate initialisation: g++ zeroed the whole
  /// query (about 500 bytes, `rep stos`) before storing the members, once
  /// per packet and part (2-3% of an iso frame with the SceneHit below).
  FirstHitQuery(TreeView const& t, CellMesh<N> const& m, RayPacket<A> const& rays, IsoSet const& i,
                CellIsoOptions const& o, HitPacket<A> const& h)
      : tree(t), mesh(m), r(rays), isos(i), method(o), hit(h) {}

  bool node_relevant(float vmin, float vmax) const { return isos.overlaps(vmin, vmax); }
  vmask<A> relevant(vfloat<A> const& vmin, vfloat<A> const& vmax) const {
    vmask<A> m = simd::no_lanes<A>();
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
    // Every lane of `m` goes to the kernel, not only those in the box.
    for_each_leaf_cell<A, N>(
        tree, mesh, r, first, count, m, r.tmin, [this](float vmin, float vmax) { return isos.overlaps(vmin, vmax); },
        [this] { return hit.t; },
        [this, &m](auto const& c, vmask<A> const&, uint64_t slot, uint64_t) -> void {
          if constexpr (std::is_same_v<std::decay_t<decltype(c)>, FoldedTet<A>>)
            folded_tet_hits(c, m, vint<A>(int32_t(slot)));
          else
            cell_hits(c, m, vint<A>(int32_t(slot)));
        });
  }

  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    if (!mesh.values()) return;
    vint<A> const cells = slot_cells<A>(tree, slots, m);
    uint32_t const keep = lanes_holding_iso<A, N>(mesh, cells, m, isos);
    if (!keep) return;
    vmask<A> const live = simd::mask_from_bits<A>(keep);
    cell_hits(gather_corners<A, N>(mesh, cells, live), live, slots);
  }

  /// Iso roots in one cell per lane (item-list slots `slots`) for lanes `m`,
  /// keeping the gradient at each hit when asked (at the hit's cell
  /// coordinates where the type keeps them).
  void cell_hits(CellCorners<A, N> const& c, vmask<A> const& m, vint<A> const& slots) {
    cell_hits_in(c, CellOps<A, N>::clip_window(ray_batch(r), c, m, r.tmin, hit.t), slots);
  }

  /// cell_hits with the cell's clip `k` to [tmin, hit.t] for its lanes.
  void cell_hits_in(CellCorners<A, N> const& c, typename CellOps<A, N>::Clip const& k, vint<A> const& slots) {
    using Ops = CellOps<A, N>;
    Vec3<A> u{};
    bool const keep_param = Ops::keeps_param && (want_gradient || want_param);
    CellIsoHit<A> const h =
        iso_in_clip<A, N>(ray_batch(r), k, c, r.tmin, hit.t, isos.values, isos.count, method, keep_param ? &u : nullptr);
    if (simd::none(h.hit)) return;
    update(h.hit, h.t, h.iso_index, slots);
    if (Ops::keeps_param && want_param) param = select<A>(h.hit, u, param);
    if (want_gradient) grad = select<A>(h.hit, Ops::gradient_at(c, u), grad);
  }

  /// cell_hits for a tetrahedron stored as this type (for_each_leaf_cell's
  /// FoldedTet), with the tet kernels: its field is linear, so its roots
  /// need no search. The hit keeps this type's coordinates
  /// (folded_tet_param) and the tet's constant gradient.
  void folded_tet_hits(FoldedTet<A> const& f, vmask<A> const& m, vint<A> const& slots) {
    folded_tet_hits_in(f, CellOps<A, 4>::clip_window(ray_batch(r), f.tet, m, r.tmin, hit.t), slots);
  }

  /// folded_tet_hits with the tet's clip `k` to [tmin, hit.t] for its lanes.
  void folded_tet_hits_in(FoldedTet<A> const& f, CellClip<A> const& k, vint<A> const& slots) {
    RayBatch<A> const ray = ray_batch(r);
    CellIsoHit<A> const h = iso_in_clip<A, 4>(ray, k, f.tet, r.tmin, hit.t, isos.values, isos.count, method);
    if (simd::none(h.hit)) return;
    update(h.hit, h.t, h.iso_index, slots);
    if (want_param)
      param = select<A>(h.hit, CellOps<A, N>::folded_tet_param(f, ray.origin() + h.t * ray.dir()), param);
    if (want_gradient) grad = select<A>(h.hit, CellOps<A, 4>::gradient_at(f.tet, Vec3<A>{}), grad);
  }
};

/// K first-hit queries, one per packet, traversed together
/// (traverse_packets): a leaf's cells are read, filtered by value and boxed
/// once for all packets, and each packet with a lane in a cell's box runs
/// the cell's kernel over all its lanes in the leaf, as
/// FirstHitQuery::leaf does, so each packet finds the hits it would alone.
/// Packets from one origin clip a cell from one setup (CellOps::
/// window_setup: a tet's face planes, a parallelogram-faced hexahedron's
/// face planes and crossing bases), with the bits of each packet's own clip.
template <class A, int N, int K> struct FirstHitGroup {
  FirstHitQuery<A, N>* q;  ///< K queries, packet k's in q[k]
  RayPacket<A> const* r;   ///< the K packets
  /// The packets' one origin, if they have one (one_origin): cells that can
  /// share their clip setup (CellOps::shares_window_setup) set it up once.
  Vec3<A> origin{};
  bool shared_origin;

  FirstHitGroup(FirstHitQuery<A, N>* queries, RayPacket<A> const* rays, vmask<A> const (&lanes)[K])
      : q(queries), r(rays), shared_origin(one_origin<A, K>(rays, lanes, origin)) {}

  bool node_relevant(float vmin, float vmax) const { return q[0].node_relevant(vmin, vmax); }
  vfloat<A> t_lo(int k) const { return q[k].t_lo(); }
  vfloat<A> t_hi(int k) const { return q[k].t_hi(); }

  void leaf(uint64_t first, uint32_t count, vmask<A> const (&lanes)[K], uint32_t packets) {
    CellMesh<N> const& mesh = q[0].mesh;
    TreeView const& tree = q[0].tree;
    if (!mesh.values()) return;  // NaN everywhere: no cell can hold a crossing
    float const* xyz = mesh.positions();
    for (uint64_t i = first; i < first + count; ++i) {
      ScalarCorners<N> k;
      read_corner_values(mesh, tree.item(i), k);
      if (!q[0].isos.overlaps(k.lo, k.hi)) continue;
      float lo[3], hi[3];
      corner_box(xyz, k, lo, hi);
      uint32_t in = 0;  // packets with a lane in the cell's box
      for (int p = 0; p < K; ++p) {
        if (!((packets >> p) & 1u)) continue;
        vfloat<A> tn;
        if (simd::any(lanes[p] && box_hit(r[p], lo, hi, r[p].tmin, q[p].hit.t, tn))) in |= 1u << p;
      }
      if (!in) continue;
      order_corners(mesh.vertex_count(), k);
      vint<A> const slot = vint<A>(int32_t(i));
      if constexpr (CellOps<A, N>::holds_folded_tets) {
        if (CellOps<A, N>::is_folded_tet(k.key)) {
          FoldedTet<A> const f = CellOps<A, N>::broadcast_folded_tet(xyz, k);
          if (shared_origin && (in & (in - 1))) {
            auto const set = CellOps<A, 4>::window_setup(f.tet, origin);
            for (uint32_t b = in; b; b &= b - 1) {
              int const p = __builtin_ctz(b);
              q[p].folded_tet_hits_in(
                  f, CellOps<A, 4>::clip_window_set(ray_batch(r[p]), f.tet, set, lanes[p], r[p].tmin, q[p].hit.t),
                  slot);
            }
            continue;
          }
          for (uint32_t b = in; b; b &= b - 1) {
            int const p = __builtin_ctz(b);
            q[p].folded_tet_hits(f, lanes[p], slot);
          }
          continue;
        }
      }
      CellCorners<A, N> const c = broadcast<A, N>(mesh, k);
      if constexpr (CellOps<A, N>::shares_window_setup) {
        if (shared_origin && (in & (in - 1))) {  // two packets or more
          auto const set = CellOps<A, N>::window_setup(c, origin);
          for (uint32_t b = in; b; b &= b - 1) {
            int const p = __builtin_ctz(b);
            q[p].cell_hits_in(
                c, CellOps<A, N>::clip_window_set(ray_batch(r[p]), c, set, lanes[p], r[p].tmin, q[p].hit.t), slot);
          }
          continue;
        }
      }
      for (uint32_t b = in; b; b &= b - 1) {
        int const p = __builtin_ctz(b);
        q[p].cell_hits(c, lanes[p], slot);
      }
    }
  }
};

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
