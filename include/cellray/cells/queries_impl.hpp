#pragma once
// Bodies of CellQueries; included by the ISA units only.

#include <limits>

#include "hex.hpp"
#include "queries.hpp"
#include "tet.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace isa_detail {

/// Lane l takes query min(i + l, n - 1): the tail repeats the last query and
/// its results are dropped.
inline uint64_t query_lane(uint64_t i, int l, uint64_t n) { return i + uint64_t(l) < n ? i + uint64_t(l) : n - 1; }

template <class A, int N>
inline CellCorners<A, N> load_cells(CellMesh<N> const& mesh, CellSelect const& sel, uint64_t i, uint64_t n) {
  if (!sel.ids) return broadcast_corners<A, N>(mesh, sel.uniform);
  alignas(64) int32_t ids[width<A>];
  for (int l = 0; l < width<A>; ++l) ids[l] = int32_t(sel.ids[query_lane(i, l, n)]);
  return gather_corners<A, N>(mesh, simd::load<A>(ids), simd::all_lanes<A>());
}

template <class A> inline RayBatch<A> load_rays(RayQuery const* rays, uint64_t i, uint64_t n) {
  alignas(64) float v[6][width<A>];
  for (int l = 0; l < width<A>; ++l) {
    RayQuery const& q = rays[query_lane(i, l, n)];
    v[0][l] = q.ox, v[1][l] = q.oy, v[2][l] = q.oz, v[3][l] = q.dx, v[4][l] = q.dy, v[5][l] = q.dz;
  }
  return {simd::load<A>(v[0]), simd::load<A>(v[1]), simd::load<A>(v[2]),
          simd::load<A>(v[3]), simd::load<A>(v[4]), simd::load<A>(v[5])};
}

template <class A> inline PointBatch<A> load_points(float const* xyz, uint64_t i, uint64_t n) {
  alignas(64) float v[3][width<A>];
  for (int l = 0; l < width<A>; ++l) {
    uint64_t const q = query_lane(i, l, n);
    v[0][l] = xyz[3 * q], v[1][l] = xyz[3 * q + 1], v[2][l] = xyz[3 * q + 2];
  }
  return {simd::load<A>(v[0]), simd::load<A>(v[1]), simd::load<A>(v[2])};
}

template <class A> inline int lanes_left(uint64_t i, uint64_t n) {
  return n - i < uint64_t(width<A>) ? int(n - i) : width<A>;
}

template <class A> inline void store_clip(CellClip<A> const& c, Vec3<A> const* u_in, Vec3<A> const* u_out, uint64_t i,
                                          uint64_t n, ClipOut* out) {
  auto const a = simd::to_array<A>(c.t_in), b = simd::to_array<A>(c.t_out);
  auto const sa = simd::to_array<A>(c.s_in), sb = simd::to_array<A>(c.s_out);
  uint32_t const hit = simd::movemask(c.hit);
  std::array<float, width<A>> u[6] = {};
  if (u_in) {
    u[0] = simd::to_array<A>(u_in->x), u[1] = simd::to_array<A>(u_in->y), u[2] = simd::to_array<A>(u_in->z);
    u[3] = simd::to_array<A>(u_out->x), u[4] = simd::to_array<A>(u_out->y), u[5] = simd::to_array<A>(u_out->z);
  }
  for (int l = 0; l < lanes_left<A>(i, n); ++l) {
    ClipOut& o = out[i + uint64_t(l)];
    o.t_in = a[l], o.t_out = b[l], o.s_in = sa[l], o.s_out = sb[l];
    for (int k = 0; k < 3; ++k) o.u_in[k] = u[k][l], o.u_out[k] = u[3 + k][l];
    o.hit = int32_t((hit >> l) & 1u);
  }
}

template <class A> inline void store_located(Located<A> const& r, uint64_t i, uint64_t n, LocateOut* out) {
  auto const v = simd::to_array<A>(r.value);
  auto const p0 = simd::to_array<A>(r.param.x), p1 = simd::to_array<A>(r.param.y), p2 = simd::to_array<A>(r.param.z);
  uint32_t const in = simd::movemask(r.inside), conv = simd::movemask(r.converged);
  for (int l = 0; l < lanes_left<A>(i, n); ++l) {
    LocateOut& o = out[i + uint64_t(l)];
    o.value = v[l], o.param[0] = p0[l], o.param[1] = p1[l], o.param[2] = p2[l];
    o.inside = int32_t((in >> l) & 1u), o.converged = int32_t((conv >> l) & 1u);
  }
}

template <class A> inline void store_iso(CellIsoHit<A> const& h, uint64_t i, uint64_t n, IsoOut* out) {
  auto const t = simd::to_array<A>(h.t);
  alignas(64) int32_t idx[width<A>];
  simd::store(idx, h.iso_index);
  uint32_t const hit = simd::movemask(h.hit);
  for (int l = 0; l < lanes_left<A>(i, n); ++l) out[i + uint64_t(l)] = {t[l], idx[l], int32_t((hit >> l) & 1u)};
}

template <class A> inline void store_vec(Vec3<A> const& g, uint64_t i, uint64_t n, float* out) {
  auto const x = simd::to_array<A>(g.x), y = simd::to_array<A>(g.y), z = simd::to_array<A>(g.z);
  for (int l = 0; l < lanes_left<A>(i, n); ++l) {
    float* o = out + 3 * (i + uint64_t(l));
    o[0] = x[l], o[1] = y[l], o[2] = z[l];
  }
}

