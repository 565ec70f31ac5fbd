#pragma once
// Occlusion (any-hit) queries for shadow and ambient-occlusion rays, and the
// regrouping of such rays into packets of similar direction. ISA units only.
//
// A first-hit query keeps searching until it has the nearest crossing; a
// shadow or AO ray only needs to know whether any isosurface crosses its
// segment [tmin, tmax]. The occlusion query stops a lane at its first
// crossing found (its search interval becomes empty, so the traversal drops
// it at the next node) and the whole packet once every lane is occluded.
// Whether a lane is occluded is exactly whether the first-hit query would
// report a hit for it: the same cells are tested with the same kernel
// (iso_in_window) over the same window.

#include <cstdint>
#include <limits>
#include <type_traits>

#include "cell_ops.hpp"
#include "first_hit.hpp"
#include "packet.hpp"
#include "traverse.hpp"
#include "tree_view.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

/// Any-hit query for the traversal skeletons (traverse.hpp): which lanes'
/// segments [r.tmin, r.tmax] cross one of `isos` in a cell of `mesh`. NaN
/// cells are never crossed. `occluded` is the answer once the traversal
/// returns; lanes outside the traversal's `active` mask stay false.
template <class A, int N> struct OcclusionQuery {
  TreeView const& tree;
  CellMesh<N> const& mesh;
  RayPacket<A> const& r;
  IsoSet const& isos;
  CellIsoOptions const& method;
  vmask<A> occluded = simd::no_lanes<A>();
  /// r.tmax for lanes still searching, -inf once occluded (box tests and
  /// stack pops then fail for them).
  vfloat<A> t_hi_ = r.tmax;
  uint32_t pending = 0;  ///< bits of the active lanes not yet occluded

  OcclusionQuery(TreeView const& t, CellMesh<N> const& m, RayPacket<A> const& rays, IsoSet const& i,
                 CellIsoOptions const& o, vmask<A> const& active)
      : tree(t), mesh(m), r(rays), isos(i), method(o), pending(simd::movemask(active)) {}

  bool node_relevant(float vmin, float vmax) const { return isos.overlaps(vmin, vmax); }
  vmask<A> relevant(vfloat<A> const& vmin, vfloat<A> const& vmax) const {
    vmask<A> m = simd::no_lanes<A>();
    for (int k = 0; k < isos.count; ++k) m = m || (vfloat<A>(isos.values[k]) >= vmin && vfloat<A>(isos.values[k]) <= vmax);
    return m;
  }
  bool done() const { return pending == 0; }
  vfloat<A> t_lo() const { return r.tmin; }
  vfloat<A> t_hi() const { return t_hi_; }

  void mark(vmask<A> const& f) {
    occluded = occluded || f;
    t_hi_ = simd::select(f, vfloat<A>(-std::numeric_limits<float>::infinity()), t_hi_);
    pending &= ~simd::movemask(f);
  }

  void leaf(uint64_t first, uint32_t count, vmask<A> const& m) {
    if (!mesh.values()) return;  // NaN everywhere: no cell can hold a crossing
    for (uint64_t i = first; i < first + count; ++i) {
      // Lanes occluded by an earlier item of this leaf are done.
      vmask<A> const live = m && !occluded;
      if (simd::none(live)) return;
      // As FirstHitQuery::leaf: values, then the cell's box in scalar, then
      // the ordered, broadcast corners.
      ScalarCorners<N> k;
      read_corner_values(mesh, tree.item(i), k);
      if (!isos.overlaps(k.lo, k.hi)) continue;  // false for NaN
      float lo[3], hi[3];
      corner_box(mesh.positions(), k, lo, hi);
      vfloat<A> tn;
      vmask<A> const lanes = live && box_hit(r, lo, hi, r.tmin, t_hi_, tn);
      if (simd::none(lanes)) continue;
      order_corners(mesh.vertex_count(), k);
      if constexpr (CellOps<A, N>::holds_folded_tets) {
        if (CellOps<A, N>::is_folded_tet(k.key)) {  // the tet kernels, as FirstHitQuery takes it
          FoldedTet<A> const f = CellOps<A, N>::broadcast_folded_tet(mesh.positions(), k);
          CellIsoHit<A> const h =
              iso_in_window(ray_batch(r), f.tet, lanes, r.tmin, t_hi_, isos.values, isos.count, method);
          if (simd::any(h.hit && lanes)) mark(h.hit && lanes);
          continue;
        }
      }
      CellCorners<A, N> const c = broadcast<A, N>(mesh, k);
      CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, lanes, r.tmin, t_hi_, isos.values, isos.count, method);
      if (simd::any(h.hit && lanes)) mark(h.hit && lanes);
    }
  }

  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    if (!mesh.values()) return;
    vmask<A> const live = m && !occluded;
    if (simd::none(live)) return;
    vint<A> const cells = slot_cells<A>(tree, slots, live);
    uint32_t const keep = lanes_holding_iso<A, N>(mesh, cells, live, isos);
    if (!keep) return;
    vmask<A> const lanes = simd::mask_from_bits<A>(keep);
    CellCorners<A, N> const c = gather_corners<A, N>(mesh, cells, lanes);
    CellIsoHit<A> const h = iso_in_window(ray_batch(r), c, lanes, r.tmin, t_hi_, isos.values, isos.count, method);
    if (simd::any(h.hit && lanes)) mark(h.hit && lanes);
  }
};

