#pragma once
// Bodies of RenderTileEntry (ISA units only): pixel-block packets, iso
// shading with shadows, ambient occlusion and transparency, and DVR.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "../traverse/cell_ops.hpp"
#include "../traverse/first_hit.hpp"
#include "../traverse/march.hpp"
#include "../traverse/queries_impl.hpp"
#include "../traverse/sample.hpp"
#include "../traverse/segments.hpp"
#include "occlusion_impl.hpp"
#include "render.hpp"
#include "render_common.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

/// Pixel block per packet: 2x2 (4 lanes), 4x2 (8), 4x4 (16), 1x1 (scalar).
template <class A> inline constexpr int block_w = width<A> >= 8 ? 4 : width<A> == 4 ? 2 : 1;
template <class A> inline constexpr int block_h = width<A> / block_w<A>;

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

/// Per-lane nearest iso hit over every part of the scene.
template <class A> struct SceneHit {
  vfloat<A> t;
  vint<A> iso, item, part;  ///< part: index into PreparedScene::parts
  Vec3<A> grad{};           ///< when asked for: the analytic gradient at the hit (FirstHitQuery::grad)
};

template <class A, int N>
inline void hit_part(PreparedPart const& part, CellMesh<N> const& mesh, RayPacket<A> const& r, vmask<A> active,
                     IsoSet const& isos, CellIsoOptions const& roots, Traversal how, int threshold, int part_index,
                     SceneHit<A>& best, bool gradient) {
  FirstHitQuery<A, N> q{part.tree, mesh, r, isos, roots, {best.t, vint<A>(-1), vint<A>(-1)}};
  q.want_gradient = gradient;
  switch (how) {
    case Traversal::packet: traverse_packet<A>(part.tree, r, active, q); break;
    case Traversal::hybrid: traverse_packet<A>(part.tree, r, active, q, 0, threshold); break;
    case Traversal::spmd: traverse_spmd<A>(part.tree, r, active, q); break;
  }
  vmask<A> const better = q.hit.t < best.t;
  auto const bi = simd::to_int_mask(better);
  best.t = simd::select(better, q.hit.t, best.t);
  best.iso = simd::select(bi, q.hit.iso, best.iso);
  best.item = simd::select(bi, q.hit.item, best.item);
  best.part = simd::select(bi, vint<A>(part_index), best.part);
  if (gradient) best.grad = select<A>(better, q.grad, best.grad);
}

/// `gradient`: hits also bring their analytic gradient (SceneHit::grad).
template <class A>
inline SceneHit<A> nearest_hit(PreparedScene const& s, RayPacket<A> const& r, vmask<A> active, IsoSet const& isos,
                               CellIsoOptions const& roots, Traversal how, int threshold, bool gradient = false) {
  // Members one by one: aggregate initialisation zeroed all 7 vectors with
  // `rep stos` first (g++ 12), a slow start-up on every packet.
  SceneHit<A> best;
  best.t = r.tmax;
  best.iso = best.item = best.part = vint<A>(-1);
  for (size_t p = 0; p < s.parts.size(); ++p) {
    PreparedPart const& part = s.parts[p];
    if (part.tets) hit_part<A>(part, *part.tets, r, active, isos, roots, how, threshold, int(p), best, gradient);
    else hit_part<A>(part, *part.hexes, r, active, isos, roots, how, threshold, int(p), best, gradient);
  }
  return best;
}

/// Unit shading normal at a hit point `p` (two-sided: faces against `dir`).
inline glm::vec3 normal_at(PreparedPart const& part, uint64_t slot, glm::vec3 p, glm::vec3 dir, GradientMethod m) {
  uint64_t const cell = part.tree.item(slot);
  Ray const at_hit{p, 0.f, dir, 0.f};  // t = 0 is the hit point itself
  return part.tets ? hit_normal(*part.tets, cell, at_hit, 0.f, m) : hit_normal(*part.hexes, cell, at_hit, 0.f, m);
}

/// Where `p` lies in `cell`: its vertex ids in the kernels' corner order and
/// the cell's shape functions there (tets: barycentric; hexes: trilinear at
/// the located coordinates), to interpolate any per-vertex quantity at an
/// isosurface hit (smooth normals, colour by another array). NaN weights
/// where a hex inversion fails.
template <int N> struct CellWeights {
  uint64_t v[N];
  float w[N];
};
template <int N> inline CellWeights<N> cell_weights(CellMesh<N> const& mesh, uint64_t cell, glm::vec3 const& p) {
  ScalarCorners<N> k;
  read_corner_values(mesh, cell, k);
  order_corners(mesh.vertex_count(), k);
  CellCorners<scalar, N> const c = broadcast<scalar, N>(mesh, k);
  Located<scalar> const at = CellOps<scalar, N>::locate(PointBatch<scalar>{p.x, p.y, p.z}, c);
  CellWeights<N> out;
  for (int i = 0; i < N; ++i) out.v[i] = k.v[i];
  if constexpr (N == 4) {
    out.w[1] = at.param.x, out.w[2] = at.param.y, out.w[3] = at.param.z;
    out.w[0] = 1.f - out.w[1] - out.w[2] - out.w[3];
  } else {
    float const u = std::clamp(at.param.x, 0.f, 1.f), v = std::clamp(at.param.y, 0.f, 1.f),
                w = std::clamp(at.param.z, 0.f, 1.f);
    if (!at.converged || !std::isfinite(at.param.x + at.param.y + at.param.z))
      for (float& x : out.w) x = std::numeric_limits<float>::quiet_NaN();
    else
      for (int i = 0; i < 8; ++i) {  // VTK order: bit 0 of (0 1 3 2 4 5 7 6)[i] is u, bit 1 v, bit 2 w
        static constexpr int corner[8] = {0, 1, 3, 2, 4, 5, 7, 6};
        int const b = corner[i];
        out.w[i] = ((b & 1) ? u : 1.f - u) * ((b & 2) ? v : 1.f - v) * ((b & 4) ? w : 1.f - w);
      }
  }
  return out;
}

/// At an isosurface hit `p` in the hit cell `slot` of a part, from one point
/// location: the smooth shading normal facing against `dir` (if `normal`;
/// GradientMethod::smooth: the vertex gradients interpolated, or the cell's
/// analytic normal where that is NaN or zero) and the colour array's value
/// (if `value`; NaN where a corner is NaN).
inline void hit_attributes(PreparedPart const& part, uint64_t slot, glm::vec3 const& p, glm::vec3 const& dir,
                           glm::vec3* normal, float* value) {
  uint64_t const cell = part.tree.item(slot);
  glm::vec3 g(0.f);
  auto interpolate = [&](auto const& mesh) {
    auto const cw = cell_weights(mesh, cell, p);
    float v = 0.f;
    for (int i = 0; i < std::decay_t<decltype(mesh)>::corners; ++i) {
      if (normal)
        for (int a = 0; a < 3; ++a) g[a] += cw.w[i] * part.gradients[3 * cw.v[i] + uint64_t(a)];
      if (value) v += cw.w[i] * part.color_values[cw.v[i]];
    }
    if (value) *value = v;
  };
  if (part.tets) interpolate(*part.tets);
  else interpolate(*part.hexes);
  if (!normal) return;
  float const gg = glm::dot(g, g);
  if (!(gg > 0.f) || !std::isfinite(gg)) {
    *normal = normal_at(part, slot, p, dir, GradientMethod::analytic);
    return;
  }
  Vec3<scalar> const d{dir.x, dir.y, dir.z};
  Vec3<scalar> const n = face_forward<scalar>(shading_normal<scalar>(Vec3<scalar>{g.x, g.y, g.z}, d), d);
  *normal = {n.x, n.y, n.z};
}

/// x^e per lane (xsimd's vector pow; std::pow for the scalar arch).
template <class A> inline vfloat<A> pow_batch(vfloat<A> const& x, float e) {
  if constexpr (std::is_same_v<A, scalar>) return std::pow(x, e);
  else return xsimd::pow(x, vfloat<A>(e));
}

/// Unit vector per lane (a zero vector gives NaN, as glm::normalize).
template <class A> inline Vec3<A> normalized(Vec3<A> const& v) {
  return (vfloat<A>(1.f) / simd::sqrt(dot(v, v))) * v;
}

/// Lane `l` of a Vec3 stored as three arrays.
template <size_t W> inline glm::vec3 lane_vec(std::array<float, W> const (&v)[3], int l) {
  return {v[0][size_t(l)], v[1][size_t(l)], v[2][size_t(l)]};
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

/// The colour of value v in a ColorTable (linear between entries).
inline glm::vec3 table_color(ColorTable const& c, float v) {
  float const x = std::min(std::max((v - c.lo) * c.scale, 0.f), float(ColorTable::entries - 1));
  int const i = std::min(int(x), ColorTable::entries - 2);
  float const f = x - float(i);
  float const* a = c.rgb[i];
  float const* b = c.rgb[i + 1];
  return {a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2])};
}

