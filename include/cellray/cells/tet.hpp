#pragma once
// Tetrahedron kernels, float SIMD, one lane per ray or point (Rathke 2015
// §6.4, §7, Fig. 5, Fig. 8). Scalar double oracle: cells/reference.hpp.
//
// Face model: the plane through the face's three corners, taken in ascending
// global vertex id order (CellCorners<A,4> from the loaders is sorted). Two
// tets sharing a face thus compute the same plane normal, the same ray
// parameter t and the same value at the crossing bit for bit: the exit of
// one cell is the entry of the next, with no gap, no overlap, and no iso
// crossing lost or counted twice (see iso_root_tet).
//
// Where this stops: a ray through an edge or a vertex leaves one cell
// through one plane and enters the next through another (or crosses cells
// that touch it only there, with an interval of rounding length). Each plane
// is consistent between its two cells, but the planes through one edge do
// not meet in exactly one float line, so intervals there may overlap or miss
// by ~1e-7 (relative) and a crossing of an isovalue equal to the edge/vertex
// value may be missed or reported by several cells at the same t. Rates are
// measured in tests/test_cells_watertight.cpp and docs/failure_modes.md; a
// ray never passes exactly through an edge in practice, so renders do not
// show it. Removing it would take per-edge (Pluecker) side tests evaluated
// once per canonically oriented edge and a topological face walk.

#include <limits>

#include "cell_ops.hpp"
#include "corners.hpp"
#include "queries.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

/// The interval [t_in, t_out] of a ray's line inside a cell and the field
/// values at its ends. `hit` only when t_in < t_out (a ray that touches a
/// vertex, an edge, or a zero-volume cell has no interval). Values in lanes
/// without a hit are unspecified. `s_in`/`s_out` are interpolated on the
/// crossed face from that face's corners only, so neighbours agree exactly.
template <class A> struct CellClip {
  vfloat<A> t_in, t_out;
  vfloat<A> s_in, s_out;
  vmask<A> hit;
};

/// Point location result. `inside`: the point belongs to the cell (face ties
/// resolved so that a point on a shared face belongs to exactly one of the
/// two cells, see locate_tet / locate_hex). `value`: the interpolated field
/// (NaN when a corner value is NaN; meaningful only where inside).
/// `converged`: false only when hexahedron Newton inversion hit its iteration
/// cap (always true for tets). `param`: tet barycentric weights of stored
/// corners 1, 2, 3; hex trilinear coordinates (u, v, w) in [0,1]^3.
template <class A> struct Located {
  vmask<A> inside;
  vmask<A> converged;
  vfloat<A> value;
  Vec3<A> param;
};

/// The nearest isosurface crossing in a cell: ray parameter, index into the
/// caller's isovalue list, and a mask. Lanes without a hit have t = +inf and
/// index -1. A hit never has a NaN t.
template <class A> struct CellIsoHit {
  vfloat<A> t;
  vint<A> iso_index;
  vmask<A> hit;
};

namespace isa_detail {

/// Faces of a tet as corner triples in ascending stored order, and the
/// corner opposite each.
inline constexpr int tet_faces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};

/// One face plane: its first corner, normal (b-a)x(c-a) from the canonical
/// order, and side = dot(n, opposite - a): its sign says on which side of the
/// plane the cell lies; |side| = 6 x volume.
template <class A> struct TetFace {
  Vec3<A> a, e1, e2, n;
  vfloat<A> side;
};

template <class A> inline TetFace<A> tet_face(CellCorners<A, 4> const& c, int f) {
  TetFace<A> F;
  F.a = c.p(tet_faces[f][0]);
  F.e1 = c.p(tet_faces[f][1]) - F.a;
  F.e2 = c.p(tet_faces[f][2]) - F.a;
  F.n = cross(F.e1, F.e2);
  F.side = dot(F.n, c.p(f) - F.a);
  return F;
}

/// Where the line o + t d crosses a triangle's plane at t: barycentric
/// coordinates beta, gamma of corners b = a + e1 and c = a + e2 (n = e1 x
/// e2). Shared by every kernel that crosses a triangle (a tet's faces, a
/// wedge's ends, a pyramid's sides) so that, with the corners in ascending
/// id order, the cells on both sides of a triangle get the same bits.
template <class A> struct TriangleCrossing {
  vfloat<A> beta, gamma;
  /// The linear interpolant of the corner values sa, sb, sc.
  vfloat<A> value(vfloat<A> const& sa, vfloat<A> const& sb, vfloat<A> const& sc) const {
    return sa + beta * (sb - sa) + gamma * (sc - sa);
  }
};

