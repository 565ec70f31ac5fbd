#pragma once
// Point location through the min-max BVH (ISA units only): the query behind
// sample_points. W points descend together as a packet, but with no ray set-up:
// a node is entered by the points inside its box (six compares per child, all
// lanes at once), a leaf's cell is tested against the points inside the
// cell's box (its corners in scalar, then one compare per lane), and only
// those points are located in the cell, W at a time (CellOps::locate: the
// tet's barycentric test, the hex's Newton inversion). A point stops at the
// first cell that holds it (in the tree's order, left child first); the
// packet stops when every point has.
// Packets are coherent only if consecutive points are near each other:
// sample_points sorts them along a Morton curve first (point_order.hpp).

#include <cmath>
#include <cstdint>
#include <limits>

#include "cell_ops.hpp"
#include "traverse.hpp"
#include "tree_view.hpp"

namespace cellray {

/// Barycentric tolerance of the second chance a tet gives a point that no
/// cell holds by the half-open face rule (tet.hpp's locate_tet): a point
/// exactly on an edge or vertex shared by several tets can fall outside all
/// of them by the rounding of the four independent plane tests (weights of
/// -1e-7 relative on the generated meshes). Such a point takes the value of
/// the first tet whose weights are all >= -tolerance (extrapolated by at most
/// that fraction of the cell's value spread), so the mesh has no cracks;
/// points held by a cell are never affected. Hexes need none: locate_hex's
/// containment is already widened by hex_inside_tolerance.
inline constexpr float probe_tet_tolerance = 1e-5f;

inline namespace CELLRAY_ISA_NS {

/// Locates one packet of up to W points in one mesh.
template <class A, int N> struct PointPacket {
  static constexpr int W = width<A>;
  TreeView const& tree;
  CellMesh<N> const& mesh;
  PointBatch<A> p;
  float lo[3], hi[3];     ///< bounds of the packet's points (scalar cull of cells)
  uint32_t pending = 0;   ///< lanes no cell holds yet
  uint32_t near = 0;      ///< lanes with a tolerance-band candidate (tets)
  alignas(64) float value[W];
  alignas(64) float near_value[W];

  /// `px`, `py`, `pz`: W coordinates each; `active`: the lanes to locate
  /// (finite coordinates only).
  PointPacket(TreeView const& t, CellMesh<N> const& m, float const* px, float const* py, float const* pz,
              uint32_t active)
      : tree(t), mesh(m), pending(active) {
    p = PointBatch<A>{simd::load<A>(px), simd::load<A>(py), simd::load<A>(pz)};
    constexpr float inf = std::numeric_limits<float>::infinity();
    for (int a = 0; a < 3; ++a) lo[a] = inf, hi[a] = -inf;
    for (uint32_t b = active; b; b &= b - 1) {
      int const l = __builtin_ctz(b);
      float const q[3] = {px[l], py[l], pz[l]};
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], q[a]), hi[a] = std::max(hi[a], q[a]);
    }
  }

  /// Lanes inside the closed box [blo, bhi] (false for NaN).
  CELLRAY_FORCE_INLINE uint32_t in_box(float const blo[3], float const bhi[3]) const {
    return simd::movemask(p.x >= vfloat<A>(blo[0]) && p.x <= vfloat<A>(bhi[0]) && p.y >= vfloat<A>(blo[1]) &&
                          p.y <= vfloat<A>(bhi[1]) && p.z >= vfloat<A>(blo[2]) && p.z <= vfloat<A>(bhi[2]));
  }