/// The field at o + t d of each lane in `lanes`, from the first part that
/// holds the point (NaN outside the mesh and in NaN cells).
template <class A>
inline vfloat<A> values_at(PreparedScene const& s, RayPacket<A> const& r, vfloat<A> const& t, vmask<A> const& lanes,
                           Traversal how, int threshold) {
  constexpr int W = width<A>;
  ValueWindows const everything;
  alignas(64) float out[W];
  for (int l = 0; l < W; ++l) out[l] = std::numeric_limits<float>::quiet_NaN();
  for (PreparedPart const& part : s.parts) {
    auto run = [&](auto const& mesh) {
      constexpr int N = std::decay_t<decltype(mesh)>::corners;
      SampleQuery<A, N> q(part.tree, mesh, r, everything, t, 0.f, 1, lanes);
      sample_group(q, lanes, how, threshold);
      for (int l = 0; l < W; ++l)
        if (!(out[l] == out[l])) out[l] = q.values[0][l];
    };
    if (part.tets) run(*part.tets);
    else run(*part.hexes);
  }
  return simd::load<A>(out);
}

/// Deterministic per-pixel hash in [0, 1): AO directions must not flicker
/// between frames or differ between ISAs.
inline float hash01(uint32_t a, uint32_t b) {
  uint32_t h = a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u;
  h ^= h >> 15;
  h *= 0x2C1B3C6Du;
  h ^= h >> 12;
  h *= 0x297A2D39u;
  h ^= h >> 15;
  return float(h >> 8) * (1.f / 16777216.f);
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

template <class A>
void render_iso_tile(PreparedScene const& s, Camera const& cam, IsoParams const& p, RenderOptions const& o,
                     Tile const& tile, FrameBuffer const& out) {
  constexpr int W = width<A>;
  int const threshold = o.hybrid_threshold > 0 ? o.hybrid_threshold : std::max(1, W / 4);
  IsoSet isos;
  isos.count = int(p.surfaces.size());
  for (int k = 0; k < isos.count; ++k) isos.values[k] = p.surfaces[size_t(k)].value;
  float const eps = 1e-5f * s.diagonal;
  float const ao_radius = p.ao_radius > 0.f ? p.ao_radius : 0.05f * s.diagonal;
  bool const headlight = !(glm::length(p.light_dir) > 0.f);
  glm::vec3 const light = headlight ? glm::vec3(0.f) : glm::normalize(p.light_dir);
  // Analytic normals come with the hits: the iso query computes the
  // gradient once per hit cell from the corners it already loaded (tets:
  // constant per cell; hexes: at the hit's coordinates). Central differences
  // locate each hit again, per lane (normal_at).
  bool const query_gradient = p.normals == GradientMethod::analytic;
  bool const smooth = p.normals == GradientMethod::smooth;
  // Any-hit shadow rays need one opacity for every surface (see the shadow block).
  bool const secondary = p.shadows || p.ao_samples > 0;
  // AO rays march from their hit cells where the scene allows (one tet part
  // with face neighbours); elsewhere `march` is `grouped`.
  bool const march_ao = o.secondary_query == SecondaryQuery::march && s.parts.size() == 1 && s.parts[0].neighbours;
  bool one_opacity = true;
  for (IsoSurface const& surf : p.surfaces) one_opacity = one_opacity && surf.opacity == p.surfaces[0].opacity;
  vfloat<A> const zero(0.f), one(1.f);
  Vec3<A> const eye{vfloat<A>(cam.eye.x), vfloat<A>(cam.eye.y), vfloat<A>(cam.eye.z)};
  bool const clipping = s.clip.count > 0;

  for (int by = tile.y0; by < tile.y0 + tile.h; by += block_h<A>)
    for (int bx = tile.x0; bx < tile.x0 + tile.w; bx += block_w<A>) {
      int px[W], py[W];
      uint32_t valid;
      RayPacket<A> r = camera_packet<A>(cam, tile, bx, by, px, py, valid);
      Vec3<A> const dir = ray_batch(r).dir();
      vfloat<A> color_r = zero, color_g = zero, color_b = zero, alpha = zero;
      r.tmin = zero;
      r.tmax = host_depth<A>(out, px, py, valid);  // the host's opaque geometry hides what lies behind it
      vfloat<A> depth(std::numeric_limits<float>::infinity());
      vfloat<A> const depth_at(out.depth_opacity);
      uint32_t live = valid;
      if (clipping) {
        ClipSpan<A> const cs = clip_span<A>(s.clip, r, zero, r.tmax);
        r.tmin = cs.t0, r.tmax = cs.t1;
        live &= simd::movemask(cs.t0 <= cs.t1);
        uint32_t const entering = live & simd::movemask(simd::to_float_mask(cs.entry >= vint<A>(0)));
        if (s.clip.caps && entering) {
          // A cap: the cut face where the ray enters the region inside the
          // mesh, opaque, in front of everything the region holds.
          auto const v = simd::to_array<A>(values_at<A>(s, r, cs.t0, simd::mask_from_bits<A>(entering), o.traversal,
                                                        threshold));
          auto const plane = simd::to_array<A>(cs.entry);
          std::array<float, W> const dir_x = simd::to_array<A>(dir.x), dir_y = simd::to_array<A>(dir.y),
                                     dir_z = simd::to_array<A>(dir.z);
          alignas(64) float cr_[W] = {}, cg_[W] = {}, cb_[W] = {}, ca_[W] = {};
          uint32_t capped = 0;
          for (uint32_t bits = entering; bits; bits &= bits - 1) {
            int const l = __builtin_ctz(bits);
            if (!std::isfinite(v[size_t(l)])) continue;
            int const k = plane[size_t(l)];
            glm::vec3 const n(s.clip.nx[k], s.clip.ny[k], s.clip.nz[k]);  // faces the eye: the ray enters against it
            glm::vec3 const d = glm::normalize(glm::vec3(dir_x[size_t(l)], dir_y[size_t(l)], dir_z[size_t(l)]));
            glm::vec3 const to_l = headlight ? -d : light;
            float const ndl = std::max(0.f, glm::dot(n, to_l));
            float const ndh = std::max(0.f, glm::dot(n, glm::normalize(to_l - d)));
            float const spec = ndl > 0.f ? p.specular * std::pow(ndh, p.shininess) : 0.f;
            glm::vec3 const c = glm::min(table_color(s.clip.cap_colors, v[size_t(l)]) * (p.ambient + p.diffuse * ndl) + spec, 1.f);
            cr_[l] = c.r, cg_[l] = c.g, cb_[l] = c.b, ca_[l] = 1.f;
            capped |= 1u << l;
          }
          color_r = simd::load<A>(cr_), color_g = simd::load<A>(cg_), color_b = simd::load<A>(cb_);
          alpha = simd::load<A>(ca_);
          depth = simd::select(simd::mask_from_bits<A>(capped), cs.t0, depth);
          live &= ~capped;
        }
      }
      // Front-to-back layers: continue behind semi-transparent surfaces.
      for (int layer = 0; layer < 16 && live; ++layer) {
        SceneHit<A> const h = nearest_hit<A>(s, r, simd::mask_from_bits<A>(live), isos, p.roots, o.traversal, threshold,
                                             query_gradient);
        vmask<A> const hit = simd::mask_from_bits<A>(live) && simd::to_float_mask(h.item >= vint<A>(0));
        uint32_t hit_bits = simd::movemask(hit);
        if (!hit_bits) break;
        // Hit points, normals and the light, all lanes at once (lanes
        // without a hit compute garbage nobody reads); the shadow and AO
        // rays below read them per lane.
        vfloat<A> const t = simd::select(hit, h.t, zero);
        Vec3<A> const hit_pos = eye + t * dir;
        Vec3<A> normal{};
        if (query_gradient) normal = face_forward<A>(shading_normal<A>(h.grad, dir), dir);
        Vec3<A> const to_light = headlight ? vfloat<A>(-1.f) * normalized<A>(dir)
                                           : Vec3<A>{vfloat<A>(light.x), vfloat<A>(light.y), vfloat<A>(light.z)};
        std::array<float, W> const pos_a[3] = {simd::to_array<A>(hit_pos.x), simd::to_array<A>(hit_pos.y),
                                               simd::to_array<A>(hit_pos.z)};
        std::array<float, W> const ldir_a[3] = {simd::to_array<A>(to_light.x), simd::to_array<A>(to_light.y),
                                                simd::to_array<A>(to_light.z)};
        std::array<float, W> nrm_a[3] = {simd::to_array<A>(normal.x), simd::to_array<A>(normal.y),
                                         simd::to_array<A>(normal.z)};
        auto const iso = simd::to_array<A>(h.iso), item = simd::to_array<A>(h.item), part = simd::to_array<A>(h.part);
        glm::vec3 pos[W], nrm[W], ldir[W];
        alignas(64) float base_r[W] = {}, base_g[W] = {}, base_b[W] = {}, opacity[W] = {};
        std::array<float, W> dir_a[3];
        if (!query_gradient) dir_a[0] = simd::to_array<A>(dir.x), dir_a[1] = simd::to_array<A>(dir.y),
                             dir_a[2] = simd::to_array<A>(dir.z);
        for (uint32_t bits = hit_bits; bits; bits &= bits - 1) {
          int const l = __builtin_ctz(bits);
          PreparedPart const& hit_part = s.parts[size_t(part[l])];
          glm::vec3 n(0.f);
          float colour_value = std::numeric_limits<float>::quiet_NaN();
          if (smooth || s.color_by)  // one location of the hit for both
            hit_attributes(hit_part, uint64_t(item[l]), lane_vec<W>(pos_a, l),
                           smooth ? lane_vec<W>(dir_a, l) : glm::vec3(0.f),  // dir_a is filled when normals are not analytic
                           smooth ? &n : nullptr, s.color_by ? &colour_value : nullptr);
          if (!query_gradient) {
            if (!smooth) n = normal_at(hit_part, uint64_t(item[l]), lane_vec<W>(pos_a, l), lane_vec<W>(dir_a, l), p.normals);
            nrm_a[0][size_t(l)] = n.x, nrm_a[1][size_t(l)] = n.y, nrm_a[2][size_t(l)] = n.z;
          }
          // Per-lane copies only for the shadow and AO rays below.
          if (secondary) pos[l] = lane_vec<W>(pos_a, l), ldir[l] = lane_vec<W>(ldir_a, l), nrm[l] = lane_vec<W>(nrm_a, l);
          IsoSurface const& surf = p.surfaces[size_t(iso[l])];
          glm::vec3 const base = std::isfinite(colour_value) ? table_color(s.colors, colour_value) : surf.color;
          base_r[l] = base.r, base_g[l] = base.g, base_b[l] = base.b;
          opacity[l] = surf.opacity;
        }
        if (!query_gradient) normal = {simd::load<A>(nrm_a[0].data()), simd::load<A>(nrm_a[1].data()),
                                       simd::load<A>(nrm_a[2].data())};
        float visibility[W], occlusion[W];
        for (int l = 0; l < W; ++l) visibility[l] = 1.f, occlusion[l] = 0.f;
        // Shadow and AO rays (RenderOptions::secondary_query). Any-hit
        // queries give the nearest hit's answer whenever only its existence
        // matters: AO always, shadows when every surface has one opacity.
        bool const any_hit = o.secondary_query != SecondaryQuery::nearest;
        if (hit_bits && p.shadows) {
          Ray sr[W];
          for (int l = 0; l < W; ++l) {
            bool const h1 = (hit_bits >> l) & 1u;
            glm::vec3 const o = pos[l] + eps * nrm[l];
            float const far = clipping && h1 ? clip_exit(s.clip, o, ldir[l], std::numeric_limits<float>::infinity())
                                             : std::numeric_limits<float>::infinity();
            sr[l] = Ray{h1 ? o : cam.eye, h1 ? eps : 0.f, h1 ? ldir[l] : glm::vec3(0, 0, 1),
                        h1 ? std::max(eps, far) : -1.f};
          }
          RayPacket<A> const srp = load_rays<A>(sr, W);
          if (any_hit && one_opacity) {
            vmask<A> const lanes = simd::mask_from_bits<A>(hit_bits);
            // Every any-hit query (grouped too) traces a pixel block's shadow
            // rays as one packet: they leave nearby points in one direction,
            // so the packet clip's lanes are mostly busy. (Through
            // occluded_packets' (cell, ray) pairs instead: 20% fewer
            // instructions, callgrind AVX2, but a 2.5-3% slower frame,
            // AVX-512 and AVX2 on an AMD EPYC, component8 and a 2M-tet mesh.)
            uint32_t const occ =
                simd::movemask(scene_occluded<A>(s, srp, lanes, isos, p.roots, o.secondary_traversal, threshold));
            for (int l = 0; l < W; ++l)
              if ((hit_bits & occ) >> l & 1u) visibility[l] = 1.f - p.surfaces[0].opacity;
          } else {
            SceneHit<A> const sh = nearest_hit<A>(s, srp, simd::mask_from_bits<A>(hit_bits), isos, p.roots,
                                                  o.secondary_traversal, threshold);
            auto const sitem = simd::to_array<A>(sh.item), siso = simd::to_array<A>(sh.iso);
            for (int l = 0; l < W; ++l)
              if (((hit_bits >> l) & 1u) && sitem[l] >= 0) visibility[l] = 1.f - p.surfaces[size_t(siso[l])].opacity;
          }
        }
        // AO ray k of lane l (a hit lane): cosine-weighted about the normal,
        // directions from the pixel's hash (the same on every ISA).
        auto const ao_ray = [&](int l, int k) {
          uint32_t const pix = uint32_t(py[l]) * uint32_t(cam.width) + uint32_t(px[l]);
          float const u1 = hash01(pix, uint32_t(2 * k + 64 * layer)), u2 = hash01(pix, uint32_t(2 * k + 1 + 64 * layer));
          float const rr = std::sqrt(u1), phi = 6.2831853f * u2;
          glm::vec3 const n = nrm[l];
          glm::vec3 const a = std::fabs(n.x) > 0.5f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
          glm::vec3 const tx = glm::normalize(glm::cross(a, n)), ty = glm::cross(n, tx);
          glm::vec3 const d = rr * std::cos(phi) * tx + rr * std::sin(phi) * ty + std::sqrt(std::max(0.f, 1.f - u1)) * n;
          glm::vec3 const o = pos[l] + eps * nrm[l];
          return Ray{o, eps, d, clipping ? std::max(eps, clip_exit(s.clip, o, d, ao_radius)) : ao_radius};
        };
        bool const regroup = o.secondary_query == SecondaryQuery::sorted || o.secondary_query == SecondaryQuery::grouped ||
                             (o.secondary_query == SecondaryQuery::march && !march_ao);
        if (hit_bits && p.ao_samples > 0 && march_ao) {
          // Each hit lane's AO rays march from its hit cell; what a march
          // cannot finish (it left the mesh, or its origin lies just outside
          // the hit cell) goes on from where it got to through the grouped
          // query, a chunk of samples at a time.
          constexpr int chunk = std::min(4, max_sorted_rays / W);
          PreparedPart const& part = s.parts[0];
          vmask<A> const lanes = simd::mask_from_bits<A>(hit_bits);
          vint<A> const hit_cells = slot_cells<A>(part.tree, h.item, lanes);  // h.item: item-list slots
          Ray rest[W * chunk];
          uint8_t owner[W * chunk];
          uint64_t occ_rest[(W * chunk + 63) / 64];
          for (int k0 = 0; k0 < p.ao_samples; k0 += chunk) {
            int n = 0;
            for (int k = k0; k < std::min(p.ao_samples, k0 + chunk); ++k) {
              Ray ar[W];
              for (int l = 0; l < W; ++l)
                ar[l] = (hit_bits >> l) & 1u ? ao_ray(l, k) : Ray{cam.eye, 0.f, glm::vec3(0, 0, 1), -1.f};
              RayPacket<A> const arp = load_rays<A>(ar, W);
              vmask<A> undecided;
              vfloat<A> t_done;
              uint32_t const occ = simd::movemask(march_occluded<A>(part.tree, *part.tets, *part.neighbours, arp, lanes,
                                                                    hit_cells, isos, p.roots, undecided, t_done)) &
                                   hit_bits;
              for (int l = 0; l < W; ++l)
                if (occ >> l & 1u) occlusion[l] += 1.f / float(p.ao_samples);
              auto const from = simd::to_array<A>(t_done);
              for (uint32_t b = simd::movemask(undecided); b; b &= b - 1) {
                int const l = __builtin_ctz(b);
                rest[n] = ar[l], rest[n].tmin = from[size_t(l)], owner[n] = uint8_t(l), ++n;
              }
            }
            if (n == 0) continue;
            scene_occluded_sorted<A>(s, rest, n, isos, p.roots, o.secondary_traversal, threshold, true, occ_rest);
            for (int i = 0; i < n; ++i)
              if (occ_rest[i / 64] >> (i % 64) & 1u) occlusion[owner[i]] += 1.f / float(p.ao_samples);
          }
        }
        if (hit_bits && p.ao_samples > 0 && regroup) {
          // A chunk of samples of every hit lane, regrouped by direction.
          constexpr int chunk = std::min(4, max_sorted_rays / W);
          Ray ar[W * chunk];
          uint8_t owner[W * chunk];
          uint64_t occ[(W * chunk + 63) / 64];
          for (int k0 = 0; k0 < p.ao_samples; k0 += chunk) {
            int n = 0;
            for (int k = k0; k < std::min(p.ao_samples, k0 + chunk); ++k)
              for (uint32_t b = hit_bits; b; b &= b - 1) {
                int const l = __builtin_ctz(b);
                ar[n] = ao_ray(l, k), owner[n] = uint8_t(l), ++n;
              }
            scene_occluded_sorted<A>(s, ar, n, isos, p.roots, o.secondary_traversal, threshold,
                                     o.secondary_query == SecondaryQuery::grouped, occ);
            for (int i = 0; i < n; ++i)
              if (occ[i / 64] >> (i % 64) & 1u) occlusion[owner[i]] += 1.f / float(p.ao_samples);
          }
        }
        for (int k = 0; hit_bits && k < p.ao_samples && !regroup && !march_ao; ++k) {
          Ray ar[W];
          for (int l = 0; l < W; ++l)
            ar[l] = (hit_bits >> l) & 1u ? ao_ray(l, k) : Ray{cam.eye, 0.f, glm::vec3(0, 0, 1), -1.f};
          RayPacket<A> const arp = load_rays<A>(ar, W);
          uint32_t occ = 0;
          if (any_hit) {
            occ = simd::movemask(scene_occluded<A>(s, arp, simd::mask_from_bits<A>(hit_bits), isos, p.roots,
                                                   o.secondary_traversal, threshold));
          } else {
            SceneHit<A> const ah = nearest_hit<A>(s, arp, simd::mask_from_bits<A>(hit_bits), isos, p.roots,
                                                  o.secondary_traversal, threshold);
            occ = simd::movemask(simd::to_float_mask(ah.item >= vint<A>(0)));
          }
          for (int l = 0; l < W; ++l)
            if ((hit_bits & occ) >> l & 1u) occlusion[l] += 1.f / float(p.ao_samples);
        }
        // Lambert + Blinn-Phong, W lanes at once.
        Vec3<A> const to_eye = vfloat<A>(-1.f) * normalized<A>(dir);
        vfloat<A> const ndl = simd::max(zero, dot(normal, to_light));
        vfloat<A> const ndh = simd::max(zero, dot(normal, normalized<A>(to_light + to_eye)));
        vfloat<A> const vis = simd::load<A>(visibility);
        vfloat<A> const spec =
            simd::select(ndl > zero, vfloat<A>(p.specular) * pow_batch<A>(ndh, p.shininess) * vis, zero);
        vfloat<A> const light_in = vfloat<A>(p.ambient) * (one - simd::load<A>(occlusion)) + vfloat<A>(p.diffuse) * ndl * vis;
        // Ambient + diffuse + specular can sum past 1 (defaults: 0.2 + 0.7 +
        // 0.25); the image holds [0, 1] (image.hpp), so clamp here, before
        // compositing, not only when writing 8 bits.
        vfloat<A> const a = simd::select(hit, simd::load<A>(opacity) * (one - alpha), zero);
        color_r = color_r + a * simd::min(simd::load<A>(base_r) * light_in + spec, one);
        color_g = color_g + a * simd::min(simd::load<A>(base_g) * light_in + spec, one);
        color_b = color_b + a * simd::min(simd::load<A>(base_b) * light_in + spec, one);
        depth = simd::select(hit && alpha < depth_at && alpha + a >= depth_at, t, depth);
        alpha = alpha + a;
        vmask<A> const next = hit && alpha < vfloat<A>(0.99f);
        r.tmin = simd::select(next, t + simd::max(vfloat<A>(eps), vfloat<A>(1e-5f) * t), r.tmin);
        live = simd::movemask(next);
      }
      vfloat<A> const bg_a(p.background.a), rest = (one - alpha) * bg_a;
      auto const cr = simd::to_array<A>(color_r + rest * vfloat<A>(p.background.r));
      auto const cg = simd::to_array<A>(color_g + rest * vfloat<A>(p.background.g));
      auto const cb = simd::to_array<A>(color_b + rest * vfloat<A>(p.background.b));
      auto const ca = simd::to_array<A>(alpha + rest);
      auto const cd = simd::to_array<A>(depth);
      for (uint32_t bits = valid; bits; bits &= bits - 1) {
        int const l = __builtin_ctz(bits);
        put_pixel(out, px[l], py[l], cr[size_t(l)], cg[size_t(l)], cb[size_t(l)], ca[size_t(l)]);
        if (out.depth_out) put_depth(out, px[l], py[l], cd[size_t(l)]);
      }
    }
}

/// Transfer function as a lookup table over [lo, hi] with the opacity
/// already corrected for the sample spacing: a' = 1 - (1 - a)^(step / unit).
template <class A> struct TfTable {
  float const* r;
  float const* g;
  float const* b;
  float const* a;
  int size;
  float lo, scale;  ///< index = (v - lo) * scale

  /// Colour and corrected opacity per lane (NaN values: transparent).
  void lookup(vfloat<A> const& v, vfloat<A>& cr, vfloat<A>& cg, vfloat<A>& cb, vfloat<A>& ca) const {
    vmask<A> const ok = !simd::isnan(v);
    vfloat<A> const x = simd::min(simd::max((simd::select(ok, v, vfloat<A>(lo)) - vfloat<A>(lo)) * vfloat<A>(scale),
                                            vfloat<A>(0.f)),
                                  vfloat<A>(float(size - 1) - 1e-3f));
    vint<A> const i = xsimd_trunc<A>(x);
    vfloat<A> const f = x - to_float<A>(i);
    vint<A> const j = i + vint<A>(1);
    cr = simd::gather(r, i) + f * (simd::gather(r, j) - simd::gather(r, i));
    cg = simd::gather(g, i) + f * (simd::gather(g, j) - simd::gather(g, i));
    cb = simd::gather(b, i) + f * (simd::gather(b, j) - simd::gather(b, i));
    ca = simd::select(ok, simd::gather(a, i) + f * (simd::gather(a, j) - simd::gather(a, i)), vfloat<A>(0.f));
  }

  template <class B> static vint<B> xsimd_trunc(vfloat<B> const& x) {
    if constexpr (std::is_same_v<B, scalar>) return int32_t(x);
    else return xsimd::batch_cast<int32_t>(x);
  }
  template <class B> static vfloat<B> to_float(vint<B> const& i) {
    if constexpr (std::is_same_v<B, scalar>) return float(i);
    else return xsimd::batch_cast<float>(i);
  }
};

/// Where each ray leaves the scene's bounding box.
template <class A> inline vfloat<A> scene_exit(RayPacket<A> const& r, PreparedScene const& s) {
  vfloat<A> const ax = (vfloat<A>(s.lo.x) - r.ox) * r.rx, bx = (vfloat<A>(s.hi.x) - r.ox) * r.rx;
  vfloat<A> const ay = (vfloat<A>(s.lo.y) - r.oy) * r.ry, by = (vfloat<A>(s.hi.y) - r.oy) * r.ry;
  vfloat<A> const az = (vfloat<A>(s.lo.z) - r.oz) * r.rz, bz = (vfloat<A>(s.hi.z) - r.oz) * r.rz;
  return simd::min(simd::min(simd::max(ax, bx), simd::max(ay, by)), simd::max(az, bz));
}

/// DVR gradient shading of one colour (render.hpp, DvrShading), scalar:
/// `g` the field gradient, `d` the unit ray direction.
inline void shade_color(DvrShading const& sh, float inv_gradient_full, float const g[3], glm::vec3 const& d,
                        float& r, float& gr, float& b) {
  float const gg = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
  float const len = std::sqrt(gg);
  if (!(len > 0.f) || !(len < std::numeric_limits<float>::infinity())) return;
  float const ndl = std::min(1.f, std::fabs(g[0] * d.x + g[1] * d.y + g[2] * d.z) / len);
  float const m = std::min(1.f, len * inv_gradient_full);
  float const lit = sh.ambient + sh.diffuse * ndl, spec = sh.specular * std::pow(ndl, sh.shininess);
  r += m * (std::min(1.f, r * lit + spec) - r);
  gr += m * (std::min(1.f, gr * lit + spec) - gr);
  b += m * (std::min(1.f, b * lit + spec) - b);
}

/// The same shading per lane (SIMD): `gx, gy, gz` the gradient, `r` the rays.
template <class A>
inline void shade_batch(DvrShading const& sh, float inv_gradient_full, vfloat<A> const& gx, vfloat<A> const& gy,
                        vfloat<A> const& gz, RayPacket<A> const& r, vfloat<A>& cr, vfloat<A>& cg, vfloat<A>& cb) {
  vfloat<A> const zero(0.f), one(1.f);
  vfloat<A> const len = simd::sqrt(gx * gx + gy * gy + gz * gz);
  vmask<A> const ok = len > zero && len < vfloat<A>(std::numeric_limits<float>::infinity());  // false for NaN
  if (simd::none(ok)) return;
  vfloat<A> const safe = simd::select(ok, len, one);
  // Lanes that are not ok (a NaN cell's gradient, or a lane not integrating)
  // keep their colour untouched: 0 * NaN would be NaN.
  vfloat<A> const ndl = simd::select(ok, simd::min(one, simd::abs(gx * r.dx + gy * r.dy + gz * r.dz) / safe), zero);
  vfloat<A> const m = simd::select(ok, simd::min(one, len * vfloat<A>(inv_gradient_full)), zero);
  vfloat<A> const lit = vfloat<A>(sh.ambient) + vfloat<A>(sh.diffuse) * ndl;
  vfloat<A> const spec = vfloat<A>(sh.specular) * pow_batch<A>(ndl, sh.shininess);
  cr = simd::select(ok, cr + m * (simd::min(one, cr * lit + spec) - cr), cr);
  cg = simd::select(ok, cg + m * (simd::min(one, cg * lit + spec) - cg), cg);
  cb = simd::select(ok, cb + m * (simd::min(one, cb * lit + spec) - cb), cb);
}

/// e^x per lane (xsimd's vector exp; std::exp for the scalar arch).
template <class B> inline vfloat<B> vexp(vfloat<B> const& x) {
  if constexpr (std::is_same_v<B, scalar>) return std::exp(x);
  else return xsimd::exp(x);
}

/// The transfer function over a piece of length `d` whose midpoint value is
/// `v`, per lane: colour from the table (linear in between) and opacity
/// 1 - exp(d ln(transmittance per unit length)); a NaN value is transparent.
template <class A> struct PieceColor {
  vfloat<A> r, g, b, a;
};
template <class A> inline PieceColor<A> piece_color(PreparedTf const& ptf, vfloat<A> const& v, vfloat<A> const& d) {
  vfloat<A> const lo(ptf.lo), scale(ptf.scale), zero(0.f), one(1.f);
  vfloat<A> const last(float(ptf.r.size() - 1) - 1e-3f);
  vmask<A> const ok = !simd::isnan(v);
  vfloat<A> const x = simd::min(simd::max((simd::select(ok, v, lo) - lo) * scale, zero), last);
  vint<A> const i = TfTable<A>::template xsimd_trunc<A>(x);
  vfloat<A> const f = x - TfTable<A>::template to_float<A>(i);
  vint<A> const i1 = i + vint<A>(1);
  auto lerp = [&](std::vector<float> const& t) {
    vfloat<A> const a = simd::gather(t.data(), i);
    return a + f * (simd::gather(t.data(), i1) - a);
  };
  vfloat<A> const lt = simd::select(ok, simd::min(lerp(ptf.log_transmittance), zero), zero);
  return {lerp(ptf.r), lerp(ptf.g), lerp(ptf.b), one - vexp<A>(lt * d)};
}

/// One ray's sorted segments over [from, to], unshaded: the pieces (midpoint
/// value and length) listed scalar, then their transfer-function colour and
/// opacity W pieces at a time (table gathers, vector exp), then composited
/// front to back in order, scalar, with exact termination.
template <class A>
inline void integrate_pieces(PreparedTf const& ptf, float step, float termination, FieldSegment const* seg,
                             uint8_t const* order, int n, float from, float to, float (&col)[3], float& alpha,
                             float depth_at, float& depth) {
  constexpr int W = width<A>;
  constexpr int cap = 128;  // pieces per batch (a multiple of every W)
  alignas(64) float pv[cap], pd[cap], pt[cap];
  alignas(64) float pr[cap], pg[cap], pb[cap], pa[cap];
  auto flush = [&](int np) {
    for (int j = np; j % W; ++j) pv[j] = ptf.lo, pd[j] = 0.f;  // padding: zero length, no opacity
    for (int j = 0; j < np; j += W) {
      PieceColor<A> const c = piece_color<A>(ptf, simd::load<A>(pv + j), simd::load<A>(pd + j));
      simd::store(pa + j, c.a), simd::store(pr + j, c.r), simd::store(pg + j, c.g), simd::store(pb + j, c.b);
    }
    for (int j = 0; j < np && alpha < termination; ++j) {
      float const w = std::min((1.f - alpha) * pa[j], termination - alpha);  // exact termination
      col[0] += w * pr[j], col[1] += w * pg[j], col[2] += w * pb[j];
      if (alpha < depth_at && alpha + w >= depth_at) depth = pt[j];
      alpha += w;
    }
  };
  int np = 0;
  float prev = from;
  for (int si = 0; si < n && alpha < termination; ++si) {
    FieldSegment const& fs = seg[order ? order[si] : si];
    float const a = std::max(fs.s.t_in, prev), e = std::min(fs.s.t_out, to);
    if (!(e > a)) continue;
    int const pieces = std::max(1, int(std::ceil((e - a) / step)));
    float const d = (e - a) / float(pieces);
    for (int i = 0; i < pieces; ++i) {
      pt[np] = a + (float(i) + 0.5f) * d;
      pv[np] = fs.value_at(fs.lambda(pt[np]));
      pd[np++] = d;
      if (np == cap) {
        flush(np), np = 0;
        if (!(alpha < termination)) return;
      }
    }
    prev = e;
  }
  if (np) flush(np);
}

/// What cell-segment DVR reuses from packet to packet of a tile: the
/// segment queries are large (max_segments per lane) and allocated once.
template <class A> struct SegmentScratch {
  std::unique_ptr<SegmentQuery<A, 4>> tet_query;
  std::unique_ptr<SegmentQuery<A, 8>> hex_query;
  std::vector<FieldSegment> lane_segs[width<A>];
};

/// Cell-segment DVR: the cells each ray crosses, window by window, each
/// segment integrated in pieces of at most `step` with the exact transfer
/// function at each piece's midpoint (midpoint rule). The field along a
/// segment comes from segments.hpp: exact-linear in tets, the cubic through
/// four on-ray values in hexes.
template <class A>
void integrate_segments(PreparedScene const& s, RayPacket<A> const& r, vmask<A> const& inside,
                        vfloat<A> const& t_enter, vfloat<A> const& t_exit, DvrParams const& p, Traversal how,
                        int threshold, SegmentScratch<A>& scratch, vfloat<A>& cr, vfloat<A>& cg, vfloat<A>& cb,
                        vfloat<A>& ca, float depth_at, vfloat<A>& depth) {
  constexpr int W = width<A>;
  PreparedTf const& ptf = *s.tf;
  auto depth_lane = simd::to_array<A>(depth);
  float const last_entry = float(ptf.r.size() - 1) - 1e-3f;
  auto lerp_entry = [](std::vector<float> const& t, int i, float f) { return t[size_t(i)] + f * (t[size_t(i) + 1] - t[size_t(i)]); };
  bool const shade = p.shading.enabled;
  // The first window is group_size steps long; each further one twice the
  // last: a ray still going after a window is likely crossing transparent or
  // faint material, and every window costs a traversal from the root. The
  // work past the termination point is at most the last window.
  float window = s.step * float(p.group_size);
  auto const enter = simd::to_array<A>(t_enter), exit_t = simd::to_array<A>(t_exit);
  auto const dx = simd::to_array<A>(r.dx), dy = simd::to_array<A>(r.dy), dz = simd::to_array<A>(r.dz);
  float col[W][3] = {}, alpha[W] = {}, t_cur[W];
  uint32_t live = simd::movemask(inside);
  for (int l = 0; l < W; ++l) t_cur[l] = enter[l];
  bool const single = s.parts.size() == 1;
  auto& lane_segs = scratch.lane_segs;
  while (live) {
    if (!single)
      for (auto& v : lane_segs) v.clear();
    alignas(64) float lo_a[W], hi_a[W];
    for (int l = 0; l < W; ++l) lo_a[l] = t_cur[l], hi_a[l] = t_cur[l] + window;
    vfloat<A> const lo = simd::load<A>(lo_a), hi = simd::load<A>(hi_a);
    vmask<A> const act = simd::mask_from_bits<A>(live);
    float end[W];
    for (int l = 0; l < W; ++l) end[l] = std::min(hi_a[l], exit_t[l]);
    // One part (the common case): integrate straight from the query's sorted
    // per-lane arrays. Several parts: merge their segments per lane.
    FieldSegment const* seg_of[W] = {};
    uint8_t const* order_of[W] = {};  // nullptr: seg_of is in order
    int seg_count[W] = {};
    for (PreparedPart const& part : s.parts) {
      auto run = [&](auto const& mesh, auto& q) {
        constexpr int N = std::decay_t<decltype(mesh)>::corners;
        if (!q) q = std::make_unique<SegmentQuery<A, N>>(part.tree, mesh, r, s.windows, lo, hi, shade);
        else q->reset(part.tree, mesh, r, lo, hi);
        collect_segments(*q, act, how, threshold);
        for (int l = 0; l < W; ++l) {
          end[l] = std::min(end[l], q->cut[l]);
          if (single) seg_of[l] = q->seg[l], order_of[l] = q->order[l], seg_count[l] = q->count[l];
          else lane_segs[l].insert(lane_segs[l].end(), q->seg[l], q->seg[l] + q->count[l]);
        }
      };
      if (part.tets) run(*part.tets, scratch.tet_query);
      else run(*part.hexes, scratch.hex_query);
    }
    uint32_t next = 0;
    for (uint32_t b = live; b; b &= b - 1) {
      int const l = __builtin_ctz(b);
      if (!single) {
        auto& segs = lane_segs[l];
        std::sort(segs.begin(), segs.end(), [](FieldSegment const& x, FieldSegment const& y) { return x.s.t_in < y.s.t_in; });
        seg_of[l] = segs.data(), seg_count[l] = int(segs.size());
      }
      if (!(end[l] > t_cur[l])) {
        // More than max_segments cells overlap the ray at t_cur (only
        // overlapping or duplicated cells do that): go on to the nearest end
        // of a kept segment past t_cur, so every window makes progress.
        float e = std::min(hi_a[l], exit_t[l]);
        for (int si = 0; si < seg_count[l]; ++si)
          if (seg_of[l][si].s.t_out > t_cur[l]) e = std::min(e, seg_of[l][si].s.t_out);
        end[l] = e;
      }
      glm::vec3 const dir(dx[size_t(l)], dy[size_t(l)], dz[size_t(l)]);
      float prev = t_cur[l];
      if (!shade)  // W pieces at a time; gradient shading below, piece by piece
        integrate_pieces<A>(ptf, s.step, p.termination, seg_of[l], order_of[l], seg_count[l], t_cur[l], end[l], col[l],
                            alpha[l], depth_at, depth_lane[size_t(l)]);
      for (int si = 0; si < seg_count[l] && shade; ++si) {
        FieldSegment const& fs = seg_of[l][order_of[l] ? order_of[l][si] : si];
        CellSegment const& sg = fs.s;
        float const a = std::max(sg.t_in, prev), e = std::min(sg.t_out, end[l]);
        if (!(e > a)) continue;
        int const pieces = std::max(1, int(std::ceil((e - a) / s.step)));
        float const d = (e - a) / float(pieces);
        for (int i = 0; i < pieces && alpha[l] < p.termination; ++i) {
          float const lam = fs.lambda(a + (float(i) + 0.5f) * d);
          // The transfer function from the table (4096 entries, linear in
          // between, as the samples use): colour and ln(transmittance) per
          // unit length, so a piece of any length costs one exp.
          float const x = std::min(std::max((fs.value_at(lam) - ptf.lo) * ptf.scale, 0.f), last_entry);
          if (!(x == x)) continue;
          int const e0 = int(x);
          float const f = x - float(e0);
          float const lt = lerp_entry(ptf.log_transmittance, e0, f);
          if (!(lt < 0.f)) continue;  // transparent
          glm::vec3 c(lerp_entry(ptf.r, e0, f), lerp_entry(ptf.g, e0, f), lerp_entry(ptf.b, e0, f));
          if (shade) {
            float g[3];
            fs.gradient_at(lam, g);
            shade_color(p.shading, s.inv_gradient_full, g, dir, c.r, c.g, c.b);
          }
          float const ad = 1.f - std::exp(lt * d);
          float const w = std::min((1.f - alpha[l]) * ad, p.termination - alpha[l]);  // exact termination
          col[l][0] += w * c.r, col[l][1] += w * c.g, col[l][2] += w * c.b;
          if (alpha[l] < depth_at && alpha[l] + w >= depth_at) depth_lane[size_t(l)] = a + (float(i) + 0.5f) * d;
          alpha[l] += w;
        }
        prev = e;
      }
      t_cur[l] = end[l];
      if (alpha[l] < p.termination && t_cur[l] < exit_t[l]) next |= 1u << l;
    }
    live = next;
    window *= 2.f;
  }
  alignas(64) float o[4][W];
  for (int l = 0; l < W; ++l) o[0][l] = col[l][0], o[1][l] = col[l][1], o[2][l] = col[l][2], o[3][l] = alpha[l];
  cr = simd::load<A>(o[0]), cg = simd::load<A>(o[1]), cb = simd::load<A>(o[2]), ca = simd::load<A>(o[3]);
  depth = simd::load<A>(depth_lane.data());
}

/// Cell-segment DVR by marching (traverse/march.hpp): the same segments as
/// integrate_segments, the same pieces (at most `step` long, the transfer
/// function at each piece's midpoint), the same field along a segment (tets:
/// linear; hexes: SegmentQuery's cubic) and the same compositing, but one
/// cell per lane per step, integrated across the lanes in SIMD as it is
/// found. Parts with face neighbours only (PreparedPart::neighbours,
/// hex_neighbours), one part.
template <class A, int N>
void integrate_march(PreparedScene const& s, TreeView const& tree, CellMesh<N> const& mesh,
                     NeighboursOf<N> const& nb, RayPacket<A> const& r, vmask<A> const& inside,
                     vfloat<A> const& t_enter, vfloat<A> const& t_exit, DvrParams const& p, Traversal how,
                     int threshold, vfloat<A>& cr, vfloat<A>& cg, vfloat<A>& cb, vfloat<A>& ca, float depth_at,
                     vfloat<A>& depth) {
  PreparedTf const& ptf = *s.tf;
  bool const shade = p.shading.enabled;
  vfloat<A> const zero(0.f), one(1.f), half(0.5f), term(p.termination), inv_step(1.f / s.step);
  CellMarch<A, N> m(tree, mesh, nb, r, s.windows, t_enter, t_exit);
  RayBatch<A> const ray = ray_batch(r);
  vmask<A> live = inside;
  while (simd::any(live)) {
    // Lanes without a cell wait until no lane has one: one traversal then
    // locates them all. Locating as soon as half the live lanes wait was
    // 1.16x slower on component8 (a quarter: 1.21x; 1024x1024, 1 thread,
    // AVX-512, the bench's transfer function): a traversal costs more than
    // idle lanes do.
    vmask<A> const has = live && m.has_cell();
    if (simd::none(has)) {
      live = live && !m.locate(live, how, threshold);
      continue;
    }
    typename CellMarch<A, N>::Step const st = m.step(has, shade);
    vmask<A> const go = st.visible && ca < term;
    if (simd::any(go)) {
      vfloat<A> const len = st.e - st.a;
      vfloat<A> const pieces = simd::max(one, simd::ceil(len * inv_step));
      vfloat<A> const d = len / pieces;
      vfloat<A> const seg_len = st.k.t_out - st.k.t_in;
      vmask<A> const long_enough = seg_len > zero;
      vfloat<A> const inv_len = one / simd::select(long_enough, seg_len, one);
      // The field along the segment as value(lambda) (integrate_segments'
      // FieldSegment): a tet's line, a hex's cubic through four points.
      isa_detail::Cubic<A> f{st.k.s_in, st.k.s_out - st.k.s_in, zero, zero};
      isa_detail::Cubic<A> gc[3];
      if constexpr (N == 8) {
        Vec3<A> u1, u2;
        vfloat<A> const v1 = SegmentQuery<A, 8>::hex_on_ray(ray, st.c, st.k, go, 1.f / 3.f, u1);
        vfloat<A> const v2 = SegmentQuery<A, 8>::hex_on_ray(ray, st.c, st.k, go, 2.f / 3.f, u2);
        f = isa_detail::cubic_through<A>(st.k.s_in, v1, v2, st.k.s_out);
        if (shade) {
          Vec3<A> const g0 = isa_detail::hex_world_gradient(st.c, st.k.u_in), g1 = isa_detail::hex_world_gradient(st.c, u1);
          Vec3<A> const g2 = isa_detail::hex_world_gradient(st.c, u2), g3 = isa_detail::hex_world_gradient(st.c, st.k.u_out);
          gc[0] = isa_detail::cubic_through<A>(g0.x, g1.x, g2.x, g3.x);
          gc[1] = isa_detail::cubic_through<A>(g0.y, g1.y, g2.y, g3.y);
          gc[2] = isa_detail::cubic_through<A>(g0.z, g1.z, g2.z, g3.z);
        }
      }
      vfloat<A> piece(0.f);
      for (vmask<A> on = go; simd::any(on); piece = piece + one, on = on && piece < pieces && ca < term) {
        vfloat<A> const tm = st.a + (piece + half) * d;
        vfloat<A> const lam = simd::select(long_enough, (tm - st.k.t_in) * inv_len, zero);
        PieceColor<A> c = piece_color<A>(ptf, f.c0 + lam * (f.c1 + lam * (f.c2 + lam * f.c3)), d);  // as integrate_pieces
        if (shade) {
          if constexpr (N == 8)
            shade_batch<A>(p.shading, s.inv_gradient_full, gc[0](lam), gc[1](lam), gc[2](lam), r, c.r, c.g, c.b);
          else
            shade_batch<A>(p.shading, s.inv_gradient_full, st.gradient.x, st.gradient.y, st.gradient.z, r, c.r, c.g, c.b);
        }
        vfloat<A> const w = simd::select(on, simd::min((one - ca) * c.a, term - ca), zero);  // exact termination
        cr = cr + w * c.r, cg = cg + w * c.g, cb = cb + w * c.b;
        depth = simd::select(ca < vfloat<A>(depth_at) && ca + w >= vfloat<A>(depth_at), tm, depth);
        ca = ca + w;
      }
    }
    live = live && ca < term && m.t < t_exit;
  }
}

/// Point-sampled DVR (Rathke 2015 §7): samples at t_enter + (k + 1/2) step,
/// located in groups of G through the BVH. Each sample stands for the step
/// around it; where the next (previous) sample is outside the visible mesh
/// (outside every cell, in a NaN cell, past the scene's exit), the step is
/// clipped at the exit (entry) of the sample's own cell, so a ray's first and
/// last steps count only their part inside the mesh: without this the error
/// is first order in the step (a boundary step counts in full or not at all),
/// with it the midpoint rule's second order. A sample is therefore
/// composited one sample late, when its successor's validity is known.
template <class A>
void integrate_samples(PreparedScene const& s, RayPacket<A> const& r, vmask<A> const& inside,
                       vfloat<A> const& t_enter, vfloat<A> const& t_exit, DvrParams const& p, Traversal how,
                       int threshold, SampleCull* cull, vfloat<A>& cr, vfloat<A>& cg, vfloat<A>& cb, vfloat<A>& ca,
                       float depth_at, vfloat<A>& depth) {
  constexpr int W = width<A>;
  constexpr float nan = std::numeric_limits<float>::quiet_NaN();
  PreparedTf const& ptf = *s.tf;
  TfTable<A> const table{ptf.r.data(), ptf.g.data(), ptf.b.data(), ptf.a.data(), int(ptf.r.size()), ptf.lo, ptf.scale};
  float const step = s.step, half = 0.5f * step;
  int G = p.group_size;  // doubles after every group, as segments' windows do
  bool const shade = p.shading.enabled;
  vfloat<A> const term(p.termination), one(1.f);
  // The pending sample per lane: colour, opacity for a full step, its t, the
  // left end of its step when clipped, its cell's exit.
  vmask<A> pend = simd::no_lanes<A>(), pend_left_clip = pend, prev_valid = pend;
  vfloat<A> pr(0.f), pg(0.f), pb(0.f), pa(0.f), pt(0.f), pleft(0.f), pout(0.f);
  // Composites the pending samples of `lanes`; `right_clip`: their successor
  // is invalid, so their step ends at their cell's exit.
  auto composite = [&](vmask<A> const& lanes, vmask<A> const& right_clip) {
    vfloat<A> a = pa;
    vmask<A> const clipped = lanes && (pend_left_clip || right_clip);
    if (simd::any(clipped)) {
      // Rare (mesh entry and exit): a' = 1 - (1 - a)^(length / step) per lane.
      vfloat<A> const right = simd::min(simd::max(pout, pt), pt + vfloat<A>(step));
      vfloat<A> const len = simd::select(pend_left_clip, pt - pleft, vfloat<A>(half)) +
                            simd::select(right_clip, right - pt, vfloat<A>(half));
      auto const aa = simd::to_array<A>(a), ll = simd::to_array<A>(len);
      alignas(64) float out[W];
      uint32_t const cb_bits = simd::movemask(clipped);
      for (int l = 0; l < W; ++l)
        out[l] = (cb_bits >> l) & 1u ? 1.f - std::pow(1.f - aa[size_t(l)], ll[size_t(l)] / step) : aa[size_t(l)];
      a = simd::load<A>(out);
    }
    // Early termination exactly at `termination`: the sample that crosses it
    // counts only up to there (its colour is constant over its step), as in
    // the reference. Counting it in full is an error of first order in the step.
    vfloat<A> const w = simd::select(lanes, simd::min((one - ca) * a, simd::max(term - ca, vfloat<A>(0.f))), vfloat<A>(0.f));
    depth = simd::select(ca < vfloat<A>(depth_at) && ca + w >= vfloat<A>(depth_at), pt, depth);
    cr = cr + w * pr, cg = cg + w * pg, cb = cb + w * pb, ca = ca + w;
  };
  vfloat<A> t0 = t_enter + vfloat<A>(half);
  vmask<A> active = inside && t0 <= t_exit;
  while (simd::any(active)) {
    alignas(64) float values[max_sample_group][W], cin[max_sample_group][W], cout[max_sample_group][W];
    alignas(64) float grad[3][max_sample_group][W];
    for (int g = 0; g < G; ++g)
      for (int l = 0; l < W; ++l) {
        values[g][l] = nan, cin[g][l] = cout[g][l] = 0.f;
        if (shade) grad[0][g][l] = grad[1][g][l] = grad[2][g][l] = 0.f;
      }
    for (size_t pi = 0; pi < s.parts.size(); ++pi) {
      PreparedPart const& part = s.parts[pi];
      auto run = [&](auto const& mesh) {
        constexpr int N = std::decay_t<decltype(mesh)>::corners;
        SampleQuery<A, N> q(part.tree, mesh, r, s.windows, t0, step, G, active);
        q.cull = &cull[pi];
        q.want_interval = true;
        q.want_gradient = shade;
        sample_group(q, active, how, threshold);
        for (int g = 0; g < G; ++g)
          for (int l = 0; l < W; ++l) {
            if (values[g][l] == values[g][l] || q.values[g][l] != q.values[g][l]) continue;
            values[g][l] = q.values[g][l], cin[g][l] = q.cell_in[g][l], cout[g][l] = q.cell_out[g][l];
            if (shade) grad[0][g][l] = q.grad[0][g][l], grad[1][g][l] = q.grad[1][g][l], grad[2][g][l] = q.grad[2][g][l];
          }
      };
      if (part.tets) run(*part.tets);
      else run(*part.hexes);
    }
    for (int g = 0; g < G; ++g) {
      vfloat<A> const t = t0 + vfloat<A>(step * float(g));
      vmask<A> const in_range = active && t <= t_exit;
      vmask<A> const finish = active && pend;
      if (simd::none(in_range) && simd::none(finish)) break;
      vfloat<A> const v = simd::load<A>(values[g]);
      vmask<A> const valid = in_range && !simd::isnan(v);
      if (simd::any(finish)) composite(finish, !valid);
      pend = pend && !finish;
      vmask<A> const take = valid && ca < term;
      if (simd::any(take)) {
        vfloat<A> sr, sg, sb, sa;
        table.lookup(v, sr, sg, sb, sa);
        if (shade)
          shade_batch<A>(p.shading, s.inv_gradient_full, simd::load<A>(grad[0][g]), simd::load<A>(grad[1][g]),
                         simd::load<A>(grad[2][g]), r, sr, sg, sb);
        vfloat<A> const c_in = simd::select(valid, simd::load<A>(cin[g]), t);
        vfloat<A> const c_out = simd::select(valid, simd::load<A>(cout[g]), t);
        pr = simd::select(take, sr, pr), pg = simd::select(take, sg, pg), pb = simd::select(take, sb, pb);
        pa = simd::select(take, sa, pa), pt = simd::select(take, t, pt), pout = simd::select(take, c_out, pout);
        pleft = simd::select(take, simd::max(simd::min(c_in, t), t - vfloat<A>(step)), pleft);
        pend_left_clip = (take && !prev_valid) || (!take && pend_left_clip);
        pend = pend || take;
      }
      prev_valid = (active && valid) || (!active && prev_valid);
    }
    t0 = t0 + vfloat<A>(step * float(G));
    G = std::min(2 * G, max_sample_group);
    active = active && t0 <= t_exit && ca < term;
  }
  if (simd::any(pend)) composite(pend, pend);
}

/// What DVR reuses from packet to packet: segment queries, per-part sample
/// culling (cell sizes differ; measured once per tile or chunk of rays).
template <class A> struct DvrScratch {
  SegmentScratch<A> segments;
  std::vector<SampleCull> sample_cull;
  explicit DvrScratch(PreparedScene const& s) : sample_cull(s.parts.size()) {}
};

/// One packet of DVR rays over [t_lo, t_hi] per lane (camera rays: [0, the
/// host's depth]; host rays: their own interval), narrowed to the scene's
/// box and the clip region: premultiplied colour and opacity, and where the
/// opacity first reaches `depth_at` (+inf: never).
template <class A>
void dvr_packet(PreparedScene const& s, DvrParams const& p, RenderOptions const& o, RayPacket<A> const& r,
                vmask<A> lanes, vfloat<A> const& t_lo, vfloat<A> const& t_hi, DvrScratch<A>& scratch, vfloat<A>& cr,
                vfloat<A>& cg, vfloat<A>& cb, vfloat<A>& ca, float depth_at, vfloat<A>& depth) {
  constexpr int W = width<A>;
  int const threshold = o.hybrid_threshold > 0 ? o.hybrid_threshold : std::max(1, W / 4);
  bool const march = s.parts.size() == 1 && (s.parts[0].neighbours || s.parts[0].hex_neighbours);
  // The part of each ray inside the scene's bounds. An empty scene's box
  // (lo = +inf, hi = -inf) passes the slab test for every t: no ray is
  // inside it (else the sample march never ends).
  vfloat<A> t_enter;
  vmask<A> inside = (s.lo.x <= s.hi.x ? lanes : simd::no_lanes<A>()) &&
                    box_hit(r, &s.lo.x, &s.hi.x, t_lo, simd::min(t_hi, vfloat<A>(std::numeric_limits<float>::max())),
                            t_enter);
  vfloat<A> t_exit = simd::min(scene_exit(r, s), t_hi);
  t_enter = simd::max(t_enter, t_lo);
  if (s.clip.count > 0) {
    ClipSpan<A> const cs = clip_span<A>(s.clip, r, t_enter, t_exit);
    t_enter = simd::select(inside, cs.t0, t_enter), t_exit = simd::select(inside, cs.t1, t_exit);
  }
  inside = inside && t_enter < t_exit;
  cr = cg = cb = ca = vfloat<A>(0.f);
  depth = vfloat<A>(std::numeric_limits<float>::infinity());
  if (simd::none(inside)) return;
  if (p.mode == DvrMode::samples)
    integrate_samples<A>(s, r, inside, t_enter, t_exit, p, o.traversal, threshold, scratch.sample_cull.data(), cr, cg,
                         cb, ca, depth_at, depth);
  else if (march && s.parts[0].tets)
    integrate_march<A, 4>(s, s.parts[0].tree, *s.parts[0].tets, *s.parts[0].neighbours, r, inside, t_enter, t_exit, p,
                          o.traversal, threshold, cr, cg, cb, ca, depth_at, depth);
  else if (march)
    integrate_march<A, 8>(s, s.parts[0].tree, *s.parts[0].hexes, *s.parts[0].hex_neighbours, r, inside, t_enter,
                          t_exit, p, o.traversal, threshold, cr, cg, cb, ca, depth_at, depth);
  else
    integrate_segments<A>(s, r, inside, t_enter, t_exit, p, o.traversal, threshold, scratch.segments, cr, cg, cb, ca,
                          depth_at, depth);
}

template <class A>
void render_dvr_tile(PreparedScene const& s, Camera const& cam, DvrParams const& p, RenderOptions const& o,
                     Tile const& tile, FrameBuffer const& out) {
  constexpr int W = width<A>;
  DvrScratch<A> scratch(s);
  for (int by = tile.y0; by < tile.y0 + tile.h; by += block_h<A>)
    for (int bx = tile.x0; bx < tile.x0 + tile.w; bx += block_w<A>) {
      int px[W], py[W];
      uint32_t valid;
      RayPacket<A> const r = camera_packet<A>(cam, tile, bx, by, px, py, valid);
      vfloat<A> cr, cg, cb, ca, depth;
      dvr_packet<A>(s, p, o, r, simd::mask_from_bits<A>(valid), vfloat<A>(0.f), host_depth<A>(out, px, py, valid),
                    scratch, cr, cg, cb, ca, out.depth_opacity, depth);
      auto const ar = simd::to_array<A>(cr), ag = simd::to_array<A>(cg), ab = simd::to_array<A>(cb),
                 aa = simd::to_array<A>(ca), ad = simd::to_array<A>(depth);
      for (int l = 0; l < W; ++l) {
        if (!((valid >> l) & 1u)) continue;
        float const rest = (1.f - aa[l]) * p.background.a;
        put_pixel(out, px[l], py[l], ar[l] + rest * p.background.r, ag[l] + rest * p.background.g,
                  ab[l] + rest * p.background.b, aa[l] + rest);
        if (out.depth_out) put_depth(out, px[l], py[l], ad[l]);
      }
    }
}

/// Host rays, W at a time (see RayVolumeEntry).
template <class A>
void integrate_host_rays(PreparedScene const& s, DvrParams const& p, RenderOptions const& o, Ray const* rays,
                         uint64_t n, float* rgba, float* depth_out, float depth_at) {
  constexpr int W = width<A>;
  DvrScratch<A> scratch(s);
  for (uint64_t base = 0; base < n; base += W) {
    int const cnt = int(std::min<uint64_t>(W, n - base));
    RayPacket<A> const r = load_rays<A>(rays + base, cnt);
    // A ray without a usable direction or interval gives nothing.
    vfloat<A> const len2 = r.dx * r.dx + r.dy * r.dy + r.dz * r.dz;
    vmask<A> const lanes = simd::mask_from_bits<A>(cnt >= 32 ? ~0u : (1u << cnt) - 1u) && len2 > vfloat<A>(0.f) &&
                           len2 < vfloat<A>(std::numeric_limits<float>::infinity()) && r.tmin <= r.tmax;
    vfloat<A> cr, cg, cb, ca, depth;
    dvr_packet<A>(s, p, o, r, lanes, simd::max(r.tmin, vfloat<A>(0.f)), r.tmax, scratch, cr, cg, cb, ca, depth_at,
                  depth);
    auto const ar = simd::to_array<A>(cr), ag = simd::to_array<A>(cg), ab = simd::to_array<A>(cb),
               aa = simd::to_array<A>(ca), ad = simd::to_array<A>(depth);
    for (int l = 0; l < cnt; ++l) {
      float* q = rgba + 4 * (base + uint64_t(l));
      q[0] = ar[size_t(l)], q[1] = ag[size_t(l)], q[2] = ab[size_t(l)], q[3] = aa[size_t(l)];
      if (depth_out) depth_out[base + uint64_t(l)] = ad[size_t(l)];
    }
  }
}

}  // namespace impl
}  // namespace CELLRAY_ISA_NS

template <class Arch>
void RenderTileEntry<Arch>::run(PreparedScene const& s, Camera const& cam, IsoParams const& p, RenderOptions const& o,
                                Tile tile, FrameBuffer const& out) {
  impl::render_iso_tile<Arch>(s, cam, p, o, tile, out);
}
template <class Arch>
void RenderTileEntry<Arch>::run(PreparedScene const& s, Camera const& cam, DvrParams const& p, RenderOptions const& o,
                                Tile tile, FrameBuffer const& out) {
  impl::render_dvr_tile<Arch>(s, cam, p, o, tile, out);
}
template <class Arch>
void RayVolumeEntry<Arch>::run(PreparedScene const& s, DvrParams const& p, RenderOptions const& o, Ray const* rays,
                               uint64_t n, float* rgba, float* depth, float depth_at) {
  impl::integrate_host_rays<Arch>(s, p, o, rays, n, rgba, depth, depth_at);
}

}  // namespace cellray