template <class A>
CELLRAY_FORCE_INLINE TriangleCrossing<A> triangle_crossing(Vec3<A> const& o, Vec3<A> const& d, vfloat<A> const& t,
                                                           Vec3<A> const& a, Vec3<A> const& e1, Vec3<A> const& e2,
                                                           Vec3<A> const& n) {
  Vec3<A> const rel = (o + t * d) - a;
  vfloat<A> const nn = dot(n, n);
  return {dot(cross(rel, e2), n) / nn, dot(cross(e1, rel), n) / nn};
}

/// a xor b, as !(a == b): xsimd 8.1's own mask xor and != are each wrong on
/// one ISA (AVX-512's `^` ors the mask registers; SSE's `!=` compares the
/// masks as floats, where all-ones is a NaN), its == is right on all three.
/// Forced inline: GCC 12 had kept the and/or form out of line in
/// add_triangle_faces.
template <class A> CELLRAY_FORCE_INLINE vmask<A> mask_xor(vmask<A> const& a, vmask<A> const& b) { return !(a == b); }

template <class A> inline vfloat<A> clamp01(vfloat<A> const& x) {
  return simd::min(simd::max(x, vfloat<A>(0.f)), vfloat<A>(1.f));  // NaN -> 0
}

/// Neubauer et al. 2002 as in Rathke 2015 Fig. 5: `steps` rounds of linear
/// interpolation between bracket ends, keeping the end whose sign differs.
/// `f(t)` returns value - iso; f0, f1 are its values at t0, t1 and differ in
/// sign (f >= 0 counts as above). The result lies in [t0, t1].
template <class A, class F>
inline vfloat<A> neubauer(F const& f, vfloat<A> t0, vfloat<A> t1, vfloat<A> f0, vfloat<A> f1, int steps) {
  auto interp = [&]() {
    vfloat<A> const den = f1 - f0;
    vfloat<A> const lam = clamp01<A>(simd::select(den == vfloat<A>(0.f), vfloat<A>(0.5f), -f0 / den));
    return t0 + lam * (t1 - t0);
  };
  for (int i = 0; i < steps; ++i) {
    vfloat<A> const t = interp();
    vfloat<A> const v = f(t);
    vmask<A> const same = !mask_xor<A>(v >= vfloat<A>(0.f), f0 >= vfloat<A>(0.f));
    t0 = simd::select(same, t, t0);
    f0 = simd::select(same, v, f0);
    t1 = simd::select(same, t1, t);
    f1 = simd::select(same, f1, v);
  }
  return interp();
}

/// Keeps, per lane, the nearer of `h` and the crossing (found, t) of
/// isovalue number `index`; a tie keeps `h` (the lower index when isovalues
/// are tried in order).
template <class A> inline void keep_nearest(CellIsoHit<A>& h, vmask<A> const& found, vfloat<A> const& t, int index) {
  vmask<A> const better = found && t < h.t;
  h.t = simd::select(better, t, h.t);
  h.iso_index = simd::select(simd::to_int_mask(better), vint<A>(index), h.iso_index);
  h.hit = h.hit || better;
}

/// The nearest crossing over `count` isovalues shared by all lanes (ties:
/// lower index). `root(iso, found)` returns the crossing's t for isovalue
/// `iso` (a batch of one value) and sets `found` in the lanes that have one;
/// it may return anything when no lane has.
template <class A, class Root> inline CellIsoHit<A> nearest_crossing(float const* isovalues, int count, Root const& root) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  CellIsoHit<A> h{vfloat<A>(inf), vint<A>(-1), simd::no_lanes<A>()};
  for (int k = 0; k < count; ++k) {
    vmask<A> found = simd::no_lanes<A>();
    vfloat<A> const t = root(vfloat<A>(isovalues[k]), found);
    if (simd::any(found)) keep_nearest<A>(h, found, t, k);
  }
  return h;
}

/// Neubauer's method (see neubauer) on a clip interval for every isovalue,
/// shared by tets and hexes: a crossing exists where exactly one end value
/// is >= iso (the half-open rule of iso_root_tet), then `steps` rounds on
/// `value(lam, lanes)`, the field at t_in + lam (t_out - t_in), lam in [0,1],
/// needed in `lanes` only.
template <class A, class Value>
inline CellIsoHit<A> neubauer_crossings(CellClip<A> const& clip, vmask<A> const& valid, float const* isovalues,
                                        int count, int steps, Value const& value) {
  return nearest_crossing<A>(isovalues, count, [&](vfloat<A> const& iso, vmask<A>& cross) {
    cross = valid && mask_xor<A>(clip.s_in >= iso, clip.s_out >= iso);
    if (simd::none(cross)) return iso;
    auto f = [&](vfloat<A> const& lam) { return value(lam, cross) - iso; };
    vfloat<A> const lam = neubauer<A>(f, vfloat<A>(0.f), vfloat<A>(1.f), clip.s_in - iso, clip.s_out - iso, steps);
    return clip.t_in + lam * (clip.t_out - clip.t_in);
  });
}

}  // namespace isa_detail

