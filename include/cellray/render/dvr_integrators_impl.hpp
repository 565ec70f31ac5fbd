#pragma once
// The DVR integrators (ISA units only), emission-absorption front to back:
// cell segments through the tree (integrate_segments) or marching through
// face neighbours (integrate_march), and point samples (integrate_samples);
// the transfer function's table and gradient shading they share.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <type_traits>
#include <vector>

#include "../traverse/cell_ops.hpp"
#include "../traverse/march.hpp"
#include "../traverse/sample.hpp"
#include "../traverse/segments.hpp"
#include "packets_impl.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

/// Entry i + f of a PairTable's pairs (`pairs`: PairTable::data()), per lane.
template <class A> inline vfloat<A> lerp_pairs(float const* pairs, vint<A> const& i, vfloat<A> const& f) {
  vfloat<A> e0, e1;
  simd::gather_pairs(pairs, i, e0, e1);
  return e0 + f * (e1 - e0);
}

/// Transfer function as a lookup table over [lo, hi] with the opacity
/// already corrected for the sample spacing: a' = 1 - (1 - a)^(step / unit).
template <class A> struct TfTable {
  float const* r;  ///< PairTable::data()
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
    cr = lerp_pairs<A>(r, i, f), cg = lerp_pairs<A>(g, i, f), cb = lerp_pairs<A>(b, i, f);
    ca = simd::select(ok, lerp_pairs<A>(a, i, f), vfloat<A>(0.f));
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
CELLRAY_FORCE_INLINE void shade_batch(DvrShading const& sh, float inv_gradient_full, vfloat<A> const& gx, vfloat<A> const& gy,
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

template <class A> struct PieceColor {
  vfloat<A> r, g, b, a;
};

/// The transfer function's integrals at value `v` per lane
/// (PreparedTf::integrals): the coordinate u, its cell, and the cell's
/// integrals before it (hi + lo) and across it, for the extinction and for
/// r, g, b times it. Three 16-byte loads a lane (simd::gather_quads3).
template <class A> struct TfIntegralAt {
  vfloat<A> u, cell;  ///< cell: its index as a float
  vfloat<A> hi[4], lo[4], in[4];
  vmask<A> ok;  ///< v is not NaN
};
template <class A> CELLRAY_FORCE_INLINE TfIntegralAt<A> tf_integral_at(PreparedTf const& ptf, vfloat<A> const& v) {
  TfIntegralAt<A> t;
  t.ok = !simd::isnan(v);
  // Within +-2^22 a float keeps a cell's index and a fraction of it; beyond
  // the range the function is constant, so clamping there changes no mean.
  vfloat<A> const lo(ptf.lo), bound(4194304.f), one(1.f);
  t.u = simd::min(simd::max((simd::select(t.ok, v, lo) - lo) * vfloat<A>(ptf.scale) + one, -bound), bound);
  t.cell = simd::floor(simd::min(simd::max(t.u, vfloat<A>(0.f)), vfloat<A>(float(ptf.size))));
  vint<A> const at = TfTable<A>::template xsimd_trunc<A>(t.cell) * vint<A>(PreparedTf::integral_stride);
  simd::gather_quads3(ptf.integrals.data(), at, t.hi, t.lo, t.in);
  return t;
}

/// A piece of length `d` whose value runs linearly between the values of
/// `a` and `b` (tf_integral_at), per lane: opacity 1 - exp(-d x the mean
/// extinction over those values) and the extinction-weighted mean colour,
/// exact for the table's function however it varies in between (a midpoint
/// rule steps over an opacity peak narrower than the piece's value span:
/// tests/test_render_march.cpp, "narrow opacity peak"). A NaN end:
/// transparent.
/// Forced inline: GCC 12 called its predecessor out of line in the tet
/// march once the onward clip was inlined there (component8 DVR 1.06-1.07x
/// inlined).
template <class A>
CELLRAY_FORCE_INLINE PieceColor<A> piece_between(TfIntegralAt<A> const& a, TfIntegralAt<A> const& b, vfloat<A> const& d) {
  vfloat<A> const zero(0.f), one(1.f);
  vfloat<A> const dc = b.cell - a.cell;
  vmask<A> const same = dc == zero, up = dc == one, down = dc == -one;
  vfloat<A> const fa = a.u - a.cell, fb = b.u - b.cell;
  // The integral from a to b is before[b] - before[a] + fb in[b] - fa in[a];
  // between neighbouring cells the difference of `before` is the lower
  // cell's `in`, taken as such (hi + lo would leave a rounding of the sum).
  vfloat<A> const wb = simd::select(same, fb - fa, simd::select(down, fb - one, fb));
  vfloat<A> const wa = simd::select(same, zero, simd::select(up, fa - one, fa));
  vmask<A> const far = !(same || up || down);
  vfloat<A> s[4];
  for (int k = 0; k < 4; ++k)
    s[k] = simd::select(far, (b.hi[k] - a.hi[k]) + (b.lo[k] - a.lo[k]), zero) + (wb * b.in[k] - wa * a.in[k]);
  // Within one cell the function is the cell's mean (no division by a
  // value span that may be zero).
  vfloat<A> const du = simd::select(same, one, b.u - a.u);
  vfloat<A> const sigma = simd::select(same, b.in[0], s[0] / du);
  vfloat<A> const weight = simd::select(same, b.in[0], s[0]);
  vmask<A> const lit = weight != zero;
  vfloat<A> const inv = one / simd::select(lit, weight, one);
  auto colour = [&](int k) { return simd::select(lit, simd::select(same, b.in[k], s[k]) * inv, zero); };
  vmask<A> const ok = a.ok && b.ok;
  return {colour(1), colour(2), colour(3), simd::select(ok && sigma > zero, one - vexp<A>(-(sigma * d)), zero)};
}

/// One ray's sorted segments over [from, to], unshaded: the pieces (the
/// values at their ends, their length) listed scalar, then their
/// transfer-function colour and opacity W pieces at a time (piece_between:
/// table loads, vector exp), then composited front to back in order,
/// scalar, with exact termination.
template <class A>
inline void integrate_pieces(PreparedTf const& ptf, float step, float termination, FieldSegment const* seg,
                             uint8_t const* order, int n, float from, float to, float (&col)[3], float& alpha,
                             float depth_at, float& depth) {
  constexpr int W = width<A>;
  constexpr int cap = 128;  // pieces per batch (a multiple of every W)
  alignas(64) float pv0[cap], pv1[cap], pd[cap], pt[cap];
  alignas(64) float pr[cap], pg[cap], pb[cap], pa[cap];
  auto flush = [&](int np) {
    for (int j = np; j % W; ++j) pv0[j] = pv1[j] = ptf.lo, pd[j] = 0.f;  // padding: zero length, no opacity
    for (int j = 0; j < np; j += W) {
      PieceColor<A> const c = piece_between<A>(tf_integral_at<A>(ptf, simd::load<A>(pv0 + j)),
                                               tf_integral_at<A>(ptf, simd::load<A>(pv1 + j)), simd::load<A>(pd + j));
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
    float v0 = fs.value_at(fs.lambda(a));
    for (int i = 0; i < pieces; ++i) {
      pt[np] = a + (float(i) + 0.5f) * d;
      pv0[np] = v0;
      pv1[np] = v0 = fs.value_at(fs.lambda(i + 1 == pieces ? e : a + float(i + 1) * d));
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
  template <int N> using QueryPtr = std::unique_ptr<SegmentQuery<A, N>>;
  PerCellTypeTuple<QueryPtr> queries;  ///< one per cell type, made when first used
  std::vector<FieldSegment> lane_segs[width<A>];
};

/// Cell-segment DVR: the cells each ray crosses, window by window, each
/// segment integrated in pieces of at most `step`, each over the transfer
/// function between its end values (piece_between). The field along a
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
      part.visit([&](auto const& mesh, auto const*) {
        constexpr int N = std::decay_t<decltype(mesh)>::corners;
        auto& q = std::get<std::unique_ptr<SegmentQuery<A, N>>>(scratch.queries);
        if (!q) q = std::make_unique<SegmentQuery<A, N>>(part.tree, mesh, r, s.windows, lo, hi, shade);
        else q->reset(part.tree, mesh, r, lo, hi);
        collect_segments(*q, act, how, threshold);
        for (int l = 0; l < W; ++l) {
          end[l] = std::min(end[l], q->cut[l]);
          if (single) seg_of[l] = q->seg[l], order_of[l] = q->order[l], seg_count[l] = q->count[l];
          else lane_segs[l].insert(lane_segs[l].end(), q->seg[l], q->seg[l] + q->count[l]);
        }
      });
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
        // As integrate_pieces, one piece at a time (the scalar arch of
        // piece_between), shaded with the gradient at its midpoint.
        TfIntegralAt<scalar> from = tf_integral_at<scalar>(ptf, fs.value_at(fs.lambda(a)));
        for (int i = 0; i < pieces && alpha[l] < p.termination; ++i) {
          TfIntegralAt<scalar> const to = tf_integral_at<scalar>(ptf, fs.value_at(fs.lambda(i + 1 == pieces ? e : a + float(i + 1) * d)));
          PieceColor<scalar> const pc = piece_between<scalar>(from, to, d);
          from = to;
          float const ad = pc.a;
          if (!(ad > 0.f)) continue;  // transparent
          glm::vec3 c(pc.r, pc.g, pc.b);
          if (shade) {
            float g[3];
            fs.gradient_at(fs.lambda(a + (float(i) + 0.5f) * d), g);
            shade_color(p.shading, s.inv_gradient_full, g, dir, c.r, c.g, c.b);
          }
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

/// One march step as integrate_march composites it, per lane: the piece
/// [a, e] of the cell segment [t_in, t_out] not integrated yet, whether to
/// integrate it (`go`), and the field (and, when shading, its gradient)
/// along the segment as cubics in lambda = (t - t_in) / (t_out - t_in):
/// integrate_segments' FieldSegment (CellOps::segment_field).
template <class A> struct MarchPiece {
  vfloat<A> a, e, t_in, t_out;
  vmask<A> go;
  isa_detail::Cubic<A> f, g[3];
};

/// Fills `pc` from a step of a one-type march (`g` only when shading: the
/// piece is reused from step to step, and nothing else reads it).
template <class A, int N>
void march_piece(RayBatch<A> const& ray, typename CellMarch<A, N>::Step const& st, vmask<A> const& go, bool shade,
                 MarchPiece<A>& pc) {
  pc.a = st.a, pc.e = st.e, pc.t_in = st.k.t_in, pc.t_out = st.k.t_out, pc.go = go;
  vfloat<A> const zero(0.f);
  if constexpr (CellOps<A, N>::linear_on_ray) {
    pc.f = {st.k.s_in, st.k.s_out - st.k.s_in, zero, zero};
    if (shade) {  // the step's constant gradient
      pc.g[0] = {st.gradient.x, zero, zero, zero};
      pc.g[1] = {st.gradient.y, zero, zero, zero};
      pc.g[2] = {st.gradient.z, zero, zero, zero};
    }
  } else if constexpr (N == 8) {
    // Hexahedra: CellOps<A, 8>::segment_field's arithmetic, copied: through
    // it hex DVR measured 5-13% slower (GCC 12, AVX-512), with or without
    // forced inlining; the cause was not found (docs/performance.md).
    // Folded tets (their clip's field is linear) get a line instead.
    vmask<A> const folded = go && st.k.linear, trilinear = go && !st.k.linear;
    if (CELLRAY_LIKELY(simd::any(trilinear))) {
      Vec3<A> u1, u2;
      vfloat<A> const v1 = CellOps<A, 8>::field_on_ray(ray, st.c(), st.k, trilinear, 1.f / 3.f, u1);
      vfloat<A> const v2 = CellOps<A, 8>::field_on_ray(ray, st.c(), st.k, trilinear, 2.f / 3.f, u2);
      pc.f = isa_detail::cubic_through<A>(st.k.s_in, v1, v2, st.k.s_out);
      if (shade) {
        Vec3<A> const g0 = isa_detail::hex_world_gradient(st.c(), st.k.u_in), g1 = isa_detail::hex_world_gradient(st.c(), u1);
        Vec3<A> const g2 = isa_detail::hex_world_gradient(st.c(), u2), g3 = isa_detail::hex_world_gradient(st.c(), st.k.u_out);
        pc.g[0] = isa_detail::cubic_through<A>(g0.x, g1.x, g2.x, g3.x);
        pc.g[1] = isa_detail::cubic_through<A>(g0.y, g1.y, g2.y, g3.y);
        pc.g[2] = isa_detail::cubic_through<A>(g0.z, g1.z, g2.z, g3.z);
      }
    }
    if (CELLRAY_UNLIKELY(simd::any(folded))) CellOps<A, 8>::folded_tet_field(st.c(), st.k, folded, pc.f, shade ? pc.g : nullptr);
  } else {
    CellOps<A, N>::segment_field(ray, st.c(), st.k, go, pc.f, shade ? pc.g : nullptr);
  }
}

/// One step of a one-type march: the lanes of `has` move one cell;
/// `open` are the lanes still gathering opacity. Forced inline, with
/// CellMarch::step and gather_corners: GCC inlined them into the hex march
/// only while the unit stayed small, and an unrelated change elsewhere
/// (the cell-type visits) made it outline them: boxturb48 DVR 0.92x.
template <class A, int N>
CELLRAY_FORCE_INLINE void march_step(CellMarch<A, N>& m, RayBatch<A> const& ray, vmask<A> const& has,
                                     vmask<A> const& open, bool shade, MarchPiece<A>& pc) {
  typename CellMarch<A, N>::Step const st = m.step(has, shade);
  pc.go = st.visible && open;
  if (simd::any(pc.go)) march_piece<A, N>(ray, st, pc.go, shade, pc);
}

/// One step of a mixed march: each part's lanes with its own field, merged.
template <class A>
void march_step(MixedMarch<A>& m, RayBatch<A> const& ray, vmask<A> const& has, vmask<A> const& open, bool shade,
                MarchPiece<A>& pc) {
  typename MixedMarch<A>::Step const st = m.step(has, shade);
  vmask<A> const go_tet = st.in_tet && st.tet.visible && open, go_hex = st.in_hex && st.hex.visible && open;
  pc.go = go_tet || go_hex;
  if (simd::none(go_hex)) {
    if (simd::any(go_tet)) march_piece<A, 4>(ray, st.tet, go_tet, shade, pc);
    return;
  }
  if (simd::none(go_tet)) {
    march_piece<A, 8>(ray, st.hex, go_hex, shade, pc);
    return;
  }
  MarchPiece<A> h;
  march_piece<A, 8>(ray, st.hex, go_hex, shade, h);
  march_piece<A, 4>(ray, st.tet, go_tet, shade, pc);
  auto pick = [&](vfloat<A>& x, vfloat<A> const& y) { x = simd::select(go_hex, y, x); };
  auto pick_cubic = [&](isa_detail::Cubic<A>& x, isa_detail::Cubic<A> const& y) {
    pick(x.c0, y.c0), pick(x.c1, y.c1), pick(x.c2, y.c2), pick(x.c3, y.c3);
  };
  pick(pc.a, h.a), pick(pc.e, h.e), pick(pc.t_in, h.t_in), pick(pc.t_out, h.t_out);
  pick_cubic(pc.f, h.f);
  if (shade)
    for (int k = 0; k < 3; ++k) pick_cubic(pc.g[k], h.g[k]);
  pc.go = go_tet || go_hex;
}

/// Cell-segment DVR by marching (traverse/march.hpp): the same segments as
/// integrate_segments, the same pieces (at most `step` long, each over the
/// transfer function between its end values), the same field along a segment and
/// the same compositing, but one cell per lane per step, integrated across
/// the lanes in SIMD as it is found. `March`: a CellMarch (one part with
/// face neighbours) or a MixedMarch (a tet and a hexahedral part, linked),
/// set up over [t_enter, t_exit]. Not inlined: inside dvr_packet, GCC left
/// shade_batch out of line (shaded tet DVR 4-5% slower). One copy per
/// `shade` (integrate_march picks it): with the flag a constant, the
/// unshaded march drops what only shading reads (a step's corner positions
/// after its clip, the gradient cubics): DVR 1.01-1.03x, docs/performance.md.
template <class A, class March, bool shade>
CELLRAY_NOINLINE void integrate_march_as(PreparedScene const& s, March& m, RayPacket<A> const& r,
                                         vmask<A> const& inside, vfloat<A> const& t_exit, DvrParams const& p,
                                         Traversal how, int threshold, vfloat<A>& cr, vfloat<A>& cg, vfloat<A>& cb,
                                         vfloat<A>& ca, float depth_at, vfloat<A>& depth) {
  PreparedTf const& ptf = *s.tf;
  vfloat<A> const zero(0.f), one(1.f), half(0.5f), term(p.termination), inv_step(1.f / s.step);
  RayBatch<A> const ray = ray_batch(r);
  // The transfer function's integrals at the end of each lane's last piece,
  // at t = carry_t (NaN: none): a step that starts there, as a march through
  // face neighbours does, starts from them instead of looking them up again
  // (the onward clip's entry value is the last exit value, bit for bit).
  TfIntegralAt<A> carry;
  vfloat<A> carry_t(std::numeric_limits<float>::quiet_NaN());
  // The pieces of one step's segments [t_in, t_out] past a, up to e; the
  // field f(lambda) and, when shading, the gradient at lambda.
  auto composite = [&](vmask<A> const& go, vfloat<A> const& a, vfloat<A> const& e, vfloat<A> const& t_in,
                       vfloat<A> const& t_out, isa_detail::Cubic<A> const& f, auto const& gradient_at) {
    vfloat<A> const len = e - a;
    vfloat<A> const pieces = simd::max(one, simd::ceil(len * inv_step));
    vfloat<A> const d = len / pieces;
    vfloat<A> const seg_len = t_out - t_in;
    vmask<A> const long_enough = seg_len > zero;
    vfloat<A> const inv_len = one / simd::select(long_enough, seg_len, one);
    auto lambda = [&](vfloat<A> const& t) { return simd::select(long_enough, (t - t_in) * inv_len, zero); };
    TfIntegralAt<A> from = simd::any(go && !(a == carry_t)) ? tf_integral_at<A>(ptf, f(lambda(a))) : carry;
    vfloat<A> piece(0.f);
    for (vmask<A> on = go; simd::any(on); piece = piece + one, on = on && piece < pieces && ca < term) {
      vfloat<A> const tm = a + (piece + half) * d;
      vfloat<A> const next = piece + one;
      TfIntegralAt<A> const to = tf_integral_at<A>(ptf, f(lambda(simd::select(next < pieces, a + next * d, e))));
      PieceColor<A> c = piece_between<A>(from, to, d);  // as integrate_pieces
      from = to;
      if (shade) {
        Vec3<A> const g = gradient_at(lambda(tm));
        shade_batch<A>(p.shading, s.inv_gradient_full, g.x, g.y, g.z, r, c.r, c.g, c.b);
      }
      vfloat<A> const w = simd::select(on, simd::min((one - ca) * c.a, term - ca), zero);  // exact termination
      cr = cr + w * c.r, cg = cg + w * c.g, cb = cb + w * c.b;
      depth = simd::select(ca < vfloat<A>(depth_at) && ca + w >= vfloat<A>(depth_at), tm, depth);
      ca = ca + w;
    }
    // A lane's last `to` was taken at e (later rounds look up e again).
    carry = from, carry_t = simd::select(go, e, vfloat<A>(std::numeric_limits<float>::quiet_NaN()));
  };
  MarchPiece<A> pc;  // hexahedra and mixed: written by each step where it goes on (`go`)
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
      carry_t = vfloat<A>(std::numeric_limits<float>::quiet_NaN());  // a located cell's field may differ there
      continue;
    }
    if constexpr (March::linear_on_ray) {
      // Straight from the step: a line and a constant gradient (tets through
      // MarchPiece: shaded DVR was 4% slower).
      typename March::Step const st = m.step(has, shade);
      vmask<A> const go = st.visible && ca < term;
      if (simd::any(go))
        composite(go, st.a, st.e, st.k.t_in, st.k.t_out, {st.k.s_in, st.k.s_out - st.k.s_in, zero, zero},
                  [&](vfloat<A> const&) { return st.gradient; });
    } else {
      march_step(m, ray, has, ca < term, shade, pc);
      if (simd::any(pc.go))
        composite(pc.go, pc.a, pc.e, pc.t_in, pc.t_out, pc.f,
                  [&](vfloat<A> const& lam) { return Vec3<A>{pc.g[0](lam), pc.g[1](lam), pc.g[2](lam)}; });
    }
    live = live && ca < term && m.t < t_exit;
  }
}

template <class A, class March>
inline void integrate_march(PreparedScene const& s, March& m, RayPacket<A> const& r, vmask<A> const& inside,
                            vfloat<A> const& t_exit, DvrParams const& p, Traversal how, int threshold, vfloat<A>& cr,
                            vfloat<A>& cg, vfloat<A>& cb, vfloat<A>& ca, float depth_at, vfloat<A>& depth) {
  if (p.shading.enabled)
    integrate_march_as<A, March, true>(s, m, r, inside, t_exit, p, how, threshold, cr, cg, cb, ca, depth_at, depth);
  else
    integrate_march_as<A, March, false>(s, m, r, inside, t_exit, p, how, threshold, cr, cg, cb, ca, depth_at, depth);
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
      part.visit([&](auto const& mesh, auto const*) {
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
      });
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

}  // namespace impl
}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