/// Occlusion of W rays in one tree with the given traversal: the lanes of
/// `active` whose segment crosses an isosurface of `mesh`.
template <class A, int N>
inline vmask<A> occluded_in(TreeView const& tree, CellMesh<N> const& mesh, RayPacket<A> const& r, vmask<A> active,
                            IsoSet const& isos, CellIsoOptions const& method, Traversal how, int hybrid_threshold) {
  OcclusionQuery<A, N> q(tree, mesh, r, isos, method, active);
  switch (how) {
    case Traversal::packet: traverse_packet<A>(tree, r, active, q); break;
    case Traversal::hybrid: traverse_packet<A>(tree, r, active, q, 0, hybrid_threshold); break;
    case Traversal::spmd: traverse_spmd<A>(tree, r, active, q); break;
  }
  return q.occluded && active;
}

/// Lane sets of K packets of W rays in one word: bit k * W + l is lane l of
/// packet k. One integer to copy, mask and test per stack entry (K arrays
/// of 32-bit masks were stored lane by lane and reloaded as one vector: a
/// store-forwarding stall on every stack pop).
template <class A, int K> using LaneSet = std::conditional_t<K * width<A> <= 32, uint32_t, uint64_t>;

/// Lanes of packet k in a lane set.
template <class A, int K> inline uint32_t packet_lanes(LaneSet<A, K> s, int k) {
  constexpr int W = width<A>;
  return uint32_t(s >> (k * W)) & uint32_t(W >= 32 ? ~0u : (1u << W) - 1u);
}