/// What clip_tet_window takes from a tet's corners and the rays' origins
/// alone, apart from the directions: each face's plane normal turned into
/// the cell and, per face, num = dot(n_in, a - o) for its first corner a.
/// Packets from one camera share their origin: a group of them computes this
/// once per cell (tet_window_setup with a broadcast origin) and each clips
/// with it (clip_tet_set), with the bits clip_tet_window would get.
template <class A> struct TetWindowSetup {
  Vec3<A> n_in[4];
  vfloat<A> num[4];
  vfloat<A> in_sign;  ///< +1 where the cell lies on the side the stored normal n[3] points to
  vmask<A> oriented;  ///< non-zero volume
};

template <class A>
CELLRAY_FORCE_INLINE TetWindowSetup<A> tet_window_setup(CellCorners<A, 4> const& c, Vec3<A> const& o) {
  vfloat<A> const zero(0.f);
  Vec3<A> const p[4] = {c.p(0), c.p(1), c.p(2), c.p(3)};
  // Face f = the corners other than f, in ascending stored order
  // (isa_detail::tet_faces): edges from its first corner and normal e1 x e2.
  Vec3<A> const e01 = p[1] - p[0], e02 = p[2] - p[0], e03 = p[3] - p[0];
  Vec3<A> const n[4] = {cross(p[2] - p[1], p[3] - p[1]), cross(e02, e03), cross(e01, e03), cross(e01, e02)};
  // 6 x signed volume. The cell lies on the side n[3] points to when it is
  // positive; faces 1 and 3 share that orientation, 0 and 2 are reversed
  // (odd permutations of the corners), so one sign orients all four planes
  // into the cell. Turning a normal (times +-1) is exact, so both cells of a
  // shared face get the same |num| and |den| bits, hence the same t.
  vfloat<A> const det = dot(n[3], e03);
  vmask<A> const pos = det > zero;
  TetWindowSetup<A> s;
  s.oriented = pos || det < zero;
  s.in_sign = simd::select(pos, vfloat<A>(1.f), vfloat<A>(-1.f));
  for (int f = 0; f < 4; ++f) {
    s.n_in[f] = ((f & 1) ? s.in_sign : -s.in_sign) * n[f];
    s.num[f] = dot(s.n_in[f], p[isa_detail::tet_faces[f][0]] - o);
  }
  return s;
}

/// clip_tet_window from its setup (tet_window_setup for these rays' origin).
template <class A>
CELLRAY_FORCE_INLINE CellClip<A> clip_tet_set(RayBatch<A> const& ray, CellCorners<A, 4> const& c,
                                              TetWindowSetup<A> const& s, vmask<A> const& lanes,
                                              vfloat<A> const& t_lo, vfloat<A> const& t_hi,
                                              vint<A>* exit_face = nullptr) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  vfloat<A> const zero(0.f);
  Vec3<A> const d = ray.dir();
  vmask<A> ok = lanes && s.oriented;
  CellClip<A> r;
  r.t_in = vfloat<A>(-inf), r.t_out = vfloat<A>(inf);
  vfloat<A> t[4];
  vmask<A> new_in[4], new_out[4];
  for (int f = 0; f < 4; ++f) {
    // With the normal pointing into the cell: entering is den > 0, leaving
    // den < 0, origin inside the plane num <= 0.
    vfloat<A> const den = dot(s.n_in[f], d);
    t[f] = s.num[f] / den;
    // Parallel to the plane (den == 0 exactly) and outside it: no interval.
    ok = ok && simd::select(den == zero, s.num[f], zero) <= zero;
    new_in[f] = den > zero && t[f] > r.t_in;
    new_out[f] = den < zero && t[f] < r.t_out;
    r.t_in = simd::select(new_in[f], t[f], r.t_in);
    r.t_out = simd::select(new_out[f], t[f], r.t_out);
    if (exit_face) *exit_face = simd::select(simd::to_int_mask(new_out[f]), vint<A>(f), *exit_face);
  }
  r.hit = ok && r.t_in < r.t_out && r.t_out >= t_lo && r.t_in <= t_hi;
  r.s_in = zero, r.s_out = zero;
  if (simd::none(r.hit)) return r;
  // The face each lane finally enters (leaves) through: the last one that
  // raised t_in (lowered t_out).
  Vec3<A> const o = ray.origin();
  vmask<A> in_taken = !r.hit, out_taken = !r.hit;
  for (int f = 3; f >= 0; --f) {
    vmask<A> const is_in = new_in[f] && !in_taken, is_out = new_out[f] && !out_taken;
    in_taken = in_taken || new_in[f], out_taken = out_taken || new_out[f];
    if (simd::none(is_in || is_out)) continue;
    // The value where the line crosses the plane, from this face's corners
    // only, with the face's own stored normal (the crossing's weights are
    // in its orientation).
    int const* fc = isa_detail::tet_faces[f];
    Vec3<A> const a = c.p(fc[0]), e1 = c.p(fc[1]) - a, e2 = c.p(fc[2]) - a;
    Vec3<A> const n = ((f & 1) ? s.in_sign : -s.in_sign) * s.n_in[f];
    isa_detail::TriangleCrossing<A> const x = isa_detail::triangle_crossing<A>(o, d, t[f], a, e1, e2, n);
    vfloat<A> const v = x.value(c.s[fc[0]], c.s[fc[1]], c.s[fc[2]]);
    r.s_in = simd::select(is_in, v, r.s_in);
    r.s_out = simd::select(is_out, v, r.s_out);
  }
  return r;
}

