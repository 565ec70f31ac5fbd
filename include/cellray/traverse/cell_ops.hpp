#pragma once
// The cell operations the traversals call, per cell type, on any arch.
// Corners are loaded once per (cell, packet): broadcast for packets, gathered
// for SPMD lanes.

#include <limits>

#include "../mesh/cell_mesh.hpp"
#include "../simd/batch.hpp"
#include "packet.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

template <class A, int N> struct Corners {
  vfloat<A> x[N], y[N], z[N], s[N];
  vint<A> id[N];  ///< global vertex ids (canonical face order)
};

template <class A, int N> inline Corners<A, N> load_corners(CellMesh<N> const& mesh, uint64_t cell) {
  Corners<A, N> c;
  float const* xyz = mesh.positions();
  float const* val = mesh.values();
  for (int k = 0; k < N; ++k) {
    uint64_t const v = mesh.vertex(cell, k);
    c.x[k] = vfloat<A>(xyz[3 * v]);
    c.y[k] = vfloat<A>(xyz[3 * v + 1]);
    c.z[k] = vfloat<A>(xyz[3 * v + 2]);
    c.s[k] = vfloat<A>(val[v]);
    c.id[k] = vint<A>(int32_t(v));
  }
  return c;
}

/// Per-lane cells; lanes outside `active` load cell 0's corners of `safe_cell`.
template <class A, int N>
inline Corners<A, N> load_corners(CellMesh<N> const& mesh, vint<A> const& cells, vmask<A> const& active) {
  Corners<A, N> c;
  alignas(64) int32_t cell_ids[width<A>];
  simd::store(cell_ids, simd::select(simd::to_int_mask(active), cells, vint<A>(0)));
  alignas(64) int32_t vids[N][width<A>];
  for (int l = 0; l < width<A>; ++l)
    for (int k = 0; k < N; ++k) vids[k][l] = int32_t(mesh.vertex(uint64_t(uint32_t(cell_ids[l])), k));
  float const* xyz = mesh.positions();
  for (int k = 0; k < N; ++k) {
    vint<A> const v = simd::load<A>(vids[k]);
    vint<A> const v3 = v * vint<A>(3);
    c.x[k] = simd::gather(xyz, v3);
    c.y[k] = simd::gather(xyz + 1, v3);
    c.z[k] = simd::gather(xyz + 2, v3);
    c.s[k] = simd::gather(mesh.values(), v);
    c.id[k] = v;
  }
  return c;
}

/// Plane functions of a tetrahedron: lambda_i(p) = (n_i . p - d_i) / h_i is
/// the barycentric coordinate of vertex i. Each face plane is computed from
/// its three vertices in ascending global id order, so the two tets sharing
/// a face evaluate bit-identical planes (no cracks, no double coverage).
template <class A> struct TetPlanes {
  vfloat<A> nx[4], ny[4], nz[4], d[4], inv_h[4];
  vmask<A> valid;  ///< false for zero-volume tets (never hit)
};

