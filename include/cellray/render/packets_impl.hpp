#pragma once
// Pixel-block packets of the renderers (ISA units only): camera rays, the
// part of a ray inside the scene's box and the clip region, framebuffer
// reads and writes, and the vector maths the shading shares.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "../traverse/traverse.hpp"
#include "render.hpp"
#include "render_common.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

/// x^e per lane (xsimd's vector pow; std::pow for the scalar arch).
template <class A> inline vfloat<A> pow_batch(vfloat<A> const& x, float e) {
  if constexpr (std::is_same_v<A, scalar>) return std::pow(x, e);
  else return xsimd::pow(x, vfloat<A>(e));
}

/// Unit vector per lane (a zero vector gives NaN, as glm::normalize).
template <class A> inline Vec3<A> normalized(Vec3<A> const& v) {
  return (vfloat<A>(1.f) / simd::sqrt(dot(v, v))) * v;
}

/// e^x per lane (xsimd's vector exp; std::exp for the scalar arch).
template <class B> inline vfloat<B> vexp(vfloat<B> const& x) {
  if constexpr (std::is_same_v<B, scalar>) return std::exp(x);
  else return xsimd::exp(x);
}

/// Pixel block per packet: 2x2 (4 lanes), 4x2 (8), 4x4 (16), 1x1 (scalar).
template <class A> inline constexpr int block_w = width<A> >= 8 ? 4 : width<A> == 4 ? 2 : 1;
template <class A> inline constexpr int block_h = width<A> / block_w<A>;

/// Pixel blocks traced together (traverse_packets: isosurface hits, DVR
/// first locates), across and down: eight, about as square in pixels as
/// blocks tile (8x4 pixels at 4 lanes, 8x8 at 8, 16x8 at 16). Eight
/// packets share more of each node, leaf and cell setup than four:
/// component8's isosurface at #23's view was 1.06-1.11x faster than with
/// 2x2 blocks on SSE4.2 and AVX-512, about the same on AVX2
/// (docs/performance.md).
template <class A> inline constexpr int group_x = block_w<A> == 2 * block_h<A> ? 2 : 4;
template <class A> inline constexpr int group_y = 8 / group_x<A>;

/// Lane l's pixel offset (l % block_w, l / block_w) in its block, as floats.
template <class A> struct BlockOffsets {
  alignas(64) float dx[width<A>];
  alignas(64) float dy[width<A>];
};
template <class A>
inline constexpr BlockOffsets<A> block_offsets = [] {
  BlockOffsets<A> b{};
  for (int l = 0; l < width<A>; ++l) b.dx[l] = float(l % block_w<A>), b.dy[l] = float(l / block_w<A>);
  return b;
}();