/// clip_tet for the lanes in `lanes` whose interval meets [t_lo, t_hi]
/// (per lane): `hit` = the line crosses the cell && lanes && t_out >= t_lo &&
/// t_in <= t_hi; t_in, t_out, s_in, s_out are meaningful in hit lanes only.
/// Four planes (paper Fig. 5, first loop): entry is the largest t of the
/// planes the ray enters through, exit the smallest t of those it leaves
/// through; a ray parallel to a face plane (dot(n, dir) == 0 exactly) misses
/// when its origin lies outside that plane. The interval is on the full
/// line (t may be negative). Zero-volume tets never hit. No NaN reaches
/// t_in/t_out of a hit lane.
///
/// Cost (the hottest code of both renderers): each face's normal and
/// distance from the origin are set up once (tet_window_setup, shared by a
/// group of packets from one origin); the cell's orientation is one
/// determinant; the face-value interpolation, which recomputes its face's
/// two edges, runs only for faces some hit lane enters or leaves through,
/// and not at all when every lane misses (most cells a packet reaches in a
/// BVH leaf).
///
/// `exit_face` (optional): the face each hit lane leaves through, as an
/// index f into the corners (the face opposite corner f; on a tie at an
/// edge or vertex, the lowest such f), for marching to the neighbour across
/// it (mesh/neighbours.hpp). Unspecified in lanes without a hit.
template <class A>
inline CellClip<A> clip_tet_window(RayBatch<A> const& ray, CellCorners<A, 4> const& c, vmask<A> const& lanes,
                                   vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face = nullptr) {
  return clip_tet_set(ray, c, tet_window_setup(c, ray.origin()), lanes, t_lo, t_hi, exit_face);
}

