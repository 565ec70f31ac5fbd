#pragma once
// What every cell kernel consumes: a batch of rays or points, and the corners
// of one cell per lane (the same cell in every lane for packet traversal, a
// different cell per lane for SPMD traversal), with loaders for both.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <utility>

#include "../mesh/cell_mesh.hpp"
#include "../simd/batch.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

/// Three batches: one 3-vector per lane.
template <class A> struct Vec3 {
  vfloat<A> x, y, z;
};

template <class A> inline Vec3<A> operator+(Vec3<A> const& a, Vec3<A> const& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <class A> inline Vec3<A> operator-(Vec3<A> const& a, Vec3<A> const& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <class A> inline Vec3<A> operator*(vfloat<A> const& s, Vec3<A> const& a) { return {s * a.x, s * a.y, s * a.z}; }
template <class A> inline vfloat<A> dot(Vec3<A> const& a, Vec3<A> const& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <class A> inline Vec3<A> cross(Vec3<A> const& a, Vec3<A> const& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class A> inline Vec3<A> select(vmask<A> const& m, Vec3<A> const& a, Vec3<A> const& b) {
  return {simd::select(m, a.x, b.x), simd::select(m, a.y, b.y), simd::select(m, a.z, b.z)};
}
/// a + t (b - a).
template <class A> inline vfloat<A> lerp(vfloat<A> const& a, vfloat<A> const& b, vfloat<A> const& t) { return a + t * (b - a); }
template <class A> inline Vec3<A> lerp(Vec3<A> const& a, Vec3<A> const& b, vfloat<A> const& t) {
  return {lerp<A>(a.x, b.x, t), lerp<A>(a.y, b.y, t), lerp<A>(a.z, b.z, t)};
}

/// One ray per lane: origin and direction (any length, not normalized: every
/// `t` the kernels return is in units of this direction). Kernels treat the
/// ray as the full line; callers clip to their own [t_min, t_max].
template <class A> struct RayBatch {
  vfloat<A> ox, oy, oz, dx, dy, dz;
  Vec3<A> origin() const { return {ox, oy, oz}; }
  Vec3<A> dir() const { return {dx, dy, dz}; }
};

/// One query point per lane.
template <class A> struct PointBatch {
  vfloat<A> x, y, z;
  Vec3<A> p() const { return {x, y, z}; }
};

/// The corners of one cell per lane: positions, scalar values (the active
/// array; NaN when the mesh has none) and global vertex ids. Hexahedra keep
/// VTK node order. Tetrahedra from the loaders are stored in ascending global
/// vertex id order (any orientation): the tet kernels build each face plane
/// from its vertices in that order, so two cells sharing a face evaluate
/// bit-identical expressions for it (watertightness). Hand-built corners
/// work in any order, only without that guarantee. `id` is an ordering key:
/// the kernels only compare the ids of one cell's corners with each other,
/// so the loaders store the global vertex id itself when the mesh has at
/// most 2^31 vertices, and the corner's rank among its cell's ids (0..N-1,
/// compared on all 64 bits) beyond: the same order, exact for any id.
namespace isa_detail {
/// Hexes only (CellCorners<A, 8>): `uniform` is true when every lane holds
/// the same cell (set by broadcast, the packet loader), and `uniform_key`
/// then holds its ordering keys as scalars, so the kernels take per-cell
/// decisions (a face's canonical corner order) once in scalar code instead
/// of per lane with selects. The decisions are the same comparisons on the
/// same keys, so both ways give bit-identical results. False from
/// gather_corners and for hand-built corners. Tets take no such decision
/// and carry nothing (empty base).
template <int N> struct UniformKeys {};
template <> struct UniformKeys<8> {
  bool uniform = false;
  int32_t uniform_key[8];
};
}  // namespace isa_detail

template <class A, int N> struct CellCorners : isa_detail::UniformKeys<N> {
  vfloat<A> x[N], y[N], z[N], s[N];
  vint<A> id[N];
  Vec3<A> p(int i) const { return {x[i], y[i], z[i]}; }
};

/// Ordering keys (CellCorners::id) of one cell's corners from their global
/// vertex ids `v`: the ids themselves when every id of the mesh fits in 31
/// bits (`vertex_count` <= 2^31), else their ranks within the cell, compared
/// on all 64 bits (equal ids, a degenerate cell, rank by corner index). Any
/// loader that fills CellCorners must use it so that neighbours order a
/// shared face alike.
template <int N> inline void corner_keys(uint64_t vertex_count, uint64_t const (&v)[N], int32_t (&key)[N]) {
  if (vertex_count <= (uint64_t(1) << 31)) {
    for (int i = 0; i < N; ++i) key[i] = int32_t(v[i]);
    return;
  }
  for (int i = 0; i < N; ++i) {
    int32_t r = 0;
    for (int j = 0; j < N; ++j) r += int32_t(v[j] < v[i] || (v[j] == v[i] && j < i));
    key[i] = r;
  }
}

namespace isa_detail {

template <class A, int N> inline void swap_corners_if(CellCorners<A, N>& c, int i, int j) {
  // Compare-exchange on the id: a sorting network step on whole corners.
  vmaski<A> const mi = c.id[i] > c.id[j];
  vmask<A> const m = simd::to_float_mask(mi);
  vint<A> const id_i = simd::select(mi, c.id[j], c.id[i]);
  c.id[j] = simd::select(mi, c.id[i], c.id[j]);
  c.id[i] = id_i;
  vfloat<A>* comps[4] = {c.x, c.y, c.z, c.s};
  for (vfloat<A>* v : comps) {
    vfloat<A> const lo = simd::select(m, v[j], v[i]);
    v[j] = simd::select(m, v[i], v[j]);
    v[i] = lo;
  }
}

/// sort_tet_corners' network on four id vectors alone.
template <class A> inline void sort_tet_ids(vint<A> (&vs)[4]) {
  auto cmpx = [&vs](int i, int j) {
    vmaski<A> const m = vs[i] > vs[j];
    vint<A> const lo = simd::select(m, vs[j], vs[i]);
    vs[j] = simd::select(m, vs[i], vs[j]);
    vs[i] = lo;
  };
  cmpx(0, 1), cmpx(2, 3), cmpx(0, 2), cmpx(1, 3), cmpx(1, 2);
}

template <class A> inline void sort_tet_corners(CellCorners<A, 4>& c) {
  swap_corners_if(c, 0, 1);
  swap_corners_if(c, 2, 3);
  swap_corners_if(c, 0, 2);
  swap_corners_if(c, 1, 3);
  swap_corners_if(c, 1, 2);
}

}  // namespace isa_detail

/// One cell's corners as read by packet traversal before it broadcasts
/// them: vertex ids, values (NaN when the mesh has none) and ordering keys,
/// tets in canonical order (sorted by key with sort_tet_corners' network, so
/// the same order). Scalar, so a leaf can reject a cell on its values before
/// loading positions or sorting five vectors.
template <int N> struct ScalarCorners {
  uint64_t v[N];
  float s[N];
  int32_t key[N];
  float lo, hi;  ///< value range of the corners; NaN if any value is NaN or +-inf (read as NaN)
};

/// Reads ids and values of `cell` (not yet ordered). No range check.
template <int N> CELLRAY_FORCE_INLINE void read_corner_values(CellMesh<N> const& mesh, uint64_t cell, ScalarCorners<N>& k) {
  constexpr float qnan = std::numeric_limits<float>::quiet_NaN();
  float const* val = mesh.values();
  // Index width and value presence decided once per cell, not per corner
  // (leaves call this for every item they reach).
  if (mesh.has_32bit_indices()) {
    uint32_t const* ix = mesh.indices32() + cell * uint64_t(N);
    for (int i = 0; i < N; ++i) k.v[i] = ix[i];
  } else {
    uint64_t const* ix = mesh.indices64() + cell * uint64_t(N);
    for (int i = 0; i < N; ++i) k.v[i] = ix[i];
  }
  if (!val) {
    for (int i = 0; i < N; ++i) k.s[i] = qnan;
    k.lo = k.hi = qnan;
    return;
  }
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  bool nan = false;
  for (int i = 0; i < N; ++i) {
    k.s[i] = simd::finite_or_nan(val[k.v[i]]);
    nan = nan || !(k.s[i] == k.s[i]);
    lo = std::min(lo, k.s[i]);
    hi = std::max(hi, k.s[i]);
  }
  k.lo = nan ? qnan : lo;
  k.hi = nan ? qnan : hi;
}

/// Bounding box of the corners `k` (positions `xyz`, 3 floats per vertex),
/// in any corner order: the same floats as a box over the broadcast corners,
/// so a box test on it gives the same answer, before ordering or broadcasting.
template <int N>
CELLRAY_FORCE_INLINE void corner_box(float const* xyz, ScalarCorners<N> const& k, float (&lo)[3], float (&hi)[3]) {
  for (int a = 0; a < 3; ++a) lo[a] = hi[a] = xyz[3 * k.v[0] + uint64_t(a)];
  for (int i = 1; i < N; ++i)
    for (int a = 0; a < 3; ++a) {
      float const x = xyz[3 * k.v[i] + uint64_t(a)];
      lo[a] = std::min(lo[a], x), hi[a] = std::max(hi[a], x);
    }
}

/// Computes the keys (corner_keys) and, for tets, puts the corners in
/// canonical order.
template <int N> CELLRAY_FORCE_INLINE void order_corners(uint64_t vertex_count, ScalarCorners<N>& k) {
  corner_keys<N>(vertex_count, k.v, k.key);
  if constexpr (N == 4) {
    auto swap_if = [&k](int i, int j) {
      if (k.key[i] > k.key[j]) std::swap(k.v[i], k.v[j]), std::swap(k.s[i], k.s[j]), std::swap(k.key[i], k.key[j]);
    };
    swap_if(0, 1), swap_if(2, 3), swap_if(0, 2), swap_if(1, 3), swap_if(1, 2);
  }
}

/// The ordered corners `k` in every lane, with their positions.
template <class A, int N>
CELLRAY_FORCE_INLINE CellCorners<A, N> broadcast(CellMesh<N> const& mesh, ScalarCorners<N> const& k) {
  CellCorners<A, N> c;
  float const* xyz = mesh.positions();
  for (int i = 0; i < N; ++i) {
    float const* q = xyz + 3 * k.v[i];
    c.x[i] = vfloat<A>(q[0]);
    c.y[i] = vfloat<A>(q[1]);
    c.z[i] = vfloat<A>(q[2]);
    c.s[i] = vfloat<A>(k.s[i]);
    c.id[i] = vint<A>(k.key[i]);
    if constexpr (N == 8) c.uniform_key[i] = k.key[i];
  }
  if constexpr (N == 8) c.uniform = true;
  return c;
}

/// The corners of `cell` in every lane (packet traversal). No range check.
template <class A, int N> inline CellCorners<A, N> broadcast_corners(CellMesh<N> const& mesh, uint64_t cell) {
  ScalarCorners<N> k;
  read_corner_values(mesh, cell, k);
  order_corners(mesh.vertex_count(), k);
  return broadcast<A, N>(mesh, k);
}

/// The corners of `cells[i]` in lane i (SPMD traversal). Inactive lanes load
/// cell 0 (the mesh must not be empty); their contents are meaningless.
/// Native gathers when offsets fit in 31 bits (cell*N and 3*vertex), else a
/// scalar loop. Forced inline: see march_step (dvr_integrators_impl.hpp).
/// Written into `c` (a march's corners stay in place: see CellMarch::last).
template <class A, int N>
CELLRAY_FORCE_INLINE void gather_corners_into(CellCorners<A, N>& c, CellMesh<N> const& mesh, vint<A> const& cells,
                                              vmask<A> const& active) {
  if constexpr (N == 8) c.uniform = false;
  vint<A> const cell = simd::select(simd::to_int_mask(active), cells, vint<A>(0));
  float const* xyz = mesh.positions();
  float const* val = mesh.values();
  constexpr uint64_t lim = uint64_t(std::numeric_limits<int32_t>::max());
  if (mesh.has_32bit_indices() && mesh.cell_count() * N < lim && mesh.vertex_count() * 3 < lim) {
    auto const* idx = reinterpret_cast<int32_t const*>(mesh.indices32());
    // A cell's ids are one row: four at a time by 16-byte loads and a
    // transpose (gather_quads), not a gather each.
    vint<A> vs[N];
    for (int h = 0; h < N; h += 4) {
      vint<A> q[4];
      simd::gather_quads(idx, cell * vint<A>(N) + vint<A>(h), q);
      for (int k = 0; k < 4; ++k) vs[h + k] = q[k];
    }
    // sort_tet_corners' network on the ids alone (here id = vertex index),
    // before the loads: the same order, without permuting 5 x 4 vectors.
    if constexpr (N == 4) isa_detail::sort_tet_ids<A>(vs);
    int32_t const last = int32_t(3 * (mesh.vertex_count() - 1));
    for (int i = 0; i < N; ++i) {
      vint<A> const v = vs[i];
      vint<A> const v3 = v * vint<A>(3);
      simd::gather_xyz(xyz, v3, last, c.x[i], c.y[i], c.z[i]);
      c.s[i] = val ? simd::finite_or_nan(simd::gather(val, v)) : vfloat<A>(std::numeric_limits<float>::quiet_NaN());
      c.id[i] = v;
    }
    return;
  } else {
    alignas(64) int32_t cid[width<A>];
    simd::store(cid, cell);
    alignas(64) float fx[N][width<A>], fy[N][width<A>], fz[N][width<A>], fs[N][width<A>];
    alignas(64) int32_t ids[N][width<A>];
    for (int l = 0; l < width<A>; ++l) {
      uint64_t vs[N];
      int32_t key[N];
      for (int i = 0; i < N; ++i) vs[i] = mesh.vertex(uint64_t(uint32_t(cid[l])), i);
      corner_keys<N>(mesh.vertex_count(), vs, key);
      for (int i = 0; i < N; ++i) {
        uint64_t const v = vs[i];
        fx[i][l] = xyz[3 * v], fy[i][l] = xyz[3 * v + 1], fz[i][l] = xyz[3 * v + 2];
        fs[i][l] = val ? simd::finite_or_nan(val[v]) : std::numeric_limits<float>::quiet_NaN();
        ids[i][l] = key[i];
      }
    }
    for (int i = 0; i < N; ++i) {
      c.x[i] = simd::load<A>(fx[i]), c.y[i] = simd::load<A>(fy[i]), c.z[i] = simd::load<A>(fz[i]);
      c.s[i] = simd::load<A>(fs[i]), c.id[i] = simd::load<A>(ids[i]);
    }
  }
  if constexpr (N == 4) isa_detail::sort_tet_corners(c);
}

/// gather_corners_into, returned.
template <class A, int N>
CELLRAY_FORCE_INLINE CellCorners<A, N> gather_corners(CellMesh<N> const& mesh, vint<A> const& cells,
                                                      vmask<A> const& active) {
  CellCorners<A, N> c;
  gather_corners_into<A, N>(c, mesh, cells, active);
  return c;
}

/// True in lanes whose cell has a NaN vertex value: such cells are invisible
/// to iso and DVR (the rule of mesh/cell_boxes.hpp).
template <class A, int N> inline vmask<A> has_nan_value(CellCorners<A, N> const& c) {
  vmask<A> m = simd::isnan(c.s[0]);
  for (int i = 1; i < N; ++i) m = m || simd::isnan(c.s[i]);
  return m;
}

/// Shading normal from a field gradient: -g/|g|, pointing from higher to lower
/// values (out of the region {value >= iso}), the same orientation all over
/// an isosurface whichever side the ray comes from. A zero or non-finite
/// gradient gives -dir/|dir| (facing the viewer), never NaN.
template <class A> inline Vec3<A> shading_normal(Vec3<A> const& g, Vec3<A> const& dir) {
  vfloat<A> const gg = dot(g, g);
  vmask<A> const ok = gg > vfloat<A>(0.f) && gg < vfloat<A>(std::numeric_limits<float>::infinity());
  Vec3<A> const v = select<A>(ok, vfloat<A>(-1.f) * g, vfloat<A>(-1.f) * dir);
  vfloat<A> const len2 = dot(v, v);
  return (vfloat<A>(1.f) / simd::sqrt(simd::select(len2 > vfloat<A>(0.f), len2, vfloat<A>(1.f)))) * v;
}

/// `n` flipped, where needed, to face against `dir` (two-sided shading).
template <class A> inline Vec3<A> face_forward(Vec3<A> const& n, Vec3<A> const& dir) {
  return select<A>(dot(n, dir) > vfloat<A>(0.f), vfloat<A>(-1.f) * n, n);
}

namespace isa_detail {

/// The field (or a gradient component) along a clip's segment as a cubic in
/// lambda = (t - t_in) / (t_out - t_in): what CellOps::segment_field gives.
template <class A> struct Cubic {
  vfloat<A> c0, c1, c2, c3;
  vfloat<A> operator()(vfloat<A> const& x) const { return ((c3 * x + c2) * x + c1) * x + c0; }
  vfloat<A> slope(vfloat<A> const& x) const { return (vfloat<A>(3.f) * c3 * x + vfloat<A>(2.f) * c2) * x + c1; }
};

/// The cubic through (0, f0), (1/3, f1), (2/3, f2), (1, f3) (Newton forward
/// differences, step 1/3).
template <class A> inline Cubic<A> cubic_through(vfloat<A> f0, vfloat<A> f1, vfloat<A> f2, vfloat<A> f3) {
  vfloat<A> const d1 = f1 - f0, d2 = f2 - vfloat<A>(2.f) * f1 + f0;
  vfloat<A> const d3 = f3 - vfloat<A>(3.f) * f2 + vfloat<A>(3.f) * f1 - f0;
  return {f0, vfloat<A>(3.f) * d1 - vfloat<A>(1.5f) * d2 + d3, vfloat<A>(4.5f) * (d2 - d3), vfloat<A>(4.5f) * d3};
}

}  // namespace isa_detail

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