/// Primary rays of the pixel block at (bx, by), clipped to the tile: the
/// directions of Camera::direction (same expressions), normalized, all
/// lanes at once.
template <class A>
inline RayPacket<A> camera_packet(Camera const& cam, Tile const& tile, int bx, int by, int (&px)[width<A>],
                                  int (&py)[width<A>], uint32_t& valid) {
  constexpr int W = width<A>;
  constexpr uint32_t all = W == 32 ? ~0u : (1u << W) - 1u;
  bool const whole = bx + block_w<A> <= tile.x0 + tile.w && by + block_h<A> <= tile.y0 + tile.h;
  if (whole) {
    // Every block but those on a tile's right or bottom edge.
    valid = all;
    for (int l = 0; l < W; ++l) px[l] = bx + l % block_w<A>, py[l] = by + l / block_w<A>;
  } else {
    uint32_t bits = 0;  // in a register, not through `valid`
    for (int l = 0; l < W; ++l) {
      int const x = bx + l % block_w<A>, y = by + l / block_w<A>;
      bool const in = x < tile.x0 + tile.w && y < tile.y0 + tile.h;
      px[l] = in ? x : bx;
      py[l] = in ? y : by;
      bits |= uint32_t(in) << l;
    }
    valid = bits;
  }
  // Pixel coordinates as floats from constant lane offsets (exact: small
  // integers), not from per-lane conversions stored and reloaded as a vector.
  vmask<A> const in = simd::mask_from_bits<A>(valid);
  vfloat<A> const fbx(static_cast<float>(bx)), fby(static_cast<float>(by));
  vfloat<A> const fx = simd::select(in, fbx + simd::load<A>(block_offsets<A>.dx), fbx);
  vfloat<A> const fy = simd::select(in, fby + simd::load<A>(block_offsets<A>.dy), fby);
  float const aspect = float(cam.width) / float(cam.height);
  vfloat<A> const one(1.f), two(2.f), half(0.5f);
  vfloat<A> const u = ((fx + half) / vfloat<A>(float(cam.width)) * two - one) * vfloat<A>(cam.tan_half_fov) *
                      vfloat<A>(aspect);
  vfloat<A> const v = (one - (fy + half) / vfloat<A>(float(cam.height)) * two) * vfloat<A>(cam.tan_half_fov);
  vfloat<A> dx = vfloat<A>(cam.forward.x) + u * vfloat<A>(cam.right.x) + v * vfloat<A>(cam.up.x);
  vfloat<A> dy = vfloat<A>(cam.forward.y) + u * vfloat<A>(cam.right.y) + v * vfloat<A>(cam.up.y);
  vfloat<A> dz = vfloat<A>(cam.forward.z) + u * vfloat<A>(cam.right.z) + v * vfloat<A>(cam.up.z);
  // Unit directions: t is world distance, as DVR steps and opacity
  // correction (per unit distance) assume.
  vfloat<A> const inv_len = one / simd::sqrt(dx * dx + dy * dy + dz * dz);
  dx = dx * inv_len, dy = dy * inv_len, dz = dz * inv_len;
  // load_rays' safe reciprocal: |d| below 1e-30 counts as +-1e-30.
  auto safe_rcp = [&one](vfloat<A> const& d) {
    vfloat<A> const r = one / d, big(1e30f);
    return simd::select(simd::abs(d) < vfloat<A>(1e-30f), simd::select(r < vfloat<A>(0.f), -big, big), r);
  };
  RayPacket<A> p;
  p.ox = vfloat<A>(cam.eye.x), p.oy = vfloat<A>(cam.eye.y), p.oz = vfloat<A>(cam.eye.z);
  p.dx = dx, p.dy = dy, p.dz = dz;
  p.rx = safe_rcp(dx), p.ry = safe_rcp(dy), p.rz = safe_rcp(dz);
  p.tmin = vfloat<A>(0.f), p.tmax = vfloat<A>(std::numeric_limits<float>::infinity());
  return p;
}

/// The part [t0, t1] of each lane's ray inside the clip region (clip.hpp),
/// narrowed from the given [t0, t1]; `entry`: the plane a ray enters through
/// at t0 (-1: t0 was not moved). Empty where t0 > t1.
template <class A> struct ClipSpan {
  vfloat<A> t0, t1;
  vint<A> entry;
};
template <class A>
inline ClipSpan<A> clip_span(PreparedClip const& c, RayPacket<A> const& r, vfloat<A> t0, vfloat<A> t1) {
  vfloat<A> const zero(0.f), inf(std::numeric_limits<float>::infinity());
  vint<A> entry(-1);
  for (int i = 0; i < c.count; ++i) {
    vfloat<A> const nx(c.nx[i]), ny(c.ny[i]), nz(c.nz[i]);
    vfloat<A> const s = nx * r.dx + ny * r.dy + nz * r.dz;
    vfloat<A> const q = nx * r.ox + ny * r.oy + nz * r.oz - vfloat<A>(c.d[i]);
    vfloat<A> const t = (zero - q) / simd::select(s == zero, vfloat<A>(1.f), s);  // parallel lanes: below
    vmask<A> const enter = s < zero && t > t0, leave = s > zero && t < t1;
    t0 = simd::select(enter, t, t0);
    entry = simd::select(simd::to_int_mask(enter), vint<A>(i), entry);
    t1 = simd::select(leave, t, t1);
    t0 = simd::select(s == zero && q > zero, inf, t0);  // parallel to the plane, on the side cut away
  }
  return {t0, t1, entry};
}