/// A march's clip of the tet a lane entered through face `entry` (the face
/// opposite corner `entry`) at t_in with value s_in, both carried from the
/// last cell's exit: only the exit is found, with Plücker tests (Marmitt and
/// Slusallek 2006). Per edge i < j of the corners, pi_ij = d . ((p_i - e) x
/// (p_j - e)), the side of the edge the line passes, taken about the entry
/// point e = o + t_in d: about the ray's origin, products of distances to
/// the camera cancel, and a boundary layer's thin cells seen from afar got
/// exit values 1e-3 of the range off. The line crosses face (i, j, k)
/// where pi_jk, -pi_ik and pi_ij share a sign, at barycentric weights
/// proportional to them: the exit t and value then need one division,
/// where clip_tet_window's four planes and two face crossings take eight.
/// `exit_face` gets the crossed face other than `entry`; where the test
/// passes on several (the line through an edge or corner) the crossing
/// furthest along the line. `hit` is false where none passes (a line that
/// only touches the cell, or a flat tet): the march then asks the tree.
/// t_out may lie before t_in after rounding; the march checks progress.
/// `inv_dd` = 1 / (d . d).
template <class A>
CELLRAY_FORCE_INLINE CellClip<A> clip_tet_onward(RayBatch<A> const& ray, CellCorners<A, 4> const& c,
                                                 vmask<A> const& lanes, vint<A> const& entry, vfloat<A> const& t_in,
                                                 vfloat<A> const& s_in, vfloat<A> const& inv_dd, vint<A>& exit_face) {
  vfloat<A> const zero(0.f);
  Vec3<A> const d = ray.dir();
  Vec3<A> const e = ray.origin() + t_in * d;
  Vec3<A> q[4], m[4];
  vfloat<A> along[4];  // (p_i - e) . d: t - t_in of corner i's projection onto the line, times d . d
  for (int i = 0; i < 4; ++i) {
    q[i] = c.p(i) - e;
    m[i] = cross(d, q[i]);
    along[i] = dot(q[i], d);
  }
  // d . (q_i x q_j) = (d x q_i) . q_j
  vfloat<A> const p01 = dot(m[0], q[1]), p02 = dot(m[0], q[2]), p03 = dot(m[0], q[3]);
  vfloat<A> const p12 = dot(m[1], q[2]), p13 = dot(m[1], q[3]), p23 = dot(m[2], q[3]);
  // Face f's corner weights (corner f's is 0).
  vfloat<A> const w[4][4] = {{zero, p23, -p13, p12}, {p23, zero, -p03, p02}, {p13, -p03, zero, p01}, {p12, -p02, p01, zero}};
  vmaski<A> take[4];
  vfloat<A> face_sum[4];
  vint<A> crossings(0);
  for (int f = 0; f < 4; ++f) {
    vfloat<A> lo = w[f][f == 0 ? 1 : 0], hi = lo, sum = zero;
    for (int i = 0; i < 4; ++i)
      if (i != f) lo = simd::min(lo, w[f][i]), hi = simd::max(hi, w[f][i]), sum = sum + w[f][i];
    // One sign, and not all zero (a line in the face's plane) nor NaN.
    vmask<A> const crossed = (lo >= zero && sum > zero) || (hi <= zero && sum < zero);
    take[f] = simd::to_int_mask(crossed) && !(entry == vint<A>(f));
    face_sum[f] = sum;
    crossings = crossings + simd::select(take[f], vint<A>(1), vint<A>(0));
  }
  // A line through an edge or a corner of the cell (some products zero)
  // passes the test on every face that meets there: the exit is then the
  // crossing furthest along the line. Else the one crossed face.
  vmaski<A> const several = crossings > vint<A>(1);
  if (CELLRAY_UNLIKELY(simd::any(simd::to_float_mask(several)))) {
    vfloat<A> best(-std::numeric_limits<float>::infinity());
    vmaski<A> const none = simd::to_int_mask(simd::no_lanes<A>());
    vmaski<A> kept[4] = {none, none, none, none};
    for (int f = 0; f < 4; ++f) {
      vfloat<A> const t_f =
          ((w[f][0] * along[0] + w[f][1] * along[1]) + (w[f][2] * along[2] + w[f][3] * along[3])) / face_sum[f];
      vmaski<A> const further = take[f] && simd::to_int_mask(t_f > best);
      best = simd::select(simd::to_float_mask(further), t_f, best);
      for (int g = 0; g < f; ++g) kept[g] = kept[g] && !further;
      kept[f] = further;
    }
    for (int f = 0; f < 4; ++f) take[f] = (several && kept[f]) || (!several && take[f]);
  }
  vmaski<A> chosen_any = simd::to_int_mask(simd::no_lanes<A>());
  vfloat<A> wc[4] = {zero, zero, zero, zero};
  vint<A> face(0);
  for (int f = 3; f >= 0; --f) {  // one face per lane now; the lowest on a tie in t
    vmask<A> const tf = simd::to_float_mask(take[f]);
    for (int i = 0; i < 4; ++i) wc[i] = simd::select(tf, w[f][i], wc[i]);
    face = simd::select(take[f], vint<A>(f), face);
    chosen_any = chosen_any || take[f];
  }
  vfloat<A> const sum = (wc[0] + wc[1]) + (wc[2] + wc[3]);
  vmask<A> const found = lanes && simd::to_float_mask(chosen_any);
  vfloat<A> const inv = vfloat<A>(1.f) / simd::select(found, sum, vfloat<A>(1.f));
  CellClip<A> r;
  r.t_in = t_in, r.s_in = s_in;
  r.t_out = t_in + ((wc[0] * along[0] + wc[1] * along[1]) + (wc[2] * along[2] + wc[3] * along[3])) * (inv * inv_dd);
  // The face's own corners only: a NaN at the corner off it stays out.
  vfloat<A> sv[4];
  for (int i = 0; i < 4; ++i) sv[i] = simd::select(simd::to_float_mask(face == vint<A>(i)), zero, c.s[i]);
  r.s_out = ((wc[0] * sv[0] + wc[1] * sv[1]) + (wc[2] * sv[2] + wc[3] * sv[3])) * inv;
  r.hit = found;
  exit_face = face;
  return r;
}

