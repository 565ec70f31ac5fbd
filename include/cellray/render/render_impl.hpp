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

/// Where a packet of DVR rays is inside the scene's bounds and the clip
/// region: per lane [t_enter, t_exit] within [t_lo, t_hi], in `inside`.
template <class A> struct DvrSpan {
  vmask<A> inside;
  vfloat<A> t_enter, t_exit;
};

template <class A>
inline DvrSpan<A> dvr_span(PreparedScene const& s, RayPacket<A> const& r, vmask<A> lanes, vfloat<A> const& t_lo,
                           vfloat<A> const& t_hi) {
  // An empty scene's box (lo = +inf, hi = -inf) passes the slab test for
  // every t: no ray is inside it (else the sample march never ends).
  DvrSpan<A> sp;
  sp.inside = (s.lo.x <= s.hi.x ? lanes : simd::no_lanes<A>()) &&
              box_hit(r, &s.lo.x, &s.hi.x, t_lo, simd::min(t_hi, vfloat<A>(std::numeric_limits<float>::max())),
                      sp.t_enter);
  sp.t_exit = simd::min(scene_exit(r, s), t_hi);
  sp.t_enter = simd::max(sp.t_enter, t_lo);
  if (s.clip.count > 0) {
    ClipSpan<A> const cs = clip_span<A>(s.clip, r, sp.t_enter, sp.t_exit);
    sp.t_enter = simd::select(sp.inside, cs.t0, sp.t_enter), sp.t_exit = simd::select(sp.inside, cs.t1, sp.t_exit);
  }
  sp.inside = sp.inside && sp.t_enter < sp.t_exit;
  return sp;
}

/// One packet of DVR rays over its span (dvr_span): premultiplied colour
/// and opacity, and where the opacity first reaches `depth_at` (+inf:
/// never). `first_cells`: where a one-part march's rays start, located
/// already for the lanes inside the span (dvr_first_cells), or nullptr.
template <class A>
void dvr_packet(PreparedScene const& s, DvrParams const& p, RenderOptions const& o, RayPacket<A> const& r,
                DvrSpan<A> const& sp, vint<A> const* first_cells, DvrScratch<A>& scratch, vfloat<A>& cr,
                vfloat<A>& cg, vfloat<A>& cb, vfloat<A>& ca, float depth_at, vfloat<A>& depth) {
  constexpr int W = width<A>;
  int const threshold = o.hybrid_threshold > 0 ? o.hybrid_threshold : std::max(1, W / 4);
  bool const march = s.parts.size() == 1 && s.parts[0].marches();
  vmask<A> inside = sp.inside;
  vfloat<A> const& t_enter = sp.t_enter;
  vfloat<A> const& t_exit = sp.t_exit;
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
      if (first_cells) inside = m.take_located(inside, *first_cells);
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

/// Whether dvr_first_cells applies: cell segments marching through one
/// part, with packet traversal (the march's first locate).
inline bool dvr_groups_first_cells(PreparedScene const& s, DvrParams const& p, RenderOptions const& o) {
  return p.mode == DvrMode::segments && o.traversal == Traversal::packet && s.parts.size() == 1 &&
         s.parts[0].marches();
}

/// The first visible cell of every lane inside the spans of K packets, in
/// one traversal (traverse_packets; as CellMarch::locate finds it for one
/// packet): neighbouring pixel blocks share the nodes, leaves and cell
/// reads. -1: none.
template <class A, int K>
void dvr_first_cells(PreparedScene const& s, RayPacket<A> const (&r)[K], DvrSpan<A> const (&sp)[K],
                     vint<A> (&cells)[K]) {
  vmask<A> lanes[K];
  for (int k = 0; k < K; ++k) lanes[k] = sp[k].inside;
  PreparedPart const& pp = s.parts[0];
  pp.visit([&](auto const& mesh, auto const*) {
    constexpr int N = std::decay_t<decltype(mesh)>::corners;
    auto query = [&](int k) {
      return FirstCellQuery<A, N>(pp.tree, mesh, r[k], s.windows, sp[k].t_enter, sp[k].t_exit);
    };
    auto q = make_array<K>(query);
    FirstCellGroup<A, N, K> group(q.data(), r, lanes);
    traverse_packets<A, K>(pp.tree, r, lanes, group);
    for (int k = 0; k < K; ++k) cells[k] = q[k].cell;
  });
}

template <class A>
void render_dvr_tile(PreparedScene const& s, Camera const& cam, DvrParams const& p, RenderOptions const& o,
                     Tile const& tile, FrameBuffer const& out) {
  constexpr int W = width<A>;
  DvrScratch<A> scratch(s);
  // Eight neighbouring pixel blocks (group_x x group_y) locate their first
  // cells in one traversal (dvr_first_cells), then march one by one: the
  // later locates, at steps that differ from block to block, went together
  // too in a trial, and lost as much on one mesh as they won on another
  // (docs/performance.md, "Tried and dropped").
  constexpr int GX = group_x<A>, GY = group_y<A>, K = GX * GY;
  bool const grouped = dvr_groups_first_cells(s, p, o);
  for (int gy = tile.y0; gy < tile.y0 + tile.h; gy += GY * block_h<A>)
    for (int gx = tile.x0; gx < tile.x0 + tile.w; gx += GX * block_w<A>) {
      int gpx[K][W], gpy[K][W];
      uint32_t gvalid[K] = {};
      RayPacket<A> gr[K];
      DvrSpan<A> gs[K];
      for (int pk = 0; pk < K; ++pk) {
        int const bx = gx + (pk % GX) * block_w<A>, by = gy + (pk / GX) * block_h<A>;
        if (bx >= tile.x0 + tile.w || by >= tile.y0 + tile.h) {
          gr[pk] = gr[0], gs[pk] = gs[0];  // no lanes (block 0 is always in the tile)
          gs[pk].inside = simd::no_lanes<A>();
          continue;
        }
        gr[pk] = camera_packet<A>(cam, tile, bx, by, gpx[pk], gpy[pk], gvalid[pk]);
        gs[pk] = dvr_span<A>(s, gr[pk], simd::mask_from_bits<A>(gvalid[pk]), vfloat<A>(0.f),
                             host_depth<A>(out, gpx[pk], gpy[pk], gvalid[pk]));
      }
      vint<A> first[K];
      if (grouped) dvr_first_cells<A, K>(s, gr, gs, first);
      for (int pk = 0; pk < K; ++pk) {
        if (!gvalid[pk]) continue;
        int const(&px)[W] = gpx[pk];
        int const(&py)[W] = gpy[pk];
        uint32_t const valid = gvalid[pk];
        vfloat<A> cr, cg, cb, ca, depth;
        dvr_packet<A>(s, p, o, gr[pk], gs[pk], grouped ? &first[pk] : nullptr, scratch, cr, cg, cb, ca,
                      out.depth_opacity, depth);
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
    DvrSpan<A> const span = dvr_span<A>(s, r, lanes, simd::max(r.tmin, vfloat<A>(0.f)), r.tmax);
    dvr_packet<A>(s, p, o, r, span, nullptr, scratch, cr, cg, cb, ca, depth_at, depth);
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
