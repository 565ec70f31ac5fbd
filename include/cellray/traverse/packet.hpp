#pragma once
// Ray batches and the ray-box slab test, on any arch (ISA units only).

#include <cmath>
#include <limits>

#include "../simd/batch.hpp"
#include "ray.hpp"
#include "tree_view.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

/// W rays, structure of arrays. `rx` = 1 / dx with zero components replaced
/// by a tiny value of the same sign, so a ray lying in a slab plane gets
/// finite slab distances instead of 0 * inf = NaN.
template <class A> struct RayPacket {
  vfloat<A> ox, oy, oz, dx, dy, dz, rx, ry, rz, tmin, tmax;
};

namespace impl {
inline float safe_rcp(float d) {
  float const tiny = 1e-30f;
  return 1.f / (std::fabs(d) < tiny ? std::copysign(tiny, d) : d);
}
}  // namespace impl

/// Loads W consecutive rays (lanes past `n` repeat the last ray; callers mask them).
template <class A> inline RayPacket<A> load_rays(Ray const* rays, int n) {
  constexpr int W = width<A>;
  alignas(64) float f[11][W];
  for (int l = 0; l < W; ++l) {
    Ray const& r = rays[l < n ? l : n - 1];
    f[0][l] = r.org.x, f[1][l] = r.org.y, f[2][l] = r.org.z;
    f[3][l] = r.dir.x, f[4][l] = r.dir.y, f[5][l] = r.dir.z;
    f[6][l] = impl::safe_rcp(r.dir.x), f[7][l] = impl::safe_rcp(r.dir.y), f[8][l] = impl::safe_rcp(r.dir.z);
    f[9][l] = r.tmin, f[10][l] = r.tmax;
  }
  RayPacket<A> p;
  vfloat<A>* dst[11] = {&p.ox, &p.oy, &p.oz, &p.dx, &p.dy, &p.dz, &p.rx, &p.ry, &p.rz, &p.tmin, &p.tmax};
  for (int k = 0; k < 11; ++k) *dst[k] = simd::load<A>(f[k]);
  return p;
}

/// Slab test of every lane against one box, clipped to [t0, t1]. Returns the
/// lanes that overlap and their entry distance. The exit distance is widened
/// by a few ulps so float rounding never culls a box a cell kernel would hit.
template <class A>
CELLRAY_FORCE_INLINE vmask<A> box_hit(RayPacket<A> const& r, float const lo[3], float const hi[3], vfloat<A> const& t0,
                        vfloat<A> const& t1, vfloat<A>& tnear) {
  vfloat<A> const ax = (vfloat<A>(lo[0]) - r.ox) * r.rx, bx = (vfloat<A>(hi[0]) - r.ox) * r.rx;
  vfloat<A> const ay = (vfloat<A>(lo[1]) - r.oy) * r.ry, by = (vfloat<A>(hi[1]) - r.oy) * r.ry;
  vfloat<A> const az = (vfloat<A>(lo[2]) - r.oz) * r.rz, bz = (vfloat<A>(hi[2]) - r.oz) * r.rz;
  vfloat<A> const tn = simd::max(simd::max(simd::min(ax, bx), simd::min(ay, by)), simd::max(simd::min(az, bz), t0));
  vfloat<A> const tf = simd::min(simd::min(simd::max(ax, bx), simd::max(ay, by)), simd::min(simd::max(az, bz), t1));
  tnear = tn;
  return tn <= tf * vfloat<A>(1.f + 4.f * std::numeric_limits<float>::epsilon());
}

/// Box test with per-lane boxes (SPMD): node fields gathered per lane.
template <class A>
CELLRAY_FORCE_INLINE vmask<A> box_hit_varying(RayPacket<A> const& r, vfloat<A> const lo[3], vfloat<A> const hi[3],
                                vfloat<A> const& t0, vfloat<A> const& t1, vfloat<A>& tnear) {
  vfloat<A> const ax = (lo[0] - r.ox) * r.rx, bx = (hi[0] - r.ox) * r.rx;
  vfloat<A> const ay = (lo[1] - r.oy) * r.ry, by = (hi[1] - r.oy) * r.ry;
  vfloat<A> const az = (lo[2] - r.oz) * r.rz, bz = (hi[2] - r.oz) * r.rz;
  vfloat<A> const tn = simd::max(simd::max(simd::min(ax, bx), simd::min(ay, by)), simd::max(simd::min(az, bz), t0));
  vfloat<A> const tf = simd::min(simd::min(simd::max(ax, bx), simd::max(ay, by)), simd::min(simd::max(az, bz), t1));
  tnear = tn;
  return tn <= tf * vfloat<A>(1.f + 4.f * std::numeric_limits<float>::epsilon());
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