/// Ray clip against one tet per lane (see clip_tet_window, with every lane
/// and the whole line).
template <class A> inline CellClip<A> clip_tet(RayBatch<A> const& ray, CellCorners<A, 4> const& c) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  return clip_tet_window(ray, c, simd::all_lanes<A>(), vfloat<A>(-inf), vfloat<A>(inf));
}

/// The tet's linear interpolant at `p`, extrapolated outside the cell.
/// Returns value; `inside` gets the containment mask (see locate_tet).
template <class A>
CELLRAY_FORCE_INLINE vfloat<A> interpolate_tet(CellCorners<A, 4> const& c, Vec3<A> const& p, vmask<A>* inside = nullptr,
                                 Vec3<A>* weights123 = nullptr) {
  vfloat<A> const zero(0.f);
  vfloat<A> value = zero;
  vmask<A> in = simd::all_lanes<A>();
  vfloat<A> w[4];
  for (int f = 0; f < 4; ++f) {
    isa_detail::TetFace<A> const F = isa_detail::tet_face(c, f);
    vfloat<A> const dist = dot(F.n, p - F.a);
    vmask<A> const pos = F.side > zero;
    vmask<A> const neg = F.side < zero;
    // Half-open: a point exactly on the plane belongs to the cell on the
    // positive side of the canonical normal, so exactly one of two neighbours.
    in = in && ((pos && dist >= zero) || (neg && dist < zero));
    w[f] = dist / F.side;
    value = value + w[f] * c.s[f];
  }
  if (inside) *inside = in;
  if (weights123) *weights123 = {w[1], w[2], w[3]};
  return value;
}

/// Point containment and linear interpolation (barycentric, paper Fig. 8).
/// A point on a face shared by two tets belongs to exactly one of them (the
/// one on the positive side of the face's canonical normal); zero-volume tets
/// contain nothing. Only near edges and vertices can rounding of the four
/// independent plane tests still assign a point to zero or two cells
/// (measured in tests/test_cells_watertight.cpp).
template <class A> inline Located<A> locate_tet(PointBatch<A> const& pts, CellCorners<A, 4> const& c) {
  Located<A> r;
  r.value = interpolate_tet(c, pts.p(), &r.inside, &r.param);
  r.converged = simd::all_lanes<A>();
  return r;
}

/// Analytic gradient of the tet's linear field (constant in the cell): the
/// solution of e_0k . g = s_k - s_0 (k = 1, 2, 3, e_0k = p_k - p_0), i.e.
/// g = (ds1 (e02 x e03) + ds2 (e03 x e01) + ds3 (e01 x e02)) / det with
/// det = e01 . (e02 x e03). Value differences first: the corner values of a
/// real field share a large offset (a temperature of ~400 varying by ~1 in a
/// cell), which the form sum s_i grad(lambda_i) would cancel in float. One
/// division; the cross products are the clip's face normals 1..3 (same
/// corner order), so a caller that clipped the cell recomputes nothing new.
/// Zero for a zero-volume tet; NaN when a corner value is NaN.
template <class A> inline Vec3<A> gradient_tet(CellCorners<A, 4> const& c) {
  vfloat<A> const zero(0.f);
  Vec3<A> const p0 = c.p(0);
  Vec3<A> const e01 = c.p(1) - p0, e02 = c.p(2) - p0, e03 = c.p(3) - p0;
  Vec3<A> const n1 = cross(e02, e03), n2 = cross(e01, e03), n3 = cross(e01, e02);
  vfloat<A> const det = dot(n3, e03);
  vfloat<A> const ds1 = c.s[1] - c.s[0], ds2 = c.s[2] - c.s[0], ds3 = c.s[3] - c.s[0];
  Vec3<A> const num = ds1 * n1 - ds2 * n2 + ds3 * n3;
  vmask<A> const ok = !(det == zero);
  return select<A>(ok, (vfloat<A>(1.f) / simd::select(ok, det, vfloat<A>(1.f))) * num, Vec3<A>{zero, zero, zero});
}