/// Where a ray from a point inside the clip region leaves it (at most t1).
inline float clip_exit(PreparedClip const& c, glm::vec3 const& o, glm::vec3 const& d, float t1) {
  for (int i = 0; i < c.count; ++i) {
    float const s = c.nx[i] * d.x + c.ny[i] * d.y + c.nz[i] * d.z;
    float const q = c.nx[i] * o.x + c.ny[i] * o.y + c.nz[i] * o.z - c.d[i];
    if (s > 0.f) t1 = std::min(t1, -q / s);
  }
  return t1;
}

/// Where each ray leaves the scene's bounding box.
template <class A> inline vfloat<A> scene_exit(RayPacket<A> const& r, PreparedScene const& s) {
  vfloat<A> const ax = (vfloat<A>(s.lo.x) - r.ox) * r.rx, bx = (vfloat<A>(s.hi.x) - r.ox) * r.rx;
  vfloat<A> const ay = (vfloat<A>(s.lo.y) - r.oy) * r.ry, by = (vfloat<A>(s.hi.y) - r.oy) * r.ry;
  vfloat<A> const az = (vfloat<A>(s.lo.z) - r.oz) * r.rz, bz = (vfloat<A>(s.hi.z) - r.oz) * r.rz;
  return simd::min(simd::min(simd::max(ax, bx), simd::max(ay, by)), simd::max(az, bz));
}

/// Row length in bytes of a frame buffer's colour (0 in the struct: tight).
inline size_t rgba_row(FrameBuffer const& f) {
  return f.row_bytes ? f.row_bytes : size_t(f.width) * (f.format == FrameBuffer::Format::rgba8 ? 4 : 16);
}

/// Writes premultiplied RGBA (x, y) in the buffer's format.
inline void put_pixel(FrameBuffer const& f, int x, int y, float r, float g, float b, float a) {
  unsigned char* row = static_cast<unsigned char*>(f.rgba) + size_t(y) * rgba_row(f);
  float const c[4] = {r, g, b, a};
  if (f.format == FrameBuffer::Format::rgba32f) {
    float* q = reinterpret_cast<float*>(row + size_t(x) * 16);
    for (int k = 0; k < 4; ++k) q[k] = c[k];
  } else {
    unsigned char* q = row + size_t(x) * 4;
    for (int k = 0; k < 4; ++k) q[k] = uint8_t((c[k] > 0.f ? std::min(c[k], 1.f) : 0.f) * 255.f + 0.5f);  // NaN: 0
  }
}

/// The host's depth at each lane's pixel (+inf without a depth buffer).
template <class A>
inline vfloat<A> host_depth(FrameBuffer const& f, int const (&px)[width<A>], int const (&py)[width<A>], uint32_t valid) {
  constexpr int W = width<A>;
  alignas(64) float d[W];
  size_t const row = f.depth_in_row ? f.depth_in_row : size_t(f.width);
  for (int l = 0; l < W; ++l)
    d[l] = f.depth_in && ((valid >> l) & 1u) ? f.depth_in[size_t(py[l]) * row + size_t(px[l])]
                                            : std::numeric_limits<float>::infinity();
  return simd::load<A>(d);
}

inline void put_depth(FrameBuffer const& f, int x, int y, float d) {
  f.depth_out[size_t(y) * (f.depth_out_row ? f.depth_out_row : size_t(f.width)) + size_t(x)] = d;
}

}  // namespace impl
}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