template <class A, int N>
inline void run_clip(CellMesh<N> const& mesh, CellSelect const& sel, RayQuery const* rays, uint64_t n, ClipOut* out) {
  for (uint64_t i = 0; i < n; i += uint64_t(width<A>)) {
    CellCorners<A, N> const c = load_cells<A, N>(mesh, sel, i, n);
    RayBatch<A> const r = load_rays<A>(rays, i, n);
    if constexpr (N == 4) {
      store_clip<A>(clip_tet<A>(r, c), nullptr, nullptr, i, n, out);
    } else {
      HexClip<A> const h = clip_hex<A>(r, c);
      store_clip<A>(h, &h.u_in, &h.u_out, i, n, out);
    }
  }
}

template <class A, int N>
inline void run_locate(CellMesh<N> const& mesh, CellSelect const& sel, float const* xyz, uint64_t n, LocateOut* out) {
  for (uint64_t i = 0; i < n; i += uint64_t(width<A>)) {
    CellCorners<A, N> const c = load_cells<A, N>(mesh, sel, i, n);
    PointBatch<A> const p = load_points<A>(xyz, i, n);
    if constexpr (N == 4) store_located<A>(locate_tet<A>(p, c), i, n, out);
    else store_located<A>(locate_hex<A>(p, c), i, n, out);
  }
}

template <class A, int N>
inline void run_gradient(CellMesh<N> const& mesh, CellSelect const& sel, float const* xyz, uint64_t n,
                         GradientMethod method, float h, float* out) {
  for (uint64_t i = 0; i < n; i += uint64_t(width<A>)) {
    CellCorners<A, N> const c = load_cells<A, N>(mesh, sel, i, n);
    PointBatch<A> const p = load_points<A>(xyz, i, n);
    if constexpr (N == 4) {
      store_vec<A>(method != GradientMethod::central ? gradient_tet<A>(c) : gradient_central_tet<A>(c, p.p(), h), i,
                   n, out);
    } else {
      Located<A> const L = locate_hex<A>(p, c);
      store_vec<A>(method != GradientMethod::central ? gradient_hex<A>(c, L.param)
                                                      : gradient_central_hex<A>(c, p.p(), L.param, h),
                   i, n, out);
    }
  }
}

template <class A, int N>
inline void run_iso(CellMesh<N> const& mesh, CellSelect const& sel, RayQuery const* rays, uint64_t n,
                    float const* iso, int count, CellIsoOptions const& opt, IsoOut* out) {
  for (uint64_t i = 0; i < n; i += uint64_t(width<A>)) {
    CellCorners<A, N> const c = load_cells<A, N>(mesh, sel, i, n);
    RayBatch<A> const r = load_rays<A>(rays, i, n);
    if constexpr (N == 4) {
      CellClip<A> const k = clip_tet<A>(r, c);
      store_iso<A>(opt.method == CellIsoMethod::exact ? iso_root_tet<A>(k, c, iso, count)
                                                  : iso_root_tet_neubauer<A>(r, k, c, iso, count, opt.neubauer_steps),
                   i, n, out);
    } else {
      HexClip<A> const k = clip_hex<A>(r, c);
      store_iso<A>(opt.method == CellIsoMethod::exact ? iso_root_hex<A>(r, k, c, iso, count, opt.refine_steps)
                                                  : iso_root_hex_neubauer<A>(r, k, c, iso, count, opt.neubauer_steps),
                   i, n, out);
    }
  }
}

}  // namespace isa_detail
}  // namespace CELLRAY_ISA_NS

template <class Arch>
void CellQueries<Arch>::run(TetMesh const& m, CellSelect s, RayQuery const* r, uint64_t n, ClipOut* o) {
  CELLRAY_ISA_NS::isa_detail::run_clip<Arch>(m, s, r, n, o);
}
template <class Arch>
void CellQueries<Arch>::run(HexMesh const& m, CellSelect s, RayQuery const* r, uint64_t n, ClipOut* o) {
  CELLRAY_ISA_NS::isa_detail::run_clip<Arch>(m, s, r, n, o);
}
template <class Arch>
void CellQueries<Arch>::run(TetMesh const& m, CellSelect s, float const* p, uint64_t n, LocateOut* o) {
  CELLRAY_ISA_NS::isa_detail::run_locate<Arch>(m, s, p, n, o);
}
template <class Arch>
void CellQueries<Arch>::run(HexMesh const& m, CellSelect s, float const* p, uint64_t n, LocateOut* o) {
  CELLRAY_ISA_NS::isa_detail::run_locate<Arch>(m, s, p, n, o);
}
template <class Arch>
void CellQueries<Arch>::run(TetMesh const& m, CellSelect s, float const* p, uint64_t n, GradientMethod g, float h,
                                 float* o) {
  CELLRAY_ISA_NS::isa_detail::run_gradient<Arch>(m, s, p, n, g, h, o);
}
template <class Arch>
void CellQueries<Arch>::run(HexMesh const& m, CellSelect s, float const* p, uint64_t n, GradientMethod g, float h,
                                 float* o) {
  CELLRAY_ISA_NS::isa_detail::run_gradient<Arch>(m, s, p, n, g, h, o);
}
template <class Arch>
void CellQueries<Arch>::run(TetMesh const& m, CellSelect s, RayQuery const* r, uint64_t n, float const* v, int k,
                            CellIsoOptions opt, IsoOut* o) {
  CELLRAY_ISA_NS::isa_detail::run_iso<Arch>(m, s, r, n, v, k, opt, o);
}
template <class Arch>
void CellQueries<Arch>::run(HexMesh const& m, CellSelect s, RayQuery const* r, uint64_t n, float const* v, int k,
                            CellIsoOptions opt, IsoOut* o) {
  CELLRAY_ISA_NS::isa_detail::run_iso<Arch>(m, s, r, n, v, k, opt, o);
}

}  // namespace cellray