template <class A> inline TetPlanes<A> tet_planes(Corners<A, 4> const& c) {
  TetPlanes<A> p;
  p.valid = vmask<A>(true);
  static constexpr int face[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  for (int i = 0; i < 4; ++i) {
    // Canonical order of the face's vertices by global id (a 3-sorting
    // network on selects, so packets and SPMD lanes share the code).
    vfloat<A> x[3], y[3], z[3];
    vint<A> id[3];
    for (int j = 0; j < 3; ++j) {
      int const k = face[i][j];
      x[j] = c.x[k], y[j] = c.y[k], z[j] = c.z[k], id[j] = c.id[k];
    }
    auto cswap = [&](int a, int b) {
      vmask<A> const sw = simd::to_float_mask(id[b] < id[a]);
      auto const swi = simd::to_int_mask(sw);
      vint<A> const ia = id[a];
      id[a] = simd::select(swi, id[b], id[a]);
      id[b] = simd::select(swi, ia, id[b]);
      vfloat<A> t = x[a];
      x[a] = simd::select(sw, x[b], x[a]), x[b] = simd::select(sw, t, x[b]);
      t = y[a];
      y[a] = simd::select(sw, y[b], y[a]), y[b] = simd::select(sw, t, y[b]);
      t = z[a];
      z[a] = simd::select(sw, z[b], z[a]), z[b] = simd::select(sw, t, z[b]);
    };
    cswap(0, 1);
    cswap(1, 2);
    cswap(0, 1);
    vfloat<A> const ex = x[1] - x[0], ey = y[1] - y[0], ez = z[1] - z[0];
    vfloat<A> const fx = x[2] - x[0], fy = y[2] - y[0], fz = z[2] - z[0];
    p.nx[i] = ey * fz - ez * fy;
    p.ny[i] = ez * fx - ex * fz;
    p.nz[i] = ex * fy - ey * fx;
    p.d[i] = p.nx[i] * x[0] + p.ny[i] * y[0] + p.nz[i] * z[0];
    vfloat<A> const h = p.nx[i] * c.x[i] + p.ny[i] * c.y[i] + p.nz[i] * c.z[i] - p.d[i];
    p.valid = p.valid && (h != vfloat<A>(0.f)) && !simd::isnan(h);
    p.inv_h[i] = vfloat<A>(1.f) / simd::select(p.valid, h, vfloat<A>(1.f));
  }
  return p;
}

/// [t_in, t_out] of each lane's ray inside the tet (mask false: misses).
/// Only the planes' signs matter: t = (d - n.o) / (n.d) is identical for
/// both neighbours of a face.
template <class A>
inline vmask<A> clip_tet(RayPacket<A> const& r, TetPlanes<A> const& p, vfloat<A>& tin, vfloat<A>& tout) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  tin = vfloat<A>(-inf);
  tout = vfloat<A>(inf);
  vmask<A> ok = p.valid;
  for (int i = 0; i < 4; ++i) {
    vfloat<A> const side = p.inv_h[i];  // sign: which side of plane i is inside
    vfloat<A> const nd = p.nx[i] * r.dx + p.ny[i] * r.dy + p.nz[i] * r.dz;
    vfloat<A> const no = p.nx[i] * r.ox + p.ny[i] * r.oy + p.nz[i] * r.oz - p.d[i];
    vfloat<A> const t = -no / simd::select(nd == vfloat<A>(0.f), vfloat<A>(1.f), nd);
    vmask<A> const entering = (nd * side) > vfloat<A>(0.f);
    vmask<A> const leaving = (nd * side) < vfloat<A>(0.f);
    tin = simd::select(entering, simd::max(tin, t), tin);
    tout = simd::select(leaving, simd::min(tout, t), tout);
    // Parallel to the plane: inside only if the origin is on the inner side.
    ok = ok && !(nd == vfloat<A>(0.f) && no * side < vfloat<A>(0.f));
  }
  return ok && tin <= tout;
}

/// The scalar along the ray in a tet is linear: s(t) = a + b t.
template <class A>
inline void tet_linear_along(RayPacket<A> const& r, TetPlanes<A> const& p, Corners<A, 4> const& c, vfloat<A>& a,
                             vfloat<A>& b) {
  a = vfloat<A>(0.f);
  b = vfloat<A>(0.f);
  for (int i = 0; i < 4; ++i) {
    vfloat<A> const w = c.s[i] * p.inv_h[i];
    a = a + w * (p.nx[i] * r.ox + p.ny[i] * r.oy + p.nz[i] * r.oz - p.d[i]);
    b = b + w * (p.nx[i] * r.dx + p.ny[i] * r.dy + p.nz[i] * r.dz);
  }
}

/// Barycentric point location + interpolation. A point on a shared face
/// counts as inside both neighbours here; sampling takes the first found.
template <class A>
inline vmask<A> locate_tet(TetPlanes<A> const& p, Corners<A, 4> const& c, vfloat<A> const& px, vfloat<A> const& py,
                           vfloat<A> const& pz, vfloat<A>& value) {
  vmask<A> inside = p.valid;
  value = vfloat<A>(0.f);
  for (int i = 0; i < 4; ++i) {
    vfloat<A> const l = (p.nx[i] * px + p.ny[i] * py + p.nz[i] * pz - p.d[i]) * p.inv_h[i];
    inside = inside && l >= vfloat<A>(0.f);
    value = value + l * c.s[i];
  }
  return inside;
}

/// Constant gradient of the linear field in a tet.
template <class A>
inline void gradient_tet(TetPlanes<A> const& p, Corners<A, 4> const& c, vfloat<A>& gx, vfloat<A>& gy, vfloat<A>& gz) {
  gx = gy = gz = vfloat<A>(0.f);
  for (int i = 0; i < 4; ++i) {
    vfloat<A> const w = c.s[i] * p.inv_h[i];
    gx = gx + w * p.nx[i];
    gy = gy + w * p.ny[i];
    gz = gz + w * p.nz[i];
  }
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