/// (cell, ray) pairs of tets collected W at a time and clipped together,
/// one cell and one ray per lane: a cell's box is usually met by 1 to 3 of
/// a group's incoherent rays (2.2 of 8 lanes measured on component8's AO
/// rays, AVX2), so clipping each packet that has a lane in it wastes most
/// lanes. Every tet clip of occluded_packets goes through here, so a ray's
/// answer never depends on the other rays of its group. Each lane computes
/// what a packet clip computes for it (the same ordered corners, ray and
/// kernel): the same answers (tests/test_traverse_occlusion.cpp,
/// test_render_occlusion.cpp check them bit for bit).
template <class A, int K> struct TetPairs {
  static constexpr int W = width<A>;
  using Lanes = LaneSet<A, K>;
  // 2 W slots: add() writes a cell's corners to W slots from slot n < W with
  // one broadcast store per component (not one scalar store per pair);
  // clip() takes slots [0, W) and the rest move down.
  alignas(64) float x[4][2 * W], y[4][2 * W], z[4][2 * W], s[4][2 * W];
  alignas(64) int32_t id[4][2 * W];
  alignas(64) float ray[8][2 * W];  ///< ox oy oz dx dy dz tmin tmax
  uint8_t owner[2 * W];             ///< packet * W + lane: its bit in a lane set
  int n = 0;

  /// Adds the pairs of one tet (ordered corners `sc`, positions `xyz`) with
  /// the lanes `lanes` of packet `k` (whose rays' components are `rays`);
  /// clips W pairs once W are held.
  void add(float const* xyz, ScalarCorners<4> const& sc, float const (&rays)[8][W], int k, uint32_t lanes,
           Lanes& pending, IsoSet const& isos, CellIsoOptions const& method) {
    // A local count: the stores below may alias the member (int32_t id[]),
    // which made g++ reload it after every store.
    int m = n;
    // The cell's corners into the pairs' slots from m on: with W-wide
    // stores, or 4-wide ones when at most 4 lanes need them (most cells: a
    // 64-byte store per component filled the store queue, 1-2% of an AO frame).
    bool const narrow = W >= 8 && __builtin_popcount(lanes) <= 4;
    for (int q = 0; q < 4; ++q) {
      float const* p = xyz + 3 * sc.v[q];
      if (narrow) {
        simd::store_broadcast4(x[q] + m, p[0]), simd::store_broadcast4(y[q] + m, p[1]);
        simd::store_broadcast4(z[q] + m, p[2]), simd::store_broadcast4(s[q] + m, sc.s[q]);
        simd::store_broadcast4(id[q] + m, sc.key[q]);
        continue;
      }
      simd::store(x[q] + m, vfloat<A>(p[0]));
      simd::store(y[q] + m, vfloat<A>(p[1]));
      simd::store(z[q] + m, vfloat<A>(p[2]));
      simd::store(s[q] + m, vfloat<A>(sc.s[q]));
      simd::store(id[q] + m, vint<A>(sc.key[q]));
    }
    for (uint32_t b = lanes; b; b &= b - 1) {
      int const l = __builtin_ctz(b);
      for (int q = 0; q < 8; ++q) ray[q][m] = rays[q][l];
      owner[m++] = uint8_t(k * W + l);
    }
    n = m;
    if (m < W) return;
    clip(W, pending, isos, method);
    n = m - W;
    if (!n) return;
    for (int q = 0; q < 4; ++q) {
      simd::store(x[q], simd::load<A>(x[q] + W)), simd::store(y[q], simd::load<A>(y[q] + W));
      simd::store(z[q], simd::load<A>(z[q] + W)), simd::store(s[q], simd::load<A>(s[q] + W));
      simd::store(id[q], simd::load<A>(id[q] + W));
    }
    for (int q = 0; q < 8; ++q) simd::store(ray[q], simd::load<A>(ray[q] + W));
    for (int i = 0; i < n; ++i) owner[i] = owner[W + i];
  }

  /// Clips the pairs held and clears the lanes of occluded rays in `pending`.
  void flush(Lanes& pending, IsoSet const& isos, CellIsoOptions const& method) {
    if (n) clip(n, pending, isos, method);
    n = 0;
  }

  /// Clips the pairs in slots [0, m), m <= W, and clears the lanes of
  /// occluded rays in `pending`.
  void clip(int m, Lanes& pending, IsoSet const& isos, CellIsoOptions const& method) {
    uint32_t live = 0;
    for (int i = 0; i < m; ++i) live |= uint32_t(pending >> owner[i] & 1u) << i;
    if (!live) return;
    CellCorners<A, 4> c;
    for (int j = 0; j < 4; ++j) {
      c.x[j] = simd::load<A>(x[j]), c.y[j] = simd::load<A>(y[j]), c.z[j] = simd::load<A>(z[j]);
      c.s[j] = simd::load<A>(s[j]), c.id[j] = simd::load<A>(id[j]);
    }
    RayBatch<A> const r{simd::load<A>(ray[0]), simd::load<A>(ray[1]), simd::load<A>(ray[2]),
                        simd::load<A>(ray[3]), simd::load<A>(ray[4]), simd::load<A>(ray[5])};
    vmask<A> const lanes = simd::mask_from_bits<A>(live);
    CellIsoHit<A> const h =
        iso_in_window(r, c, lanes, simd::load<A>(ray[6]), simd::load<A>(ray[7]), isos.values, isos.count, method);
    for (uint32_t b = simd::movemask(h.hit && lanes); b; b &= b - 1) pending &= ~(Lanes(1) << owner[__builtin_ctz(b)]);
  }
};

