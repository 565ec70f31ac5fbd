#pragma once
// Bodies of RenderTileEntry and RayVolumeEntry (ISA units only): the iso
// tile loop (iso_impl.hpp), and DVR per packet of camera or host rays over
// the integrators of dvr_integrators_impl.hpp.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "dvr_integrators_impl.hpp"
#include "iso_impl.hpp"
#include "packets_impl.hpp"
#include "render.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

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
  bool const march = s.parts.size() == 1 && s.parts[0].marches();
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
  else if (march) {
    PreparedPart const& pp = s.parts[0];
    pp.visit([&](auto const& mesh, auto const* neighbours) {
      CellMarch<A, std::decay_t<decltype(mesh)>::corners> m(pp.tree, mesh, *neighbours, r, s.windows, t_enter, t_exit);
      integrate_march<A>(s, m, r, inside, t_exit, p, o.traversal, threshold, cr, cg, cb, ca, depth_at, depth);
    });
  } else if (s.mixed_march) {
    PartCells<4> const& t = *s.parts[0].cells_of<4>();  // prepare() checked both
    PartCells<8> const& h = *s.parts[1].cells_of<8>();
    MixedMarch<A> m(s.parts[0].tree, *t.mesh, *t.neighbours, s.parts[1].tree, *h.mesh, *h.neighbours, r, s.windows,
                    t_enter, t_exit);
    integrate_march<A>(s, m, r, inside, t_exit, p, o.traversal, threshold, cr, cg, cb, ca, depth_at, depth);
  } else
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