/// Central differences of the tet's interpolant around `p` with step `h`
/// (world units): the paper's shading normal source (§6.4). For a linear
/// field it equals gradient_tet up to rounding; it exists so both methods
/// can be compared on equal terms with hexes.
template <class A> inline Vec3<A> gradient_central_tet(CellCorners<A, 4> const& c, Vec3<A> const& p, float h) {
  vfloat<A> const hv(h), zero(0.f), inv(0.5f / h);
  auto diff = [&](Vec3<A> const& e) {
    return (interpolate_tet(c, p + e) - interpolate_tet(c, p - e)) * inv;
  };
  return {diff({hv, zero, zero}), diff({zero, hv, zero}), diff({zero, zero, hv})};
}

/// Exact isosurface root: the field is linear along the ray inside a tet, so
/// the crossing of `isovalues[k]` is the linear interpolation between the
/// clip's end values. A crossing exists when exactly one end value is
/// >= iso (half-open, so along a ray through several cells each crossing is
/// counted in exactly one cell, also when iso equals a vertex or face value).
/// Constant cells and cells with a NaN corner value never hit. Several
/// isovalues (all lanes share the list): the nearest crossing wins, ties go
/// to the lower index.
template <class A>
inline CellIsoHit<A> iso_root_tet(CellClip<A> const& clip, CellCorners<A, 4> const& c, float const* isovalues, int count) {
  vmask<A> const valid = clip.hit && !has_nan_value(c);
  return isa_detail::nearest_crossing<A>(isovalues, count, [&](vfloat<A> const& iso, vmask<A>& cross) {
    cross = valid && isa_detail::mask_xor<A>(clip.s_in >= iso, clip.s_out >= iso);
    vfloat<A> const lam = isa_detail::clamp01<A>((iso - clip.s_in) / (clip.s_out - clip.s_in));
    return clip.t_in + lam * (clip.t_out - clip.t_in);
  });
}

/// Neubauer's method with `steps` rounds (the paper uses 2) on the tet's
/// interpolant along the ray. Same hit rule as iso_root_tet (endpoint signs);
/// for the linear tet field it returns the same root up to rounding.
template <class A>
inline CellIsoHit<A> iso_root_tet_neubauer(RayBatch<A> const& ray, CellClip<A> const& clip, CellCorners<A, 4> const& c,
                                           float const* isovalues, int count, int steps) {
  Vec3<A> const o = ray.origin(), d = ray.dir();
  vfloat<A> const dt = clip.t_out - clip.t_in;
  return isa_detail::neubauer_crossings<A>(clip, clip.hit && !has_nan_value(c), isovalues, count, steps,
                                       [&](vfloat<A> const& lam, vmask<A> const&) {
                                         return interpolate_tet(c, o + (clip.t_in + lam * dt) * d);
                                       });
}