  /// The cells of leaf slots [first, first + count) for the lanes `m`.
  void leaf(uint64_t first, uint32_t count, uint32_t m) {
    float const* xyz = mesh.positions();
    // Every cell's index row first: they are the leaf's cache misses (the
    // host's cell order need not follow space), and the loop below branches
    // on each cell's box before it reads the next (component8: 0.96x time).
    for (uint64_t i = first; i < first + count; ++i) {
      uint64_t const cell = tree.item(i);
      if (mesh.has_32bit_indices()) __builtin_prefetch(mesh.indices32() + cell * uint64_t(N));
      else __builtin_prefetch(mesh.indices64() + cell * uint64_t(N));
    }
    for (uint64_t i = first; i < first + count; ++i) {
      uint64_t const cell = tree.item(i);
      uint64_t v[N];
      if (mesh.has_32bit_indices()) {
        uint32_t const* ix = mesh.indices32() + cell * uint64_t(N);
        for (int k = 0; k < N; ++k) v[k] = ix[k];
      } else {
        uint64_t const* ix = mesh.indices64() + cell * uint64_t(N);
        for (int k = 0; k < N; ++k) v[k] = ix[k];
      }
      float clo[3], chi[3];
      for (int a = 0; a < 3; ++a) clo[a] = chi[a] = xyz[3 * v[0] + uint64_t(a)];
      for (int k = 1; k < N; ++k)
        for (int a = 0; a < 3; ++a) {
          float const x = xyz[3 * v[k] + uint64_t(a)];
          clo[a] = std::min(clo[a], x), chi[a] = std::max(chi[a], x);
        }
      // The packet's bounds first (scalar): most cells of a leaf miss them.
      if (clo[0] > hi[0] || chi[0] < lo[0] || clo[1] > hi[1] || chi[1] < lo[1] || clo[2] > hi[2] || chi[2] < lo[2])
        continue;
      uint32_t const in = m & pending & in_box(clo, chi);
      if (!in) continue;
      ScalarCorners<N> k;
      read_corner_values(mesh, cell, k);
      if (!(k.lo == k.lo)) continue;  // a NaN (or +-inf) corner value: the cell holds nothing
      order_corners(mesh.vertex_count(), k);
      CellCorners<A, N> const c = broadcast<A, N>(mesh, k);
      Located<A> const loc = CellOps<A, N>::locate(p, c, simd::mask_from_bits<A>(in));
      uint32_t const held = in & simd::movemask(loc.inside);
      if (held) {
        alignas(64) float v_all[W];
        simd::store(v_all, loc.value);
        for (uint32_t b = held; b; b &= b - 1) value[__builtin_ctz(b)] = v_all[__builtin_ctz(b)];
        pending &= ~held;
      }
      if (uint32_t const band = in & ~held & ~near) {
        uint32_t const close = band & simd::movemask(CellOps<A, N>::nearly_inside(loc, probe_tet_tolerance));
        if (close) {
          alignas(64) float v_all[W];
          simd::store(v_all, loc.value);
          for (uint32_t b = close; b; b &= b - 1) near_value[__builtin_ctz(b)] = v_all[__builtin_ctz(b)];
          near |= close;
        }
      }
      if (!(m & pending)) return;
    }
  }

  /// Descends from the root; returns when every lane is held or the tree is done.
  void run() {
    if (tree.empty() || !pending) return;
    struct Entry {
      uint32_t node, lanes;
    };
    Entry stack[traversal_stack_size];
    int sp = 0;
    {
      Node const& root = tree.nodes[0];
      uint32_t const m = pending & in_box(root.lo, root.hi);
      if (!m) return;
      stack[sp++] = Entry{0, m};
    }
    while (sp > 0) {
      Entry const e = stack[--sp];
      uint32_t ni = e.node, m = e.lanes & pending;
      // Down without the stack while a child holds points; the other child
      // of a split is pushed (every child box a point lies in is visited:
      // boxes overlap, and the first cell that holds the point may be in any).
      while (m) {
        Node const& node = tree.nodes[ni];
        if (node.is_leaf()) {
          leaf(node.first_item(), node.item_count(), m);
          if (!pending) return;
          break;
        }
        uint32_t const li = node.left(), ri = node.right();
        uint32_t const ml = m & in_box(tree.nodes[li].lo, tree.nodes[li].hi);
        uint32_t const mr = m & in_box(tree.nodes[ri].lo, tree.nodes[ri].hi);
        if (ml && mr) {
          // Always the left child first: each point then meets the cells
          // whose boxes hold it in the tree's own order, whatever points
          // share its packet, so the cell it stops at (and its value) does
          // not depend on the order or number of the points, nor on W.
          // The builders cap the depth at MinMaxBvh::max_depth: the stack holds.
          stack[sp++] = Entry{ri, mr};
          ni = li, m = ml;
        } else if (ml) {
          ni = li, m = ml;
        } else if (mr) {
          ni = ri, m = mr;
        } else {
          break;
        }
      }
    }
  }
};

/// Fills the NaN entries of values[0, n) with the mesh's field at the points
/// xyz[3i, 3i + 3) (entries already set, e.g. by an earlier part, are left
/// alone and their points not located). Points in no cell, or only in cells
/// with a NaN corner value, stay NaN.
template <class A, int N>
void probe_points(TreeView const& tree, CellMesh<N> const& mesh, float const* xyz, uint64_t n, float* values) {
  constexpr int W = width<A>;
  if (tree.empty()) return;
  for (uint64_t base = 0; base < n; base += W) {
    int const cnt = int(std::min<uint64_t>(W, n - base));
    alignas(64) float px[W] = {}, py[W] = {}, pz[W] = {};
    uint32_t active = 0;
    for (int l = 0; l < cnt; ++l) {
      uint64_t const i = base + uint64_t(l);
      if (values[i] == values[i]) continue;
      float const x = xyz[3 * i], y = xyz[3 * i + 1], z = xyz[3 * i + 2];
      if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) continue;
      px[l] = x, py[l] = y, pz[l] = z;
      active |= 1u << l;
    }
    if (!active) continue;
    PointPacket<A, N> q(tree, mesh, px, py, pz, active);
    q.run();
    for (uint32_t b = active; b; b &= b - 1) {
      int const l = __builtin_ctz(b);
      if (!((q.pending >> l) & 1u)) values[base + uint64_t(l)] = q.value[l];
      else if ((q.near >> l) & 1u) values[base + uint64_t(l)] = q.near_value[l];
    }
  }
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