/// Occlusion of K packets of W rays in one traversal: each node is visited
/// once for all K x W rays, each relevant cell's corners read once, and only
/// the packets whose lanes meet the cell's box run the clip (tets: the
/// pairs of sparse packets are clipped W at a time, TetPairs). For
/// incoherent rays leaving one pixel block (AO), K packets of W rays visit
/// nearly the same nodes one by one; together they pay the traversal and
/// the corner reads once. `pending_rays[k]`: on entry the lanes of packet k
/// to trace, on return those not occluded (occluded = entry bits minus
/// return bits). The answer per lane is OcclusionQuery's. No value array:
/// nothing occluded. K x W <= 64.
template <class A, int K, int N>
void occluded_packets(TreeView const& tree, CellMesh<N> const& mesh, RayPacket<A> const (&r)[K],
                      uint32_t (&pending_rays)[K], IsoSet const& isos, CellIsoOptions const& method) {
  constexpr int W = width<A>;
  static_assert(K * W <= 64, "one lane set holds at most 64 rays");
  using Lanes = LaneSet<A, K>;
  if (tree.empty() || !mesh.values()) return;
  Lanes pending = 0;
  for (int k = 0; k < K; ++k) pending |= Lanes(pending_rays[k]) << (k * W);
  struct Entry {
    uint32_t node;
    Lanes lanes;  ///< rays that entered the node's box
  };
  // The lanes of `from` whose rays enter node ni's box.
  auto const enter = [&](uint32_t ni, Lanes from) {
    Node const& node = tree.nodes[ni];
    Lanes in = 0;
    for (int k = 0; k < K; ++k) {
      uint32_t const lanes = packet_lanes<A, K>(from, k);
      if (!lanes) continue;
      vfloat<A> tn;
      in |= Lanes(simd::movemask(simd::mask_from_bits<A>(lanes) &&
                                 box_hit(r[k], node.lo, node.hi, r[k].tmin, r[k].tmax, tn)))
            << (k * W);
    }
    return in;
  };
  Entry stack[traversal_stack_size];
  int sp = 0;
  if (!isos.overlaps(tree.ranges[0], tree.ranges[1])) return;
  if (Lanes const in = enter(0, pending)) stack[sp++] = {0, in};
  // occlusion_in_pairs: the rays' components per lane, for the pairs.
  TetPairs<A, K> pairs;
  constexpr bool in_pairs = CellOps<A, N>::occlusion_in_pairs;
  alignas(64) float rays[in_pairs ? K : 1][8][W];
  if constexpr (in_pairs)
    for (int k = 0; k < K; ++k) {
      vfloat<A> const* comp[8] = {&r[k].ox, &r[k].oy, &r[k].oz, &r[k].dx, &r[k].dy, &r[k].dz, &r[k].tmin, &r[k].tmax};
      for (int j = 0; j < 8; ++j) simd::store(rays[k][j], *comp[j]);
    }
  while (sp > 0) {
    --sp;
    uint32_t ni = stack[sp].node;
    Lanes entered = stack[sp].lanes & pending;  // occluded since the push: done
    if (!entered) continue;
    // Down to a leaf without the stack while a child is entered (as
    // traverse_packet): any order finds the same answers; the left child is
    // taken first, the right one pushed when both are entered.
    bool reached = true;
    while (!tree.nodes[ni].is_leaf()) {
      uint32_t const li = tree.nodes[ni].left(), ri = tree.nodes[ni].right();
      Lanes const hl = isos.overlaps(tree.ranges[2 * li], tree.ranges[2 * li + 1]) ? enter(li, entered) : 0;
      Lanes const hr = isos.overlaps(tree.ranges[2 * ri], tree.ranges[2 * ri + 1]) ? enter(ri, entered) : 0;
      // The builders cap the depth at MinMaxBvh::max_depth, so the stack holds.
      if (hl && hr) stack[sp++] = {ri, hr};
      if (hl) ni = li, entered = hl;
      else if (hr) ni = ri, entered = hr;
      else {
        reached = false;
        break;
      }
    }
    if (!reached) continue;
    Node const& node = tree.nodes[ni];
    float const* xyz = mesh.positions();
    uint64_t const first = node.first_item();
    for (uint64_t i = first; i < first + node.item_count(); ++i) {
      ScalarCorners<N> sc;
      read_corner_values(mesh, tree.item(i), sc);
      if (!isos.overlaps(sc.lo, sc.hi)) continue;  // false for NaN
      float lo[3], hi[3];
      corner_box(xyz, sc, lo, hi);
      // The box against every packet first: most cells are met by none,
      // and then cost no corner ordering (nor, for hexes, broadcast).
      Lanes const live = entered & pending;
      uint32_t in[K], any_in = 0;
      for (int k = 0; k < K; ++k) {
        uint32_t const lanes = packet_lanes<A, K>(live, k);
        in[k] = 0;
        if (!lanes) continue;
        vfloat<A> tn;
        in[k] = simd::movemask(simd::mask_from_bits<A>(lanes) && box_hit(r[k], lo, hi, r[k].tmin, r[k].tmax, tn));
        any_in |= in[k];
      }
      if (any_in) {
        order_corners(mesh.vertex_count(), sc);
        if constexpr (in_pairs) {
          for (int k = 0; k < K; ++k)
            if (in[k]) pairs.add(xyz, sc, rays[k], k, in[k], pending, isos, method);
        } else {
          CellCorners<A, N> const c = broadcast<A, N>(mesh, sc);
          for (int k = 0; k < K; ++k) {
            if (!in[k]) continue;
            vmask<A> const lanes = simd::mask_from_bits<A>(in[k]);
            CellIsoHit<A> const h =
                iso_in_window(ray_batch(r[k]), c, lanes, r[k].tmin, r[k].tmax, isos.values, isos.count, method);
            pending &= ~(Lanes(simd::movemask(h.hit && lanes)) << (k * W));
          }
        }
      }
      if (!(entered & pending)) break;
    }
  }
  if constexpr (in_pairs) pairs.flush(pending, isos, method);
  for (int k = 0; k < K; ++k) pending_rays[k] = packet_lanes<A, K>(pending, k);
}