/// What the traversals call for tetrahedra (cells/cell_ops.hpp).
template <class A> struct CellOps<A, 4> {
  using Clip = CellClip<A>;
  /// The field is linear along a ray: a clip's end values bound it on the
  /// segment and give it anywhere on it (no point location).
  static constexpr bool linear_on_ray = true;
  /// A hit or located point has no cell coordinates worth keeping.
  static constexpr bool keeps_param = false;
  /// Another type's cells that are tets in disguise (see CellOps<A, 8>): none.
  static constexpr bool holds_folded_tets = false;
  /// Packets from one origin (a camera's) clip a cell from one setup: its
  /// face normals and their distances from the origin.
  static constexpr bool shares_window_setup = true;
  /// march_clip_window is clip_window: a march's locate may share the setup.
  static constexpr bool march_clips_window = true;
  using WindowSetup = TetWindowSetup<A>;
  static WindowSetup window_setup(CellCorners<A, 4> const& c, Vec3<A> const& origin) {
    return tet_window_setup(c, origin);
  }
  static Clip clip_window_set(RayBatch<A> const& r, CellCorners<A, 4> const& c, WindowSetup const& s,
                              vmask<A> const& lanes, vfloat<A> const& t_lo, vfloat<A> const& t_hi) {
    return clip_tet_set(r, c, s, lanes, t_lo, t_hi);
  }
  static Clip clip(RayBatch<A> const& r, CellCorners<A, 4> const& c) { return clip_tet(r, c); }
  /// The clip narrowed to [t_lo, t_hi]; `exit_face`, if given, receives the
  /// face (mesh face order, FaceNeighbours') the ray leaves through.
  static Clip clip_window(RayBatch<A> const& r, CellCorners<A, 4> const& c, vmask<A> const& lanes,
                          vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face = nullptr) {
    return clip_tet_window(r, c, lanes, t_lo, t_hi, exit_face);
  }
  /// A march's clip (CellMarch::step): clip_window.
  static Clip march_clip_window(RayBatch<A> const& r, CellCorners<A, 4> const& c, vmask<A> const& lanes,
                                vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face) {
    return clip_window(r, c, lanes, t_lo, t_hi, exit_face);
  }
  /// A march's next cell shares a face's corners with the last one: the
  /// march gathers only the one it does not share (CellMarch::next_corners)
  /// and clips onward from the face it entered through.
  static constexpr bool march_reuses_corners = true;
  CELLRAY_FORCE_INLINE static Clip march_clip_onward(RayBatch<A> const& r, CellCorners<A, 4> const& c, vmask<A> const& lanes,
                                vint<A> const& entry, vfloat<A> const& t_in, vfloat<A> const& s_in,
                                vfloat<A> const& inv_dd, vint<A>& exit_face) {
    return clip_tet_onward(r, c, lanes, entry, t_in, s_in, inv_dd, exit_face);
  }
  /// Grouped occlusion queries clip (cell, ray) pairs, W per kernel call,
  /// instead of each cell against every packet that meets it: a tet's clip
  /// is cheap against its broadcast (TetPairs in occlusion.hpp, tets only).
  static constexpr bool occlusion_in_pairs = true;
  /// `param` is for hexes (hit coordinates); tets leave it alone.
  /// `t_from` is for hexes too: a tet holds one crossing per isovalue.
  static CellIsoHit<A> iso(RayBatch<A> const& r, Clip const& k, CellCorners<A, 4> const& c, float const* isos,
                           int count, CellIsoOptions const& o, Vec3<A>* /*param*/ = nullptr,
                           vfloat<A> const* /*t_from*/ = nullptr) {
    return o.method == CellIsoMethod::exact ? iso_root_tet(k, c, isos, count)
                                            : iso_root_tet_neubauer(r, k, c, isos, count, o.neubauer_steps);
  }
  static Located<A> locate(PointBatch<A> const& p, CellCorners<A, 4> const& c) { return locate_tet(p, c); }
  static Located<A> locate(PointBatch<A> const& p, CellCorners<A, 4> const& c, vmask<A> const& /*lanes*/) {
    return locate_tet(p, c);
  }
  /// Lanes that `locate` left outside by at most `tol` in the cell's own
  /// coordinates, with a finite value: a probe's fallback where rounding put
  /// a point on a shared edge or vertex outside every cell (probe.hpp).
  /// Comparisons, not a min: a flat tet's NaN weights must fail.
  static vmask<A> nearly_inside(Located<A> const& loc, float tol) {
    Vec3<A> const& w = loc.param;
    vfloat<A> const w0 = vfloat<A>(1.f) - (w.x + w.y + w.z), t(-tol);
    return w0 >= t && w.x >= t && w.y >= t && w.z >= t &&
           simd::abs(loc.value) <= vfloat<A>(std::numeric_limits<float>::max());
  }
  static Vec3<A> gradient(CellCorners<A, 4> const& c, Vec3<A> const& p, GradientMethod m, float h) {
    return m != GradientMethod::central ? gradient_tet(c) : gradient_central_tet(c, p, h);
  }
  /// The analytic gradient at a point of the cell given by its coordinates
  /// (keeps_param; a tet's is one per cell and ignores them).
  static Vec3<A> gradient_at(CellCorners<A, 4> const& c, Vec3<A> const& /*param*/) { return gradient_tet(c); }
  /// The shape functions at a located point's coordinates (locate's param:
  /// barycentric 1 to 3), one per corner in the located corners' order.
  static void shape_weights(Vec3<A> const& param, vfloat<A> (&w)[4]) {
    w[1] = param.x, w[2] = param.y, w[3] = param.z;
    w[0] = vfloat<A>(1.f) - w[1] - w[2] - w[3];
  }
  /// The field on the clip's segment as a cubic in lambda = (t - t_in) /
  /// (t_out - t_in) (here the line between its end values) and, if `g` is
  /// given, its world-space gradient as three (here the cell's constant one).
  static void segment_field(RayBatch<A> const& /*r*/, CellCorners<A, 4> const& c, Clip const& k,
                            vmask<A> const& /*lanes*/, isa_detail::Cubic<A>& f, isa_detail::Cubic<A>* g) {
    vfloat<A> const zero(0.f);
    f = {k.s_in, k.s_out - k.s_in, zero, zero};
    if (g) {
      Vec3<A> const d = gradient_tet(c);
      g[0] = {d.x, zero, zero, zero}, g[1] = {d.y, zero, zero, zero}, g[2] = {d.z, zero, zero, zero};
    }
  }
};

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