/// Direction bin of a ray for regrouping incoherent rays: the cube-map face
/// of `d` (6) and a 4x4 cell on it in Morton order, so consecutive keys are
/// neighbouring directions. 0..95; zero directions get 0. The bin only
/// decides which rays share a packet, never a ray's answer.
inline uint32_t direction_bin(float dx, float dy, float dz) {
  float const ax = dx < 0.f ? -dx : dx, ay = dy < 0.f ? -dy : dy, az = dz < 0.f ? -dz : dz;
  int axis = 0;
  float major = ax, u = dy, v = dz, sign = dx;
  if (ay > major) axis = 1, major = ay, u = dz, v = dx, sign = dy;
  if (az > major) axis = 2, major = az, u = dx, v = dy, sign = dz;
  if (!(major > 0.f)) return 0;
  auto const cell = [major](float x) {
    int const q = int((x / major + 1.f) * 2.f);  // [-1, 1] -> 0..4
    return uint32_t(q < 0 ? 0 : q > 3 ? 3 : q);
  };
  uint32_t const qu = cell(u), qv = cell(v);
  uint32_t const morton = (qu & 1u) | ((qv & 1u) << 1) | ((qu & 2u) << 1) | ((qv & 2u) << 2);
  return uint32_t(2 * axis + (sign < 0.f ? 1 : 0)) * 16u + morton;
}

/// Number of direction_bin values.
inline constexpr uint32_t direction_bins = 96;

/// order[0..n) = 0..n-1 sorted by key[i] < direction_bins, stable: a
/// counting sort (the insertion sort before it took 1.5% of an AO frame,
/// mostly mispredicted compares; std::sort has no place in ISA-unit code,
/// TOOLCHAIN.md).
inline void sort_by_direction_bin(uint16_t* order, int n, uint32_t const* key) {
  uint16_t start[direction_bins + 1] = {};
  for (int i = 0; i < n; ++i) ++start[key[i] + 1];
  for (uint32_t b = 1; b <= direction_bins; ++b) start[b] = uint16_t(start[b] + start[b - 1]);
  for (int i = 0; i < n; ++i) order[start[key[i]]++] = uint16_t(i);
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
