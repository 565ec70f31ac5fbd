#pragma once
// Hexahedron kernels, float SIMD, one lane per ray or point (Rathke 2015
// §6.4, §7, Fig. 5). Trilinear field over VTK node order; scalar double
// oracle in cells/reference.hpp.
//
// Face model: bilinear patches. The boundary of the trilinear map restricted
// to a face *is* the bilinear patch through the face's four corners, so ray
// clipping against patches agrees with point containment by trilinear
// inversion (u, v, w in [0,1]) without any split of non-planar quads. Each
// patch is evaluated from its corners in a canonical order (start at the
// lowest global vertex id, continue towards the lower of its two neighbours),
// so two hexes sharing a face compute the same ray parameter, patch
// coordinates and value bit for bit. A face with three distinct corners (a
// wedge's end or a pyramid's side, read as a collapsed hex) is crossed as a
// tet crosses its faces instead, the plane through its corners in ascending
// id order (add_triangle_faces): the bits then agree with any cell across it,
// whichever vertex that cell repeats, and with a tet; a face collapsed to an
// edge or a point is skipped. A ray meeting a patch more than twice in total
// (non-convex hex with strongly curved faces) gets the hull of its
// crossings as one interval: that hull covers part of the neighbour across
// the curved face, where both cells then report (a clip overlap, and an iso
// crossing there seen twice; 2 of 60 face rays on the generated hexes with
// jitter 0.3, none on disk_out_ref, see tests/test_cells_watertight.cpp).
// Rays through edges and vertices: as for tets (tet.hpp), several patches
// meet there, so crossings exactly at an edge/vertex value can be missed or
// seen by several cells.
//
// "Exact" iso roots for general hexes: the field along a world-space ray is a
// cubic in t only when the hex is a parallelepiped (affine map); in general it
// is not a polynomial. The method takes the cubic through the field's values
// on the ray at t_in, t_in + dt/3, t_in + 2dt/3, t_out (ends: the clip's
// canonical face values; interior: trilinear inversions warm-started on the
// parametric segment between entry and exit), which is the exact field for
// parallelepipeds. Its first root is isolated by splitting at the cubic's
// extrema (Marmitt et al. 2004) and polished by a safeguarded Newton
// iteration; then `refine_steps` world-space Newton steps on
// value(o + t d) - iso (inversion at each step) move it onto the real ray's
// root inside the same bracket. Accuracy and miss rates against the double
// reference (dense bracketing + bisection) are measured in
// tests/test_cells_hex.cpp.
//
// Fast paths (structured grids stored as hexes are the common case, e.g. a
// DNS box): a face whose canonical corners form a parallelogram is clipped
// as its plane (no quadratic), decided from those corners alone so both
// neighbours take the same path; a parallelepiped hex (affine map) takes the
// cubic through its parametric segment as the exact ray field (no
// inversions, no refinement). Packet leaves (every lane the same cell)
// choose each face's canonical rotation once in scalar code
// (CellCorners::uniform) instead of per lane. Bit identity between
// neighbours and between the packet and SPMD loaders is tested in
// tests/test_cells_hex_affine.cpp. Marches, which need no bit-identical
// faces, clip parallelepipeds as slabs in the cell's own coordinates
// instead (clip_parallelepipeds, CellOps<A, 8>::march_clip_window).

#include <cstdint>
#include <limits>
#include <utility>

#include "tet.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

/// CellClip plus the trilinear coordinates (u, v, w) of the entry and exit
/// points, read off the entry/exit faces (exact, not inverted), and
/// `affine`: every face of the lane's hex is a parallelogram (canonical
/// corners, hex_affine_tolerance), i.e. the hex is a parallelepiped and its
/// trilinear map affine; the iso root then needs no inversions. `linear`:
/// the lane's cell is a tetrahedron stored folded (0 1 2 2 3 3 3 3,
/// fold_tets_into_hexes) and was clipped by the tet kernel (CellOps<A,
/// 8>::clip_window: when every lane's is): its field is linear along the
/// ray, from s_in at t_in to s_out at t_out.
template <class A> struct HexClip : CellClip<A> {
  Vec3<A> u_in, u_out;
  vmask<A> affine;
  vmask<A> linear;
};

/// Containment tolerance in trilinear coordinates: inside means every
/// coordinate in [-tol, 1 + tol]. Positive so that points on shared faces
/// and edges are never lost (no gaps); the price is a band of width about
/// tol x cell size claimed by both neighbours (measured as the double rate).
inline constexpr float hex_inside_tolerance = 1e-5f;
/// Newton inversion: iteration cap and convergence threshold on the step
/// (trilinear coordinates). Float Newton reaches ~1e-7 near a solution, so
/// 1e-5 on the step means the last iterate is already at rounding level.
inline constexpr int hex_newton_cap = 12;
inline constexpr float hex_newton_tol = 1e-5f;
/// The cubic root's Newton iteration (lam in [0,1] across the clip
/// interval) stops once every lane's step is below this: 2^-23, one float
/// spacing just below 1.
inline constexpr float hex_cubic_step_tol = 1.f / (1 << 23);
/// Patch coordinates are accepted in [-tol, 1 + tol]: rounding of the
/// quadratic's roots must not lose a crossing at a patch edge (ray through a
/// hex edge or vertex). Canonical evaluation keeps neighbours consistent.
inline constexpr float hex_patch_tolerance = 6e-5f;

namespace isa_detail {

/// VTK hex faces as cyclic corner lists and corner trilinear coordinates.
inline constexpr int hex_faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                        {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};
inline constexpr float hex_corner_uvw[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                               {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

template <class A> struct PatchCorner {
  Vec3<A> p;
  vfloat<A> s;
  vint<A> id;
  Vec3<A> uvw;
};

template <class A>
CELLRAY_FORCE_INLINE PatchCorner<A> select_corner(vmask<A> const& m, vmaski<A> const& mi, PatchCorner<A> const& a,
                                                  PatchCorner<A> const& b) {
  return {select<A>(m, a.p, b.p), simd::select(m, a.s, b.s), simd::select(mi, a.id, b.id),
          select<A>(m, a.uvw, b.uvw)};
}

/// The face's corner indices (into the cell's corners) in canonical order
/// from scalar ordering keys: the comparisons of canonical_patch's lane
/// path, once per cell (packet leaves broadcast one cell to every lane).
inline void canonical_face_order(int32_t const* key, int f, int order[4]) {
  int const* q = hex_faces[f];
  int32_t const k0 = key[q[0]], k1 = key[q[1]], k2 = key[q[2]], k3 = key[q[3]];
  // Rotate the lowest id to position 0: by 2 if it sits at 2 or 3, then by 1.
  int32_t const lo01 = k1 < k0 ? k1 : k0, lo23 = k3 < k2 ? k3 : k2;
  bool const r2 = lo23 < lo01;
  bool const r1 = r2 ? k3 < k2 : k1 < k0;
  int const shift = (r2 ? 2 : 0) + (r1 ? 1 : 0);
  for (int k = 0; k < 4; ++k) order[k] = q[(k + shift) & 3];
  // Walk towards the lower-id neighbour.
  if (key[order[3]] < key[order[1]]) std::swap(order[1], order[3]);
}

/// The corners of face f in the canonical order `order` (uniform corners).
template <class A>
CELLRAY_FORCE_INLINE void ordered_patch(CellCorners<A, 8> const& c, int const order[4], PatchCorner<A> q[4]) {
  for (int k = 0; k < 4; ++k) {
    int const i = order[k];
    q[k] = {c.p(i), c.s[i], c.id[i],
            {vfloat<A>(hex_corner_uvw[i][0]), vfloat<A>(hex_corner_uvw[i][1]), vfloat<A>(hex_corner_uvw[i][2])}};
  }
}

/// The face's corners in canonical order (see the file comment): decided
/// once in scalar code when the corners are uniform (packet), per lane by
/// selects otherwise. Both give the same corners, bit for bit.
template <class A> CELLRAY_FORCE_INLINE void canonical_patch(CellCorners<A, 8> const& c, int f, PatchCorner<A> q[4]) {
  if (c.uniform) {
    int order[4];
    canonical_face_order(c.uniform_key, f, order);
    ordered_patch<A>(c, order, q);
    return;
  }
  for (int k = 0; k < 4; ++k) {
    int const i = hex_faces[f][k];
    q[k] = {c.p(i), c.s[i], c.id[i],
            {vfloat<A>(hex_corner_uvw[i][0]), vfloat<A>(hex_corner_uvw[i][1]), vfloat<A>(hex_corner_uvw[i][2])}};
  }
  // Rotate the lowest id to position 0: by 2 if it sits at 2 or 3, then by 1.
  vint<A> const lo01 = simd::select(q[1].id < q[0].id, q[1].id, q[0].id);
  vint<A> const lo23 = simd::select(q[3].id < q[2].id, q[3].id, q[2].id);
  vmaski<A> const r2i = lo23 < lo01;
  vmaski<A> const r1i = (r2i && (q[3].id < q[2].id)) || (!r2i && (q[1].id < q[0].id));
  vmask<A> const r2 = simd::to_float_mask(r2i), r1 = simd::to_float_mask(r1i);
  PatchCorner<A> t[4];
  for (int k = 0; k < 4; ++k) t[k] = select_corner<A>(r2, r2i, q[(k + 2) & 3], q[k]);
  for (int k = 0; k < 4; ++k) q[k] = select_corner<A>(r1, r1i, t[(k + 1) & 3], t[k]);
  // Walk towards the lower-id neighbour.
  vmaski<A> const flipi = q[3].id < q[1].id;
  vmask<A> const flip = simd::to_float_mask(flipi);
  PatchCorner<A> const q1 = q[1];
  q[1] = select_corner<A>(flip, flipi, q[3], q[1]);
  q[3] = select_corner<A>(flip, flipi, q1, q[3]);
}

/// Running hull of patch crossings; `face_out` the face (hex_faces index)
/// of the crossing that set t_out.
template <class A> struct HullAcc {
  vfloat<A> t_in, t_out, s_in, s_out;
  Vec3<A> u_in, u_out;
  vint<A> face_out;
};

/// Relative tolerance under which a face counts as a parallelogram (and a
/// hex whose faces all do as a parallelepiped): the length of the defect
/// (q1 - q0) - (q2 - q3) at most this times the length of (e10, e00), i.e.
/// within a few float roundings of the corner coordinates (an affine image
/// of a grid, rounded to float).
inline constexpr float hex_affine_tolerance = 1.f / (1 << 20);

/// The value and trilinear coordinates at patch coordinates (u, v) of a
/// face: bilinear in its canonical corners (bit-identical in both cells).
template <class A>
CELLRAY_FORCE_INLINE void face_point(PatchCorner<A> const q[4], vfloat<A> const& u, vfloat<A> const& v, vfloat<A>& s,
                                     Vec3<A>& uvw) {
  s = lerp<A>(lerp<A>(q[0].s, q[1].s, u), lerp<A>(q[3].s, q[2].s, u), v);
  // The face is a unit square in (u, v, w): its bilinear map is affine.
  uvw = q[0].uvw + u * (q[1].uvw - q[0].uvw) + v * (q[3].uvw - q[0].uvw);
}

/// Records a face crossing at ray parameter t with value s and trilinear
/// coordinates uvw in the lanes `ok` into the hull.
template <class A>
CELLRAY_FORCE_INLINE void hull_add(vmask<A> const& ok, vfloat<A> const& t, vfloat<A> const& s, Vec3<A> const& uvw,
                                   int face, HullAcc<A>& acc) {
  vmask<A> const new_in = ok && t < acc.t_in;
  vmask<A> const new_out = ok && t > acc.t_out;
  acc.t_in = simd::select(new_in, t, acc.t_in);
  acc.s_in = simd::select(new_in, s, acc.s_in);
  acc.u_in = select<A>(new_in, uvw, acc.u_in);
  acc.t_out = simd::select(new_out, t, acc.t_out);
  acc.s_out = simd::select(new_out, s, acc.s_out);
  acc.u_out = select<A>(new_out, uvw, acc.u_out);
  acc.face_out = simd::select(simd::to_int_mask(new_out), vint<A>(face), acc.face_out);
}

/// Records a patch crossing at ray parameter t, patch coordinates (u, v) in
/// the lanes `ok` into the hull.
template <class A>
CELLRAY_FORCE_INLINE void hull_add(PatchCorner<A> const q[4], vmask<A> const& ok, vfloat<A> const& t,
                                   vfloat<A> const& u, vfloat<A> const& v, int face, HullAcc<A>& acc) {
  vfloat<A> s;
  Vec3<A> uvw;
  face_point<A>(q, u, v, s, uvw);
  hull_add<A>(ok, t, s, uvw, face, acc);
}

/// What a face of a collapsed hex is, per lane, from which cycle
/// neighbours share an id: `triangle` when exactly one pair does (three
/// distinct corners: a wedge's end, a pyramid's side; three equal pairs
/// imply the fourth, so "exactly one" is their parity), `collapsed` when
/// two opposite pairs do (an edge or a point: a wedge's folded side, a
/// pyramid's top), which no ray crosses through an area.
template <class A> struct FaceKind {
  vmask<A> triangle, collapsed;
};

template <class A> CELLRAY_FORCE_INLINE FaceKind<A> face_kind(CellCorners<A, 8> const& c, int f) {
  int const* q = hex_faces[f];
  auto const eq = [&](int a, int b) { return simd::to_float_mask(c.id[q[a]] == c.id[q[b]]); };
  vmask<A> const e01 = eq(0, 1), e12 = eq(1, 2), e23 = eq(2, 3), e30 = eq(3, 0);
  return {mask_xor<A>(mask_xor<A>(e01, e12), mask_xor<A>(e23, e30)), (e01 && e23) || (e12 && e30)};
}

/// One face's crossing per lane, for the hull (hull_add).
template <class A> struct FaceHit {
  vmask<A> ok;
  vfloat<A> t, s;
  Vec3<A> uvw;
};

/// The crossing of a triangular face. The triangle is crossed
/// as a tet crosses its faces (triangle_crossing; `r`: its corners in
/// ascending id order), not as a bilinear patch with two equal corners:
/// which corner a cell repeats depends on how the cell is listed, so the
/// patches of one triangle differ between its two cells, while the sorted
/// triangle is the same in both and in a tet across it. The crossing's
/// (u, v, w) is then the cell's own: on the face cycle d d' y z with d = d'
/// (corner coordinates `u`), the face map is (1-b) d + b ((1-a) z + a y), so
/// b = lambda_y + lambda_z, a = lambda_y / b (any a at the apex b = 0, where
/// d and d' are one point). `weights_yz(w, wy, wz)` picks lambda_y and
/// lambda_z from the sorted corners' weights w.
template <class A, class WeightsYZ>
CELLRAY_FORCE_INLINE FaceHit<A> triangle_hit(RayBatch<A> const& ray, Vec3<A> const r[3], vfloat<A> const rs[3],
                                             Vec3<A> const u[4], vmask<A> const& lanes, WeightsYZ const& weights_yz) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  vfloat<A> const zero(0.f), one(1.f), lo(-hex_patch_tolerance), hi(1.f + hex_patch_tolerance);
  Vec3<A> const o = ray.origin(), d = ray.dir();
  Vec3<A> const e1 = r[1] - r[0], e2 = r[2] - r[0];
  Vec3<A> const n = cross(e1, e2);
  vfloat<A> const t = dot(n, r[0] - o) / dot(n, d);
  TriangleCrossing<A> const x = triangle_crossing<A>(o, d, t, r[0], e1, e2, n);
  // A ray in the plane gives t = +-inf or NaN, a collinear triangle NaN.
  vmask<A> const ok = lanes && simd::abs(t) < vfloat<A>(inf) && x.beta >= lo && x.gamma >= lo && x.beta + x.gamma <= hi;
  if (simd::none(ok)) return {ok, t, zero, {zero, zero, zero}};
  vfloat<A> const w[3] = {one - x.beta - x.gamma, x.beta, x.gamma};
  vfloat<A> wy, wz;
  weights_yz(w, wy, wz);
  vfloat<A> const b = wy + wz;
  vfloat<A> const a = simd::select(b > vfloat<A>(1e-6f), simd::min(simd::max(wy / b, zero), one), vfloat<A>(0.5f));
  return {ok, t, x.value(rs[0], rs[1], rs[2]), lerp<A>(lerp<A>(u[0], u[1], a), lerp<A>(u[3], u[2], a), b)};
}

template <class A> inline Vec3<A> corner_uvw(int i) {
  return {vfloat<A>(hex_corner_uvw[i][0]), vfloat<A>(hex_corner_uvw[i][1]), vfloat<A>(hex_corner_uvw[i][2])};
}

/// Swaps corners a and b in the lanes where b's id is the lower.
template <class A> CELLRAY_FORCE_INLINE void order_by_id(PatchCorner<A>& a, PatchCorner<A>& b) {
  vmaski<A> const mi = b.id < a.id;
  vmask<A> const m = simd::to_float_mask(mi);
  PatchCorner<A> const a0 = a;
  a = select_corner<A>(m, mi, b, a);
  b = select_corner<A>(m, mi, a0, b);
}

/// The crossing of face f of the lanes `tri`, a triangle in every one of
/// them (see face_kind), whose corners may differ between lanes: the
/// repeated pair found per lane by selects unless every lane has it at the
/// same place (a batch of one kind of cell, as the readers store them: a
/// pyramid's sides, a wedge's ends), the id order per lane by selects.
template <class A>
CELLRAY_FORCE_INLINE FaceHit<A> lane_triangle_hit(RayBatch<A> const& ray, CellCorners<A, 8> const& cell, int f,
                                                  vmask<A> const& tri) {
  // The face's cycle as the cell lists it (uniform_triangle_hit's), turned
  // so that its repeated pair comes first: d d' y z.
  PatchCorner<A> q[4];
  vmaski<A> at[4];
  for (int k = 0; k < 4; ++k) {
    int const i = hex_faces[f][k], next = hex_faces[f][(k + 1) & 3];
    q[k] = {cell.p(i), cell.s[i], cell.id[i], corner_uvw<A>(i)};
    at[k] = cell.id[i] == cell.id[next];
  }
  int shared = -1;
  for (int k = 0; k < 4 && shared < 0; ++k)
    if (simd::all(!tri || simd::to_float_mask(at[k]))) shared = k;
  PatchCorner<A> c[4];
  if (shared >= 0) {
    for (int j = 0; j < 4; ++j) c[j] = q[(shared + j) & 3];
  } else {
    for (int j = 0; j < 4; ++j) c[j] = q[j];
    for (int k = 1; k < 4; ++k) {
      vmask<A> const m = simd::to_float_mask(at[k]);
      for (int j = 0; j < 4; ++j) c[j] = select_corner<A>(m, at[k], q[(k + j) & 3], c[j]);
    }
  }
  // d, y, z in ascending id order (three compare-exchanges).
  PatchCorner<A> r[3] = {c[0], c[2], c[3]};
  order_by_id<A>(r[0], r[1]), order_by_id<A>(r[1], r[2]), order_by_id<A>(r[0], r[1]);
  Vec3<A> const rp[3] = {r[0].p, r[1].p, r[2].p}, u[4] = {c[0].uvw, c[1].uvw, c[2].uvw, c[3].uvw};
  vfloat<A> const rs[3] = {r[0].s, r[1].s, r[2].s};
  auto weights_yz = [&](vfloat<A> const w[3], vfloat<A>& wy, vfloat<A>& wz) {
    auto weight_of = [&](vint<A> const& id) {
      return simd::select(simd::to_float_mask(id == r[0].id), w[0],
                          simd::select(simd::to_float_mask(id == r[1].id), w[1], w[2]));
    };
    wy = weight_of(c[2].id), wz = weight_of(c[3].id);
  };
  return triangle_hit<A>(ray, rp, rs, u, tri, weights_yz);
}

/// The crossing of face f, a triangle with the repeated pair at cycle
/// positions k, k+1, in a cell every lane shares (CellCorners::uniform):
/// the corner order decided once in scalar code, the same bits as
/// lane_triangle_hit.
template <class A>
CELLRAY_FORCE_INLINE FaceHit<A> uniform_triangle_hit(RayBatch<A> const& ray, CellCorners<A, 8> const& cell, int f, int k) {
  int const* q = hex_faces[f];
  int32_t const* key = cell.uniform_key;
  int const cyc[4] = {q[k], q[(k + 1) & 3], q[(k + 2) & 3], q[(k + 3) & 3]};  // d d' y z
  int idx[3] = {cyc[0], cyc[2], cyc[3]};
  auto order = [&](int i, int j) {
    if (key[idx[j]] < key[idx[i]]) std::swap(idx[i], idx[j]);
  };
  order(0, 1), order(1, 2), order(0, 1);
  int const slot_y = idx[0] == cyc[2] ? 0 : idx[1] == cyc[2] ? 1 : 2;
  int const slot_z = idx[0] == cyc[3] ? 0 : idx[1] == cyc[3] ? 1 : 2;
  Vec3<A> const rp[3] = {cell.p(idx[0]), cell.p(idx[1]), cell.p(idx[2])};
  vfloat<A> const rs[3] = {cell.s[idx[0]], cell.s[idx[1]], cell.s[idx[2]]};
  Vec3<A> const u[4] = {corner_uvw<A>(cyc[0]), corner_uvw<A>(cyc[1]), corner_uvw<A>(cyc[2]), corner_uvw<A>(cyc[3])};
  auto weights_yz = [&](vfloat<A> const w[3], vfloat<A>& wy, vfloat<A>& wz) { wy = w[slot_y], wz = w[slot_z]; };
  return triangle_hit<A>(ray, rp, rs, u, simd::all_lanes<A>(), weights_yz);
}

/// What face f of a cell every lane shares is, in scalar code from its
/// ordering keys: 0 four distinct corners (or a b a c, clipped as the patch
/// it is), 1 a triangle, 2 collapsed (see FaceKind); `k` the position of a
/// triangle's repeated pair.
inline int uniform_face_kind(int32_t const* key, int f, int& k) {
  int const* q = hex_faces[f];
  bool e[4];
  for (int j = 0; j < 4; ++j) e[j] = key[q[j]] == key[q[(j + 1) & 3]];
  int const pairs = int(e[0]) + int(e[1]) + int(e[2]) + int(e[3]);
  if (CELLRAY_LIKELY(pairs == 0)) return 0;
  if ((e[0] && e[2]) || (e[1] && e[3])) return 2;
  k = e[0] ? 0 : e[1] ? 1 : e[2] ? 2 : 3;
  return pairs == 1 ? 1 : 0;
}

/// The triangular faces `faces` (bit f: face f is a triangle in some lane)
/// into the hull, after the quadrilaterals: out of line, with the hull by
/// value, so that the common path (hexahedra: no triangles) keeps its
/// accumulator in registers and its unrolled face loop small.
template <class A>
CELLRAY_NOINLINE HullAcc<A> add_triangle_faces(RayBatch<A> const& ray, CellCorners<A, 8> const& c, unsigned faces,
                                               HullAcc<A> acc) {
  for (int f = 0; f < 6; ++f) {
    if (!((faces >> f) & 1u)) continue;
    FaceHit<A> h;
    if (c.uniform) {
      int k = 0;
      uniform_face_kind(c.uniform_key, f, k);
      h = uniform_triangle_hit<A>(ray, c, f, k);
    } else {
      h = lane_triangle_hit<A>(ray, c, f, face_kind<A>(c, f).triangle);
    }
    if (simd::any(h.ok)) hull_add<A>(h.ok, h.t, h.s, h.uvw, f, acc);
  }
  return acc;
}

/// The plane of a face whose canonical corners form a parallelogram:
/// through q0, spanned by e10 = q1 - q0 and e00 = q3 - q0, normal n = e10 x
/// e00.
template <class A> struct FacePlane {
  Vec3<A> e10, e00, n, p00;  ///< p00 = q0 - ray origin
  vmask<A> para;             ///< the face is a parallelogram (hex_affine_tolerance)
  /// Ray parameter of the crossing (+-inf or NaN for rays in the plane's direction).
  vfloat<A> t(Vec3<A> const& d) const { return dot(n, p00) / dot(n, d); }
  /// Patch coordinates of the crossing at t by the dual basis: u = r . (e00
  /// x n) / n.n, v = r . (n x e10) / n.n with r = o + t d - q0.
  void uv(Vec3<A> const& d, vfloat<A> const& t, vfloat<A>& u, vfloat<A>& v) const {
    Vec3<A> const r = t * d - p00;
    vfloat<A> const inv = vfloat<A>(1.f) / dot(n, n);
    u = dot(r, cross(e00, n)) * inv;
    v = dot(r, cross(n, e10)) * inv;
  }
};

/// The face plane of canonical corners q0..q3 (positions) for ray origin o.
template <class A>
CELLRAY_FORCE_INLINE FacePlane<A> face_plane(Vec3<A> const& q0, Vec3<A> const& q1, Vec3<A> const& q2,
                                             Vec3<A> const& q3, Vec3<A> const& o) {
  FacePlane<A> F;
  F.e10 = q1 - q0;
  F.e00 = q3 - q0;
  Vec3<A> const defect = F.e10 - (q2 - q3);
  F.para = dot(defect, defect) <= vfloat<A>(hex_affine_tolerance * hex_affine_tolerance) *
                                      (dot(F.e10, F.e10) + dot(F.e00, F.e00));
  F.n = cross(F.e10, F.e00);
  F.p00 = q0 - o;
  return F;
}

template <class A> CELLRAY_FORCE_INLINE FacePlane<A> face_plane(PatchCorner<A> const q[4], Vec3<A> const& o) {
  return face_plane<A>(q[0].p, q[1].p, q[2].p, q[3].p, o);
}

/// Ray / face intersection on the whole line; every valid crossing updates
/// `acc`; returns the face's parallelogram mask. A face whose canonical
/// corners form a parallelogram (within hex_affine_tolerance: every face of
/// a parallelepiped, e.g. a structured grid) is its plane: one ray/plane
/// crossing (FacePlane). Any other face is the bilinear patch, after
/// Reshetov, "Cool Patches" (Ray Tracing Gems, 2019): a quadratic in u, up
/// to two roots. The choice is a function of the canonical corners only, so
/// the two cells of a shared face take the same path and get the same bits.
///
/// `skip`: lanes whose face is a triangle or collapsed (face_kind), which
/// add_triangle_faces handles or which add nothing.
template <class A>
CELLRAY_FORCE_INLINE vmask<A> patch_hits(RayBatch<A> const& ray, PatchCorner<A> const q[4], int face,
                                         HullAcc<A>& acc, vmask<A> const& skip) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  vfloat<A> const zero(0.f);
  vfloat<A> const lo(-hex_patch_tolerance), hi(1.f + hex_patch_tolerance);
  Vec3<A> const o = ray.origin(), d = ray.dir();
  FacePlane<A> F = face_plane<A>(q, o);
  // Two equal corners are never a parallelogram (and a collapsed face is
  // not affine either: the cell's map is singular there).
  F.para = F.para && !skip;
  vmask<A> const patch = !F.para && !skip;
  if (simd::any(F.para)) {
    vfloat<A> const t = F.t(d);
    vfloat<A> u, v;
    F.uv(d, t, u, v);
    // Parallel rays give t = +-inf or NaN, never a crossing; a zero-area
    // face gives NaN (u, v).
    vmask<A> const ok = F.para && simd::abs(t) < vfloat<A>(inf) && u >= lo && u <= hi && v >= lo && v <= hi;
    if (simd::any(ok)) hull_add<A>(q, ok, t, u, v, face, acc);
    if (simd::none(patch)) return F.para;
  }
  Vec3<A> const e10 = F.e10, e00 = F.e00, e11 = q[2].p - q[1].p, p00 = F.p00;
  Vec3<A> const qn = cross(e10, q[3].p - q[2].p);
  Vec3<A> const p10 = q[1].p - o;
  vfloat<A> const a = dot(cross(p00, d), e00);
  vfloat<A> const cc = dot(qn, d);
  vfloat<A> const b = dot(cross(p10, d), e11) - (a + cc);
  vfloat<A> const disc = b * b - vfloat<A>(4.f) * a * cc;
  vmask<A> const real = patch && disc >= zero;
  vfloat<A> const sq = simd::sqrt(simd::select(real, disc, zero));
  vmask<A> const linear = cc == zero;
  vfloat<A> const qq = vfloat<A>(-0.5f) * (b + simd::select(b >= zero, sq, zero - sq));
  vfloat<A> const ua = simd::select(linear, zero - a / b, qq / cc);
  vfloat<A> const ub = a / qq;
  vmask<A> const valid_b = real && !linear;
  for (int root = 0; root < 2; ++root) {
    vfloat<A> const u = root == 0 ? ua : ub;
    vmask<A> const cand = (root == 0 ? real : valid_b) && u >= lo && u <= hi;
    if (simd::none(cand)) continue;
    Vec3<A> const pa = lerp<A>(p00, p10, u);
    Vec3<A> const pb = lerp<A>(e00, e11, u);
    Vec3<A> n = cross(d, pb);
    vfloat<A> const det = dot(n, n);
    n = cross(n, pa);
    vfloat<A> const t = dot(n, pb) / det;
    vfloat<A> const v = dot(n, d) / det;
    vmask<A> const ok = cand && det > zero && v >= lo && v <= hi;
    if (simd::any(ok)) hull_add<A>(q, ok, t, u, v, face, acc);
  }
  return F.para;
}

template <class A> inline vfloat<A> trilerp(vfloat<A> const* v, Vec3<A> const& u) {
  vfloat<A> const b0 = lerp<A>(lerp<A>(v[0], v[1], u.x), lerp<A>(v[3], v[2], u.x), u.y);
  vfloat<A> const b1 = lerp<A>(lerp<A>(v[4], v[5], u.x), lerp<A>(v[7], v[6], u.x), u.y);
  return lerp<A>(b0, b1, u.z);
}

/// d/du, d/dv, d/dw of a trilinear function with corner values v.
template <class A> inline Vec3<A> trilerp_grad(vfloat<A> const* v, Vec3<A> const& u) {
  vfloat<A> const one(1.f);
  vfloat<A> const mu = one - u.x, mv = one - u.y, mw = one - u.z;
  vfloat<A> const du = mw * (mv * (v[1] - v[0]) + u.y * (v[2] - v[3])) + u.z * (mv * (v[5] - v[4]) + u.y * (v[6] - v[7]));
  vfloat<A> const dv = mw * (mu * (v[3] - v[0]) + u.x * (v[2] - v[1])) + u.z * (mu * (v[7] - v[4]) + u.x * (v[6] - v[5]));
  vfloat<A> const dw = mv * (mu * (v[4] - v[0]) + u.x * (v[5] - v[1])) + u.y * (mu * (v[7] - v[3]) + u.x * (v[6] - v[2]));
  return {du, dv, dw};
}

template <class A> struct Jacobian {
  Vec3<A> ju, jv, jw;  // columns: dx/du, dx/dv, dx/dw
};

template <class A> inline Jacobian<A> hex_jacobian(CellCorners<A, 8> const& c, Vec3<A> const& u) {
  Vec3<A> const gx = trilerp_grad<A>(c.x, u), gy = trilerp_grad<A>(c.y, u), gz = trilerp_grad<A>(c.z, u);
  return {{gx.x, gy.x, gz.x}, {gx.y, gy.y, gz.y}, {gx.z, gy.z, gz.z}};
}

/// Newton inversion of the trilinear map (see locate_hex). Starts from
/// `start` (centre for a cold start), updates lanes in `lanes` only.
template <class A>
inline Vec3<A> invert_hex(CellCorners<A, 8> const& c, Vec3<A> const& p, Vec3<A> u, vmask<A> lanes, int cap,
                          vmask<A>& converged) {
  vfloat<A> const tol(hex_newton_tol), far(3.f), half(0.5f);
  vmask<A> active = lanes;
  converged = simd::no_lanes<A>();
  for (int it = 0; it < cap && simd::any(active); ++it) {
    Vec3<A> const x{trilerp<A>(c.x, u), trilerp<A>(c.y, u), trilerp<A>(c.z, u)};
    Vec3<A> const r = x - p;
    Jacobian<A> const J = hex_jacobian(c, u);
    Vec3<A> const cvw = cross(J.jv, J.jw), cwu = cross(J.jw, J.ju), cuv = cross(J.ju, J.jv);
    vfloat<A> const det = dot(J.ju, cvw);
    vfloat<A> const inv = vfloat<A>(1.f) / det;
    Vec3<A> const step{dot(r, cvw) * inv, dot(r, cwu) * inv, dot(r, cuv) * inv};
    vfloat<A> const size = simd::max(simd::abs(step.x), simd::max(simd::abs(step.y), simd::abs(step.z)));
    vmask<A> const finite = size < vfloat<A>(std::numeric_limits<float>::infinity());  // false for NaN
    u = select<A>(active && finite, u - step, u);
    vmask<A> const done = active && finite && size < tol;
    converged = converged || done;
    // A singular Jacobian, or an iterate far outside [0,1]^3 (the point is far
    // outside the cell), ends the lane: reported not converged, not inside.
    vfloat<A> const dist = simd::max(simd::abs(u.x - half), simd::max(simd::abs(u.y - half), simd::abs(u.z - half)));
    active = active && finite && !done && dist < far;
  }
  return u;
}

template <class A> inline Vec3<A> centre() { return {vfloat<A>(0.5f), vfloat<A>(0.5f), vfloat<A>(0.5f)}; }

/// The lanes whose cell is a pyramid as the readers store it
/// (mesh/vtk_cells.hpp's pyramid_as_hex: base 0 1 2 3, corners 4-7 the
/// apex, five distinct vertices).
template <class A> CELLRAY_FORCE_INLINE vmask<A> pyramid_lanes(CellCorners<A, 8> const& c) {
  if (c.uniform) {
    int32_t const* k = c.uniform_key;
    bool const apex = k[4] == k[5] && k[5] == k[6] && k[6] == k[7];
    bool const base = k[0] != k[1] && k[0] != k[2] && k[0] != k[3] && k[1] != k[2] && k[1] != k[3] && k[2] != k[3];
    bool const apart = k[0] != k[4] && k[1] != k[4] && k[2] != k[4] && k[3] != k[4];
    return apex && base && apart ? simd::all_lanes<A>() : simd::no_lanes<A>();
  }
  vint<A> const* id = c.id;
  return simd::to_float_mask(id[4] == id[5] && id[5] == id[6] && id[6] == id[7] && id[0] != id[1] && id[0] != id[2] &&
                             id[0] != id[3] && id[1] != id[2] && id[1] != id[3] && id[2] != id[3] && id[0] != id[4] &&
                             id[1] != id[4] && id[2] != id[4] && id[3] != id[4]);
}

/// A pyramid (pyramid_lanes) located in closed form. Its trilinear map is
/// x = (1 - w) B(u, v) + w a, B the bilinear base and a the apex, so the
/// line from the apex through p meets the base patch at B(u, v), at
/// a + lambda (p - a) with lambda = 1 / (1 - w): one ray/patch crossing
/// (the quadratic in u of patch_hits, after Reshetov) instead of Newton's
/// 2 to 4 steps, which converge slowly towards the apex. Of the two roots
/// the one with lambda > 0 nearest the base's unit square is taken (of two
/// inside it, the one nearer `guess`). `ok` false where there is none (p
/// at the apex, NaN corners): the caller falls back to invert_hex.
template <class A>
inline Vec3<A> invert_pyramid(CellCorners<A, 8> const& c, Vec3<A> const& p, Vec3<A> const& guess, vmask<A>& ok) {
  vfloat<A> const zero(0.f), one(1.f);
  Vec3<A> const a = c.p(4), d = p - a;
  Vec3<A> const q0 = c.p(0), q1 = c.p(1), q2 = c.p(2), q3 = c.p(3);
  Vec3<A> const e10 = q1 - q0, e00 = q3 - q0, e11 = q2 - q1, p00 = q0 - a, p10 = q1 - a;
  Vec3<A> const qn = cross(e10, q3 - q2);
  vfloat<A> const qa = dot(cross(p00, d), e00);
  vfloat<A> const qc = dot(qn, d);
  vfloat<A> const qb = dot(cross(p10, d), e11) - (qa + qc);
  vfloat<A> const disc = qb * qb - vfloat<A>(4.f) * qa * qc;
  vmask<A> const real = disc >= zero;
  vfloat<A> const sq = simd::sqrt(simd::select(real, disc, zero));
  vmask<A> const linear = qc == zero;
  vfloat<A> const qq = vfloat<A>(-0.5f) * (qb + simd::select(qb >= zero, sq, zero - sq));
  vfloat<A> const roots[2] = {simd::select(linear, zero - qa / qb, qq / qc), qa / qq};
  Vec3<A> best{zero, zero, zero};
  vfloat<A> best_out(std::numeric_limits<float>::infinity()), best_far = best_out;
  ok = simd::no_lanes<A>();
  for (int i = 0; i < 2; ++i) {
    vfloat<A> const u = roots[i];
    Vec3<A> const pa = lerp<A>(p00, p10, u), pb = lerp<A>(e00, e11, u);
    Vec3<A> n = cross(d, pb);
    vfloat<A> const det = dot(n, n);
    n = cross(n, pa);
    vfloat<A> const lambda = dot(n, pb) / det, v = dot(n, d) / det;
    vfloat<A> const w = one - one / lambda;
    vfloat<A> const out = simd::max(simd::max(simd::max(zero - u, u - one), simd::max(zero - v, v - one)), zero);
    vfloat<A> const far = simd::abs(u - guess.x) + simd::abs(v - guess.y) + simd::abs(w - guess.z);
    // Comparisons are false for NaN: a NaN root, v or lambda never wins.
    // Two roots in the base (an inverted pyramid, whose map folds): the one
    // nearer the guess, where Newton would have gone.
    vmask<A> const root = i == 0 ? real : real && !linear;
    vmask<A> const take = root && det > zero && lambda > zero &&
                          lambda < vfloat<A>(std::numeric_limits<float>::infinity()) &&
                          (out < best_out || (out == best_out && far < best_far));
    best = select<A>(take, Vec3<A>{u, v, w}, best);
    best_out = simd::select(take, out, best_out);
    best_far = simd::select(take, far, best_far);
    ok = ok || take;
  }
  return best;
}

/// Whether corners 4-7 are one vertex in some lane of `lanes`: a pyramid's
/// top (or a folded tet's). Three compares for the hexahedra.
template <class A> CELLRAY_FORCE_INLINE bool top_collapsed(CellCorners<A, 8> const& c, vmask<A> const& lanes) {
  if (c.uniform)
    return c.uniform_key[4] == c.uniform_key[5] && c.uniform_key[5] == c.uniform_key[6] &&
           c.uniform_key[6] == c.uniform_key[7];
  return simd::any(lanes && simd::to_float_mask(c.id[4] == c.id[5] && c.id[5] == c.id[6] && c.id[6] == c.id[7]));
}

/// invert_on_ray for lanes some of which may hold pyramids: out of line,
/// so that the hexahedra's path keeps its shape.
template <class A>
CELLRAY_NOINLINE Vec3<A> invert_pyramids_on_ray(CellCorners<A, 8> const& c, Vec3<A> const& p, Vec3<A> const& guess,
                                                vmask<A> const& lanes, int cap, vmask<A>& converged) {
  vmask<A> const pyramids = lanes && pyramid_lanes(c);
  if (simd::none(pyramids)) return invert_hex(c, p, guess, lanes, cap, converged);  // folded tets
  vmask<A> solved;
  Vec3<A> const q = invert_pyramid(c, p, guess, solved);
  solved = solved && pyramids;
  Vec3<A> const u = invert_hex(c, p, guess, lanes && !solved, cap, converged);
  converged = converged || solved;
  return select<A>(solved, q, u);
}

/// invert_hex, with the lanes that hold pyramids (pyramid_lanes) located
/// in closed form (invert_pyramid; converged there), Newton for the rest:
/// the inversions of points on a ray in a cell (iso roots, DVR fields).
template <class A>
CELLRAY_FORCE_INLINE Vec3<A> invert_on_ray(CellCorners<A, 8> const& c, Vec3<A> const& p, Vec3<A> const& guess,
                                           vmask<A> const& lanes, int cap, vmask<A>& converged) {
  if (CELLRAY_LIKELY(!top_collapsed(c, lanes))) return invert_hex(c, p, guess, lanes, cap, converged);
  return invert_pyramids_on_ray(c, p, guess, lanes, cap, converged);
}

/// A wedge as the readers store it (mesh/vtk_cells.hpp's wedge_as_hex:
/// corners 2 = 3 and 6 = 7, the side v = 1 collapsed to an edge) located in
/// VTK's own wedge coordinates: barycentric (r, s) in the end triangles
/// (corners 0 1 2 and 4 5 6) and w between them, x = (1 - w) B(r, s) +
/// w T(r, s). That map is regular up to the collapsed edge, where the
/// trilinear one is singular (u = r / (1 - s), v = s: u is lost at s = 1),
/// so Newton converges there as anywhere. Returns (r, s, w); `converged`
/// as invert_hex.
template <class A>
inline Vec3<A> invert_wedge(CellCorners<A, 8> const& c, Vec3<A> const& p, vmask<A> lanes, int cap, vmask<A>& converged) {
  vfloat<A> const tol(hex_newton_tol), far(3.f), third(1.f / 3.f), half(0.5f);
  Vec3<A> const b0 = c.p(0), b1 = c.p(1) - b0, b2 = c.p(2) - b0;
  Vec3<A> const t0 = c.p(4), t1 = c.p(5) - t0, t2 = c.p(6) - t0;
  Vec3<A> q{third, third, half};  // (r, s, w)
  vmask<A> active = lanes;
  converged = simd::no_lanes<A>();
  for (int it = 0; it < cap && simd::any(active); ++it) {
    Vec3<A> const bottom = b0 + q.x * b1 + q.y * b2, top = t0 + q.x * t1 + q.y * t2;
    vfloat<A> const one_w = vfloat<A>(1.f) - q.z;
    Vec3<A> const r = bottom + q.z * (top - bottom) - p;
    Vec3<A> const jr = one_w * b1 + q.z * t1, js = one_w * b2 + q.z * t2, jw = top - bottom;
    Vec3<A> const csw = cross(js, jw), cwr = cross(jw, jr), crs = cross(jr, js);
    vfloat<A> const inv = vfloat<A>(1.f) / dot(jr, csw);
    Vec3<A> const step{dot(r, csw) * inv, dot(r, cwr) * inv, dot(r, crs) * inv};
    vfloat<A> const size = simd::max(simd::abs(step.x), simd::max(simd::abs(step.y), simd::abs(step.z)));
    vmask<A> const finite = size < vfloat<A>(std::numeric_limits<float>::infinity());  // false for NaN
    q = select<A>(active && finite, q - step, q);
    vmask<A> const done = active && finite && size < tol;
    converged = converged || done;
    vfloat<A> const dist = simd::max(simd::abs(q.x - third), simd::max(simd::abs(q.y - third), simd::abs(q.z - half)));
    active = active && finite && !done && dist < far;
  }
  return q;
}

/// Lanes whose hexahedron has an edge collapsed to a point (two corners of
/// one edge share a vertex): wedges, pyramids, folded tets and the like.
template <class A> inline vmask<A> collapsed_edge(CellCorners<A, 8> const& c) {
  static constexpr int edge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                      {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  auto m = c.id[edge[0][0]] == c.id[edge[0][1]];
  for (int e = 1; e < 12; ++e) m = m || c.id[edge[e][0]] == c.id[edge[e][1]];
  return simd::to_float_mask(m);
}

/// invert_hex for hexahedra with a collapsed edge (collapsed_edge). Their
/// map is singular there, and two things lose points next to it: a
/// direction the collapse leaves undetermined (u along a wedge's collapsed
/// side, u and v at a pyramid's apex) takes steps that fling the iterate
/// past invert_hex's far limit, and the float residual's rounding, divided
/// by the vanishing Jacobian, keeps the step from ever falling below
/// hex_newton_tol (tests/test_traverse_probe.cpp, points made at 0.5 to
/// 0.9999 of the way to the singular side: 82 of 2,160 lost on pyramids,
/// and 102 of 1,145 on wedges before invert_wedge took those). So each step
/// is projected onto [0,1]^3, where a point inside has its solution (a
/// point outside ends held on the cube's surface, not converged), and a
/// lane is also converged when its residual is below 1e-5 of the cell's
/// extent (or the rounding of p's coordinates): the value there is off by
/// as little.
template <class A>
inline Vec3<A> invert_collapsed_hex(CellCorners<A, 8> const& c, Vec3<A> const& p, vmask<A> lanes, int cap,
                                    vmask<A>& converged) {
  vfloat<A> const zero(0.f), one(1.f), half(0.5f), tol(hex_newton_tol);
  auto span = [](vfloat<A> const* v) {
    vfloat<A> lo = v[0], hi = v[0];
    for (int k = 1; k < 8; ++k) lo = simd::min(lo, v[k]), hi = simd::max(hi, v[k]);
    return hi - lo;
  };
  auto largest = [](Vec3<A> const& v) { return simd::max(simd::abs(v.x), simd::max(simd::abs(v.y), simd::abs(v.z))); };
  vfloat<A> const reach =
      simd::max(vfloat<A>(1e-5f) * simd::max(span(c.x), simd::max(span(c.y), span(c.z))), vfloat<A>(4e-7f) * largest(p));
  auto unit = [&](vfloat<A> const& x) { return simd::min(one, simd::max(zero, x)); };
  Vec3<A> u = centre<A>();
  vmask<A> active = lanes;
  converged = simd::no_lanes<A>();
  for (int it = 0; it < cap && simd::any(active); ++it) {
    Vec3<A> const r = Vec3<A>{trilerp<A>(c.x, u), trilerp<A>(c.y, u), trilerp<A>(c.z, u)} - p;
    vmask<A> const close = active && largest(r) <= reach;
    converged = converged || close;
    active = active && !close;
    Jacobian<A> const J = hex_jacobian(c, u);
    Vec3<A> const cvw = cross(J.jv, J.jw), cwu = cross(J.jw, J.ju), cuv = cross(J.ju, J.jv);
    vfloat<A> const inv = one / dot(J.ju, cvw);
    Vec3<A> const step{dot(r, cvw) * inv, dot(r, cwu) * inv, dot(r, cuv) * inv};
    vfloat<A> const size = largest(step);
    vmask<A> const finite = size < vfloat<A>(std::numeric_limits<float>::infinity());  // false for NaN
    // On the singular set itself (an apex): halfway back to the centre.
    Vec3<A> const next = select<A>(finite, Vec3<A>{unit(u.x - step.x), unit(u.y - step.y), unit(u.z - step.z)},
                                   half * (u + centre<A>()));
    vfloat<A> const moved = largest(next - u);
    u = select<A>(active, next, u);
    vmask<A> const done = active && finite && size < tol;
    // Held on the cube's surface by a step out of it: the point is outside
    // (a few iterations, not the cap, for the cells around a probe point).
    vmask<A> const held = active && finite && moved < tol;
    converged = converged || done;
    active = active && !done && !held;
  }
  return u;
}

template <class A> inline vmask<A> in_unit_cube(Vec3<A> const& u, float tol) {
  vfloat<A> const lo(-tol), hi(1.f + tol);
  return u.x >= lo && u.x <= hi && u.y >= lo && u.y <= hi && u.z >= lo && u.z <= hi;
}

/// Gradient of the hex field in world space at trilinear coordinates u:
/// J^-T times the parametric gradient. `ok` false where J is singular.
template <class A> inline Vec3<A> hex_world_gradient(CellCorners<A, 8> const& c, Vec3<A> const& u, vmask<A>* ok = nullptr) {
  Jacobian<A> const J = hex_jacobian(c, u);
  Vec3<A> const ds = trilerp_grad<A>(c.s, u);
  Vec3<A> const cvw = cross(J.jv, J.jw), cwu = cross(J.jw, J.ju), cuv = cross(J.ju, J.jv);
  vfloat<A> const det = dot(J.ju, cvw);
  vmask<A> const good = !(det == vfloat<A>(0.f)) && !simd::isnan(det);
  vfloat<A> const inv = vfloat<A>(1.f) / simd::select(good, det, vfloat<A>(1.f));
  Vec3<A> g = inv * (ds.x * cvw + ds.y * cwu + ds.z * cuv);
  vfloat<A> const zero(0.f);
  if (ok) *ok = good;
  return select<A>(good, g, Vec3<A>{zero, zero, zero});
}

}  // namespace isa_detail

/// The trilinear shape functions at coordinates u clamped to the cell, in
/// VTK corner order: sum of w[i] * v[i] is trilerp(v, u) inside the cell.
template <class A> inline void trilinear_weights(Vec3<A> const& u, vfloat<A> (&w)[8]) {
  vfloat<A> const zero(0.f), one(1.f);
  vfloat<A> const c[3] = {simd::min(simd::max(u.x, zero), one), simd::min(simd::max(u.y, zero), one),
                          simd::min(simd::max(u.z, zero), one)};
  for (int i = 0; i < 8; ++i) {
    vfloat<A> f[3];
    for (int a = 0; a < 3; ++a) f[a] = isa_detail::hex_corner_uvw[i][a] != 0.f ? c[a] : one - c[a];
    w[i] = f[0] * f[1] * f[2];
  }
}

/// Whether hexahedron coordinates lie in the cell within 1e-3 (false for
/// NaN): a root search's coordinates that can stand for a located point.
template <class A> inline vmask<A> hex_param_in_cell(Vec3<A> const& u) {
  vfloat<A> const lo(-1e-3f), hi(1.f + 1e-3f);
  return u.x >= lo && u.x <= hi && u.y >= lo && u.y <= hi && u.z >= lo && u.z <= hi;
}

/// Ray clip against one hex per lane by its six faces (see the file
/// comment) for the lanes in `lanes` whose interval meets [t_lo, t_hi] (per
/// lane): `hit` = the line crosses the cell && lanes && t_out >= t_lo &&
/// t_in <= t_hi; the rest is meaningful in hit lanes only. [t_in, t_out] is
/// the hull of all face crossings on the full line (bilinear patches,
/// parallelogram faces as planes), with the values and trilinear
/// coordinates there. Rays parallel to a planar face meet it at most in its edges
/// and are handled by the other faces. Flat (zero-volume) hexes yield no
/// hit. NaN positions or a miss yield hit == false; hit lanes never carry
/// NaN t. `exit_face`, if given, receives per hit lane the face (hex_faces
/// index) of the crossing at t_out: where a march leaves the cell.
template <class A>
inline HexClip<A> clip_hex_window(RayBatch<A> const& ray, CellCorners<A, 8> const& c, vmask<A> const& lanes,
                                  vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face = nullptr) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  vfloat<A> const zero(0.f);
  isa_detail::HullAcc<A> acc{vfloat<A>(inf), vfloat<A>(-inf), zero, zero, {zero, zero, zero}, {zero, zero, zero}, vint<A>(0)};
  vmask<A> affine = simd::all_lanes<A>();
  unsigned triangles = 0;  // bit f: face f is a triangle in some lane
  // Unrolled, so that each face's corner indices are constants.
#pragma GCC unroll 6
  for (int f = 0; f < 6; ++f) {
    vmask<A> skip = simd::no_lanes<A>();
    if (c.uniform) {
      int k = 0;
      int const kind = isa_detail::uniform_face_kind(c.uniform_key, f, k);
      if (CELLRAY_UNLIKELY(kind != 0)) {
        triangles |= unsigned(kind == 1) << f;
        affine = simd::no_lanes<A>();  // the map is singular on a collapsed face
        continue;
      }
    }
    if (!c.uniform) {
      isa_detail::FaceKind<A> const kind = isa_detail::face_kind<A>(c, f);
      skip = kind.triangle || kind.collapsed;
      if (CELLRAY_UNLIKELY(simd::any(kind.triangle))) triangles |= 1u << f;
      if (CELLRAY_UNLIKELY(simd::all(skip))) {  // a pyramid's sides and top in every lane, say
        affine = simd::no_lanes<A>();
        continue;
      }
    }
    isa_detail::PatchCorner<A> q[4];
    isa_detail::canonical_patch(c, f, q);
    vmask<A> const para = isa_detail::patch_hits(ray, q, f, acc, skip);  // not inside &&: for scalar that short-circuits
    affine = affine && para;
  }
  if (CELLRAY_UNLIKELY(triangles != 0)) acc = isa_detail::add_triangle_faces(ray, c, triangles, acc);
  HexClip<A> r;
  r.t_in = acc.t_in, r.t_out = acc.t_out, r.s_in = acc.s_in, r.s_out = acc.s_out;
  r.u_in = acc.u_in, r.u_out = acc.u_out;
  r.hit = lanes && acc.t_in < acc.t_out && acc.t_out >= t_lo && acc.t_in <= t_hi;
  r.affine = affine;
  r.linear = simd::no_lanes<A>();
  if (exit_face) *exit_face = acc.face_out;
  return r;
}

/// What clip_hex_window takes from a cell whose six faces are all
/// parallelograms (a structured grid's hexahedra) and from the rays'
/// origin, apart from the directions: each face's canonical corner order
/// and plane, with its crossing's dual basis. Packets from one camera
/// share their origin: a group of them computes this once per cell
/// (hex_window_setup with a broadcast origin) and each clips with it
/// (clip_hex_set), with the bits clip_hex_window would get. Cells with a
/// curved, triangular or collapsed face are not `planar`: clip_hex_set
/// then runs clip_hex_window. Uniform corners (a packet leaf's broadcast
/// cell) only; others are not `planar` either.
template <class A> struct HexWindowSetup {
  struct Face {
    int order[4];            ///< canonical corner order (isa_detail::canonical_face_order)
    Vec3<A> n, p00;          ///< normal and first corner - origin (isa_detail::FacePlane)
    Vec3<A> dual_u, dual_v;  ///< cross(e00, n), cross(n, e10): FacePlane::uv's basis
    vfloat<A> num, inv_nn;   ///< dot(n, p00), 1 / dot(n, n)
  };
  bool planar = false;
  Face face[6];
};

template <class A>
inline HexWindowSetup<A> hex_window_setup(CellCorners<A, 8> const& c, Vec3<A> const& o) {
  HexWindowSetup<A> s;
  if (!c.uniform) return s;
  for (int f = 0; f < 6; ++f) {
    int k = 0;
    if (isa_detail::uniform_face_kind(c.uniform_key, f, k) != 0) return s;
    typename HexWindowSetup<A>::Face& F = s.face[f];
    isa_detail::canonical_face_order(c.uniform_key, f, F.order);
    isa_detail::FacePlane<A> const P =
        isa_detail::face_plane<A>(c.p(F.order[0]), c.p(F.order[1]), c.p(F.order[2]), c.p(F.order[3]), o);
    if (!simd::all(P.para)) return s;  // one cell in every lane
    F.n = P.n, F.p00 = P.p00;
    F.dual_u = cross(P.e00, P.n), F.dual_v = cross(P.n, P.e10);
    F.num = dot(P.n, P.p00);
    F.inv_nn = vfloat<A>(1.f) / dot(P.n, P.n);
  }
  s.planar = true;
  return s;
}

/// clip_hex_window from its setup (hex_window_setup for these rays' origin).
template <class A>
inline HexClip<A> clip_hex_set(RayBatch<A> const& ray, CellCorners<A, 8> const& c, HexWindowSetup<A> const& s,
                               vmask<A> const& lanes, vfloat<A> const& t_lo, vfloat<A> const& t_hi) {
  if (!s.planar) return clip_hex_window(ray, c, lanes, t_lo, t_hi);
  constexpr float inf = std::numeric_limits<float>::infinity();
  vfloat<A> const zero(0.f);
  vfloat<A> const lo(-hex_patch_tolerance), hi(1.f + hex_patch_tolerance);
  Vec3<A> const d = ray.dir();
  isa_detail::HullAcc<A> acc{vfloat<A>(inf), vfloat<A>(-inf), zero, zero, {zero, zero, zero}, {zero, zero, zero}, vint<A>(0)};
#pragma GCC unroll 6
  for (int f = 0; f < 6; ++f) {
    // isa_detail::patch_hits' parallelogram path, FacePlane::t and uv.
    typename HexWindowSetup<A>::Face const& F = s.face[f];
    vfloat<A> const t = F.num / dot(F.n, d);
    Vec3<A> const r = t * d - F.p00;
    vfloat<A> const u = dot(r, F.dual_u) * F.inv_nn, v = dot(r, F.dual_v) * F.inv_nn;
    vmask<A> const ok = simd::abs(t) < vfloat<A>(inf) && u >= lo && u <= hi && v >= lo && v <= hi;
    if (simd::any(ok)) {
      isa_detail::PatchCorner<A> q[4];
      isa_detail::ordered_patch<A>(c, F.order, q);
      isa_detail::hull_add<A>(q, ok, t, u, v, f, acc);
    }
  }
  HexClip<A> r;
  r.t_in = acc.t_in, r.t_out = acc.t_out, r.s_in = acc.s_in, r.s_out = acc.s_out;
  r.u_in = acc.u_in, r.u_out = acc.u_out;
  r.hit = lanes && acc.t_in < acc.t_out && acc.t_out >= t_lo && acc.t_in <= t_hi;
  r.affine = simd::all_lanes<A>();
  r.linear = simd::no_lanes<A>();
  return r;
}

/// clip_hex_window with every lane and the whole line.
template <class A> inline HexClip<A> clip_hex(RayBatch<A> const& ray, CellCorners<A, 8> const& c) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  return clip_hex_window(ray, c, simd::all_lanes<A>(), vfloat<A>(-inf), vfloat<A>(inf));
}

namespace isa_detail {
/// The lanes whose hexahedron is a parallelepiped: corners 2, 5, 7 and 6 are
/// where the edges from corner 0 (to 1, 3 and 4) put them, each within
/// hex_affine_tolerance of the edges' length. False for NaN positions and
/// for collapsed cells (wedges, pyramids, folded tets: a repeated corner
/// leaves an edge's length as the defect).
template <class A> CELLRAY_FORCE_INLINE vmask<A> parallelepiped_lanes(CellCorners<A, 8> const& c) {
  Vec3<A> const p0 = c.p(0), e1 = c.p(1) - p0, e2 = c.p(3) - p0, e3 = c.p(4) - p0;
  Vec3<A> const d2 = c.p(2) - p0 - e1 - e2, d5 = c.p(5) - p0 - e1 - e3, d7 = c.p(7) - p0 - e2 - e3;
  Vec3<A> const d6 = c.p(6) - p0 - e1 - e2 - e3;
  vfloat<A> const worst = simd::max(simd::max(dot(d2, d2), dot(d5, d5)), simd::max(dot(d7, d7), dot(d6, d6)));
  vfloat<A> const scale = dot(e1, e1) + dot(e2, e2) + dot(e3, e3);
  return worst <= vfloat<A>(hex_affine_tolerance * hex_affine_tolerance) * scale;
}
}  // namespace isa_detail

/// clip_hex_window for the lanes of `lanes` that hold parallelepipeds
/// (parallelepiped_lanes; other lanes' results mean nothing), as a slab
/// test in the cell's own coordinates:
/// the ray as u(t) = M^-1 (o + t d - p0), M the edges from corner 0, against
/// the unit cube. Trilinear coordinates at entry and exit come from the
/// same line (clamped to the cube), values by trilinear interpolation,
/// `affine` set. The same interval as the six face planes up to rounding
/// (tests/test_cells_hex_affine.cpp), at a fraction of the work: no face is
/// put in canonical order, so a face shared with a neighbour does not give
/// bit-identical crossings. For marches (CellOps::march_clip_window), which
/// go on from where the last cell ended, not for isosurface leaves: there a
/// root at a face two cells round apart can fall in neither interval
/// (docs/performance.md, "Tried and dropped").
template <class A>
inline HexClip<A> clip_parallelepipeds(RayBatch<A> const& ray, CellCorners<A, 8> const& c, vmask<A> const& lanes,
                                       vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face = nullptr) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  vfloat<A> const zero(0.f), one(1.f);
  Vec3<A> const p0 = c.p(0), e1 = c.p(1) - p0, e2 = c.p(3) - p0, e3 = c.p(4) - p0;
  // Dual basis: u = n1 . (x - p0) / det, and so on.
  Vec3<A> const n1 = cross(e2, e3), n2 = cross(e3, e1), n3 = cross(e1, e2);
  vfloat<A> const det = dot(e1, n1);
  vmask<A> const solid = !(det == zero);
  vfloat<A> const inv_det = one / simd::select(solid, det, one);
  Vec3<A> const r0 = ray.origin() - p0, d = ray.dir();
  vfloat<A> const uo[3] = {dot(n1, r0) * inv_det, dot(n2, r0) * inv_det, dot(n3, r0) * inv_det};
  vfloat<A> const ud[3] = {dot(n1, d) * inv_det, dot(n2, d) * inv_det, dot(n3, d) * inv_det};
  // Per axis the slab [0, 1]; a ray in a face's plane (0 / 0) is inside it.
  vfloat<A> near[3], far[3];
  for (int a = 0; a < 3; ++a) {
    vfloat<A> const inv = one / ud[a];
    vfloat<A> const t0 = -uo[a] * inv, t1 = (one - uo[a]) * inv;
    vmask<A> const in_plane = simd::isnan(t0) || simd::isnan(t1);
    near[a] = simd::select(in_plane, vfloat<A>(-inf), simd::min(t0, t1));
    far[a] = simd::select(in_plane, vfloat<A>(inf), simd::max(t0, t1));
  }
  vfloat<A> const t_in = simd::max(simd::max(near[0], near[1]), near[2]);
  vfloat<A> const t_out = simd::min(simd::min(far[0], far[1]), far[2]);
  HexClip<A> r;
  r.t_in = t_in, r.t_out = t_out;
  r.hit = lanes && solid && t_in < t_out && t_out >= t_lo && t_in <= t_hi;
  auto at = [&](vfloat<A> const& t) {
    auto unit = [&](vfloat<A> const& x) { return simd::min(simd::max(x, zero), one); };
    return Vec3<A>{unit(uo[0] + t * ud[0]), unit(uo[1] + t * ud[1]), unit(uo[2] + t * ud[2])};
  };
  r.u_in = at(t_in), r.u_out = at(t_out);
  r.s_in = isa_detail::trilerp<A>(c.s, r.u_in), r.s_out = isa_detail::trilerp<A>(c.s, r.u_out);
  r.affine = r.hit;
  r.linear = simd::no_lanes<A>();
  if (exit_face) {
    // hex_faces: u = 0 / 1 are faces 4 / 5, v = 0 / 1 faces 2 / 3, w = 0 / 1
    // faces 0 / 1; the ray leaves a slab at its far side.
    vint<A> const face_u = simd::select(simd::to_int_mask(ud[0] > zero), vint<A>(5), vint<A>(4));
    vint<A> const face_v = simd::select(simd::to_int_mask(ud[1] > zero), vint<A>(3), vint<A>(2));
    vint<A> const face_w = simd::select(simd::to_int_mask(ud[2] > zero), vint<A>(1), vint<A>(0));
    *exit_face = simd::select(simd::to_int_mask(far[0] == t_out), face_u,
                              simd::select(simd::to_int_mask(far[1] == t_out), face_v, face_w));
  }
  return r;
}

namespace isa_detail {
/// Trilinear coordinates of `p` in a tetrahedron stored as a hexahedron (0 1
/// 2 2 3 3 3 3, fold_tets_into_hexes) whose corners 0, 1, 2 and 4 are at
/// `p0`, `p1`, `p2`, `p4`: barycentric weights l1, l2, l3 of corners 1, 2 and
/// 4 (Cramer), and the trilinear coordinates they are: w = l3,
/// v = l2 / (1 - w), u = l1 / (l0 + l1) (any u, v where the map collapses).
/// `solid`: the tet has volume; `in`: p is inside it (within
/// hex_inside_tolerance).
template <class A>
inline Vec3<A> folded_tet_param(Vec3<A> const& p0, Vec3<A> const& p1, Vec3<A> const& p2, Vec3<A> const& p4,
                                Vec3<A> const& p, vmask<A>& solid, vmask<A>& in) {
  vfloat<A> const zero(0.f), one(1.f), half(0.5f), tol(hex_inside_tolerance);
  Vec3<A> const e1 = p1 - p0, e2 = p2 - p0, e3 = p4 - p0, d = p - p0;
  Vec3<A> const n23 = cross(e2, e3);
  vfloat<A> const det = dot(e1, n23);
  solid = !(det == zero);
  vfloat<A> const inv = one / simd::select(solid, det, one);
  vfloat<A> const l1 = dot(d, n23) * inv, l2 = dot(e1, cross(d, e3)) * inv, l3 = dot(e1, cross(e2, d)) * inv;
  vfloat<A> const l0 = one - l1 - l2 - l3, below = l0 + l1, one_w = one - l3;
  in = solid && l0 >= zero - tol && l1 >= zero - tol && l2 >= zero - tol && l3 >= zero - tol;
  return {simd::select(below > zero, l1 / simd::select(below > zero, below, one), half),
          simd::select(one_w > zero, l2 / simd::select(one_w > zero, one_w, one), half), l3};
}

/// Whether ordering keys `k` are a tetrahedron's stored folded (0 1 2 2 3
/// 3 3 3) with four distinct corners. Keys that are ranks (meshes over 2^31
/// vertices) never match: the hexahedron kernels then take it, as they take
/// any collapsed cell.
inline bool is_folded_tet(int32_t const (&k)[8]) {
  return k[2] == k[3] && k[4] == k[5] && k[5] == k[6] && k[6] == k[7] && k[0] != k[1] && k[0] != k[2] &&
         k[0] != k[4] && k[1] != k[2] && k[1] != k[4] && k[2] != k[4];
}

/// The lanes whose cell is a folded tetrahedron (is_folded_tet's pattern;
/// a folded cell with repeated corners beyond it has no volume, which the
/// tet clip and the hexahedron clip alike never hit).
template <class A> CELLRAY_FORCE_INLINE vmask<A> folded_tet_lanes(CellCorners<A, 8> const& c) {
  if (c.uniform) return is_folded_tet(c.uniform_key) ? simd::all_lanes<A>() : simd::no_lanes<A>();
  return simd::to_float_mask(c.id[2] == c.id[3] && c.id[4] == c.id[5] && c.id[5] == c.id[6] && c.id[6] == c.id[7]);
}

/// A folded tetrahedron's corners, hexahedron corners 0, 1, 2 and 4, as a
/// tet in that order (unsorted).
template <class A> CELLRAY_FORCE_INLINE CellCorners<A, 4> folded_tet_corners(CellCorners<A, 8> const& c) {
  CellCorners<A, 4> t;
  int const from[4] = {0, 1, 2, 4};
  for (int i = 0; i < 4; ++i)
    t.x[i] = c.x[from[i]], t.y[i] = c.y[from[i]], t.z[i] = c.z[from[i]], t.s[i] = c.s[from[i]], t.id[i] = c.id[from[i]];
  return t;
}

/// clip_hex_window for `lanes` that all hold folded tets: the tet clip over
/// corners 0, 1, 2 and 4 in ascending key order, as gather_corners<4>
/// orders a tet (the hexahedron kernels cross a triangle face as the tet
/// does, so t and the values are the same bits, at a quarter of the work),
/// with `linear` set and trilinear coordinates at entry and exit from the
/// barycentric ones; the exit face is the hexahedron face opposite the tet
/// corner the tet clip names. Out of line: the hexahedra's own path stays
/// as it was.
template <class A>
CELLRAY_NOINLINE HexClip<A> clip_folded_tets(RayBatch<A> const& ray, CellCorners<A, 8> const& c, vmask<A> const& lanes,
                                             vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face) {
  HexClip<A> r;
  r.affine = simd::no_lanes<A>();
  r.linear = lanes;
  // Tet corner i is hexahedron corner 0, 1, 2 or 4; the hexahedron face
  // opposite it (hex_faces: 5 = 1 2 6 5, 4 = 0 3 7 4, 2 = 0 1 5 4, 0 = 0 1 2 3).
  CellCorners<A, 4> t = folded_tet_corners(c);
  vint<A> opposite[4] = {vint<A>(5), vint<A>(4), vint<A>(2), vint<A>(0)};
  auto order = [&](int i, int j) {  // sort_tet_corners' network, carrying the faces along
    vmaski<A> const m = t.id[i] > t.id[j];
    vint<A> const lo = simd::select(m, opposite[j], opposite[i]);
    opposite[j] = simd::select(m, opposite[i], opposite[j]);
    opposite[i] = lo;
    swap_corners_if(t, i, j);
  };
  order(0, 1), order(2, 3), order(0, 2), order(1, 3), order(1, 2);
  vint<A> tet_exit(0);
  CellClip<A> const k = clip_tet_window(ray, t, lanes, t_lo, t_hi, exit_face ? &tet_exit : nullptr);
  r.t_in = k.t_in, r.t_out = k.t_out, r.s_in = k.s_in, r.s_out = k.s_out, r.hit = k.hit;
  Vec3<A> const o = ray.origin(), d = ray.dir();
  Vec3<A> const p0 = c.p(0), p1 = c.p(1), p2 = c.p(2), p4 = c.p(4);
  vmask<A> solid, in;
  r.u_in = folded_tet_param(p0, p1, p2, p4, o + k.t_in * d, solid, in);
  r.u_out = folded_tet_param(p0, p1, p2, p4, o + k.t_out * d, solid, in);
  if (exit_face) {
    vint<A> face = opposite[3];
    for (int i = 2; i >= 0; --i) face = simd::select(tet_exit == vint<A>(i), opposite[i], face);
    *exit_face = face;
  }
  return r;
}
}  // namespace isa_detail

/// Point containment and trilinear interpolation by Newton inversion of the
/// trilinear map: start at the cell centre (u = v = w = 1/2: the first step
/// is the inverse of the centre's affine approximation), at most
/// hex_newton_cap iterations, converged when the step is below
/// hex_newton_tol. Inside: converged and every coordinate within
/// hex_inside_tolerance of [0,1]. When the iteration does not converge (cap
/// reached, singular Jacobian of a flat hex, or an iterate more than 2.5 cell
/// widths out: the point is far outside) the lane reports converged = false
/// and inside = false; a caller that must not lose such points falls back to
/// ref::locate (double, multi-start). The non-convergence rate on distorted
/// hexes is measured in tests/test_cells_hex.cpp. `lanes`: the lanes to
/// locate (the others report not converged, not inside): the iteration
/// stops when they are done, not when every lane is (point probes test a
/// cell for the few points inside its box).
///
/// A wedge as the readers store it is located in its own coordinates
/// (invert_wedge); another hexahedron with a collapsed edge (a pyramid)
/// through invert_collapsed_hex (projected onto the cube; converged by the
/// residual too). A tetrahedron stored as a hexahedron (0 1 2 2 3 3 3 3,
/// UnstructuredGrid::fold_tets_into_hexes) is located by its barycentric
/// coordinates:
/// its map is singular along a whole face and an edge, where Newton stalls
/// (0.2% of random points in gmsh's mixed test mesh were lost).
template <class A>
inline Located<A> locate_hex(PointBatch<A> const& pts, CellCorners<A, 8> const& c,
                             vmask<A> const& lanes = simd::all_lanes<A>()) {
  Located<A> r;
  vmask<A> const tet = lanes && simd::to_float_mask(c.id[2] == c.id[3] && c.id[4] == c.id[5] &&
                                                    c.id[5] == c.id[6] && c.id[6] == c.id[7]);
  vmask<A> const wedge = lanes && !tet && simd::to_float_mask(c.id[2] == c.id[3] && c.id[6] == c.id[7]);
  vmask<A> const collapsed = lanes && !tet && !wedge && isa_detail::collapsed_edge(c);
  r.param = isa_detail::invert_hex(c, pts.p(), isa_detail::centre<A>(), lanes && !tet && !wedge && !collapsed,
                                   hex_newton_cap, r.converged);
  if (CELLRAY_UNLIKELY(simd::any(collapsed))) {
    vmask<A> converged;
    Vec3<A> const u = isa_detail::invert_collapsed_hex(c, pts.p(), collapsed, hex_newton_cap, converged);
    r.param = select<A>(collapsed, u, r.param);
    r.converged = (collapsed && converged) || (!collapsed && r.converged);
  }
  r.inside = r.converged && isa_detail::in_unit_cube<A>(r.param, hex_inside_tolerance);
  if (CELLRAY_UNLIKELY(simd::any(wedge))) {
    vmask<A> converged;
    Vec3<A> const q = isa_detail::invert_wedge(c, pts.p(), wedge, hex_newton_cap, converged);
    vfloat<A> const zero(0.f), one(1.f), tol(hex_inside_tolerance);
    vmask<A> const in = converged && q.x >= -tol && q.y >= -tol && q.x + q.y <= one + tol && q.z >= -tol &&
                        q.z <= one + tol;
    // Trilinear coordinates: v = s, u = r / (1 - s) (any u on the collapsed edge).
    vfloat<A> const one_s = one - q.y;
    vfloat<A> const u = simd::select(one_s > zero, q.x / simd::select(one_s > zero, one_s, one), vfloat<A>(0.5f));
    r.param = select<A>(wedge, Vec3<A>{simd::min(one, simd::max(zero, u)), q.y, q.z}, r.param);
    r.converged = (wedge && converged) || (!wedge && r.converged);
    r.inside = (wedge && in) || (!wedge && r.inside);
  }
  if (CELLRAY_UNLIKELY(simd::any(tet))) {
    vmask<A> solid, in;
    Vec3<A> const param = isa_detail::folded_tet_param(c.p(0), c.p(1), c.p(2), c.p(4), pts.p(), solid, in);
    r.param = select<A>(tet, param, r.param);
    r.converged = r.converged || (tet && solid);
    r.inside = (tet && in) || (!tet && r.inside);
  }
  r.value = isa_detail::trilerp<A>(c.s, r.param);
  return r;
}

/// Analytic gradient of the trilinear field at trilinear coordinates `param`
/// (e.g. Located::param): J^-T grad_uvw(s). Zero where the map is singular.
template <class A> inline Vec3<A> gradient_hex(CellCorners<A, 8> const& c, Vec3<A> const& param) {
  return isa_detail::hex_world_gradient(c, param);
}

/// Central differences of the cell's trilinear field around world point `p`
/// with step `h` (world units), the paper's shading normal source (§6.4).
/// Each of the six samples is a Newton inversion warm-started at `param`
/// (p's trilinear coordinates); a sample whose inversion does not converge
/// makes that component 0.
template <class A>
inline Vec3<A> gradient_central_hex(CellCorners<A, 8> const& c, Vec3<A> const& p, Vec3<A> const& param, float h) {
  vfloat<A> const hv(h), zero(0.f), inv(0.5f / h);
  auto value_at = [&](Vec3<A> const& x, vmask<A>& ok) {
    Vec3<A> const u = isa_detail::invert_hex(c, x, param, simd::all_lanes<A>(), hex_newton_cap, ok);
    return isa_detail::trilerp<A>(c.s, u);
  };
  auto diff = [&](Vec3<A> const& e) {
    vmask<A> ok1, ok2;
    vfloat<A> const a = value_at(p + e, ok1), b = value_at(p - e, ok2);
    return simd::select(ok1 && ok2, (a - b) * inv, zero);
  };
  return {diff({hv, zero, zero}), diff({zero, hv, zero}), diff({zero, zero, hv})};
}

namespace isa_detail {

/// The first crossing (f >= 0 predicate change) of the cubic in [start,1]
/// (start per lane, in [0,1)), in `lanes`, with the values at 0 and 1 given
/// exactly (canonical face values; at start > 0 the cubic's own value, so
/// its roots before start stay consistently excluded). Splits [start,1] at
/// the cubic's extrema (Marmitt et al. 2004) into monotone pieces, takes the
/// first piece whose ends differ, and polishes there with a
/// bisection-safeguarded Newton iteration. `lo_out`/`hi_out` return that
/// piece (for world-space refinement).
template <class A>
inline vfloat<A> first_cubic_root(Cubic<A> const& p, vfloat<A> const& f0, vfloat<A> const& f3, vmask<A> const& lanes,
                                  vfloat<A> const& start, vmask<A>& found, vfloat<A>& lo_out, vfloat<A>& hi_out) {
  vfloat<A> const zero(0.f), one(1.f);
  vfloat<A> const fs = simd::select(start > zero, p(start), f0);
  // Extrema: roots of 3 c3 x^2 + 2 c2 x + c1, stable form.
  vfloat<A> const A2 = vfloat<A>(3.f) * p.c3, B2 = vfloat<A>(2.f) * p.c2;
  vfloat<A> const disc = B2 * B2 - vfloat<A>(4.f) * A2 * p.c1;
  vfloat<A> const sq = simd::sqrt(simd::max(disc, zero));
  vfloat<A> const q = vfloat<A>(-0.5f) * (B2 + simd::select(B2 >= zero, sq, zero - sq));
  vmask<A> const has = disc > zero;
  vfloat<A> r1 = simd::select(A2 == zero, zero - p.c1 / B2, q / A2);
  vfloat<A> r2 = p.c1 / q;
  // Invalid roots (no real extrema, 0/0) collapse onto x = 1.
  r1 = simd::select(has && !simd::isnan(r1), clamp01<A>(r1), one);
  r2 = simd::select(has && !simd::isnan(r2) && !(A2 == zero), clamp01<A>(r2), one);
  // Extrema before start collapse onto it (pieces of zero length).
  vfloat<A> const e1 = simd::max(simd::min(r1, r2), start), e2 = simd::max(simd::max(r1, r2), start);
  auto val = [&](vfloat<A> const& x) {
    return simd::select(x <= start, fs, simd::select(x >= one, f3, p(x)));
  };
  vfloat<A> const g1 = val(e1), g2 = val(e2);
  vmask<A> const a0 = fs >= zero, a1 = g1 >= zero, a2 = g2 >= zero, a3 = f3 >= zero;
  vmask<A> const p0 = mask_xor<A>(a0, a1), p1 = mask_xor<A>(a1, a2), p2 = mask_xor<A>(a2, a3);
  found = lanes && (p0 || p1 || p2);
  vfloat<A> lo = simd::select(p0, start, simd::select(p1, e1, e2));
  vfloat<A> hi = simd::select(p0, e1, simd::select(p1, e2, one));
  vfloat<A> flo = simd::select(p0, fs, simd::select(p1, g1, g2));
  vfloat<A> fhi = simd::select(p0, g1, simd::select(p1, g2, f3));
  lo_out = lo, hi_out = hi;
  // Start at the secant point, then Newton kept inside the bracket.
  vfloat<A> den = fhi - flo;
  vfloat<A> x = lo + clamp01<A>(simd::select(den == zero, vfloat<A>(0.5f), -flo / den)) * (hi - lo);
  // A lane stops once its Newton step is within about one float spacing of
  // lam in [0,1] (quadratic convergence: the next step would be below
  // rounding); frozen per lane, so a lane's root never depends on the
  // other lanes (packet and SPMD agree bit for bit).
  vmask<A> active = found;
  for (int it = 0; it < 8 && simd::any(active); ++it) {
    vfloat<A> const fx = p(x);
    vmask<A> const same_lo = !mask_xor<A>(fx >= zero, flo >= zero);
    lo = simd::select(same_lo, x, lo);
    flo = simd::select(same_lo, fx, flo);
    hi = simd::select(same_lo, hi, x);
    fhi = simd::select(same_lo, fhi, fx);
    vfloat<A> const nx = x - fx / p.slope(x);
    // Closed bracket: a root exactly at an end (iso equal to the face value
    // there, f == 0 counts as above) is a fixed point of Newton at that end;
    // an open test bisected it away, 2^-8 of the cell into the interval.
    vmask<A> const inside = nx >= lo && nx <= hi;  // false for NaN
    vfloat<A> const next = simd::select(inside, nx, vfloat<A>(0.5f) * (lo + hi));
    vmask<A> const settled = inside && simd::abs(next - x) <= vfloat<A>(hex_cubic_step_tol);
    x = simd::select(active, next, x);
    active = active && !settled;
  }
  return x;
}

}  // namespace isa_detail

/// Exact-method isosurface root in a hex (see the file comment): the first
/// crossing along the ray of any of `count` isovalues (shared by all lanes),
/// nearest wins, ties to the lower index. The hit decision uses the clip's
/// canonical end values plus the cubic's extrema, so crossings are neither
/// lost nor doubled between neighbours, and a pair of crossings inside one
/// cell (double root, grazing ray) is found when the cubic shows it.
/// Parallelepipeds (HexClip::affine) take the cubic's root as is: it is the
/// field on the ray. Other hexes get `refine_steps` world-space Newton steps
/// (0 = the cubic's root only; each step is one warm-started trilinear
/// inversion of 3 iterations), kept inside the isolated bracket. Cells with
/// a NaN corner value never hit; hits never carry NaN. `param`, if given,
/// receives the trilinear coordinates of the hit in hit lanes (for the
/// shading gradient; other lanes unchanged): exact for parallelepipeds, the
/// last refinement's inversion (one Newton step behind t) otherwise.
/// `t_from` (per lane), if given: crossings before it are ignored and the
/// search starts there, so a window that starts inside the cell (a ray
/// leaving a surface, or continuing behind a transparent one) still finds a
/// second crossing of the same isovalue in that cell; hits have t >= t_from.
template <class A>
inline CellIsoHit<A> iso_root_hex(RayBatch<A> const& ray, HexClip<A> const& clip, CellCorners<A, 8> const& c,
                                  float const* isovalues, int count, int refine_steps = 2, Vec3<A>* param = nullptr,
                                  vfloat<A> const* t_from = nullptr) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  CellIsoHit<A> h{vfloat<A>(inf), vint<A>(-1), simd::no_lanes<A>()};
  vmask<A> const valid = clip.hit && !has_nan_value(c);
  if (simd::none(valid)) return h;
  Vec3<A> const du = clip.u_out - clip.u_in;
  vfloat<A> const dt = clip.t_out - clip.t_in;
  // Where the search starts, as lambda on the clip's segment: 0 unless the
  // window starts inside the cell (then t_from itself is the lower bound).
  vfloat<A> start(0.f), t_floor(-inf);
  if (t_from) {
    vmask<A> const inner = valid && *t_from > clip.t_in && dt > vfloat<A>(0.f);
    start = simd::select(inner, simd::min((*t_from - clip.t_in) / dt, vfloat<A>(1.f)), start);
    t_floor = simd::select(inner, *t_from, t_floor);
  }
  Vec3<A> const o = ray.origin(), d = ray.dir();
  // Parallelepipeds: the parametric segment between the entry and exit
  // coordinates *is* the ray, so the cubic through its values is the exact
  // field on the ray and needs neither inversions nor refinement. Other
  // hexes: the field on the ray itself at 1/3 and 2/3 by inversions
  // warm-started on the parametric segment (exact points of the
  // non-polynomial ray field).
  vmask<A> const general = valid && !clip.affine;
  bool const any_general = simd::any(general);
  auto on_ray = [&](float lam) {
    Vec3<A> u = clip.u_in + vfloat<A>(lam) * du;
    if (any_general) {
      vmask<A> conv;
      u = isa_detail::invert_on_ray(c, o + (clip.t_in + vfloat<A>(lam) * dt) * d, u, general, 4, conv);
    }
    return isa_detail::trilerp<A>(c.s, u);
  };
  vfloat<A> const v1 = on_ray(1.f / 3.f), v2 = on_ray(2.f / 3.f);
  for (int k = 0; k < count; ++k) {
    vfloat<A> const iso(isovalues[k]);
    vfloat<A> const f0 = clip.s_in - iso, f3 = clip.s_out - iso;
    isa_detail::Cubic<A> const cubic = isa_detail::cubic_through<A>(f0, v1 - iso, v2 - iso, f3);
    vfloat<A> lo, hi;
    vmask<A> found;
    vfloat<A> const lam = isa_detail::first_cubic_root(cubic, f0, f3, valid, start, found, lo, hi);
    if (simd::none(found)) continue;
    vfloat<A> t = simd::max(clip.t_in + lam * dt, t_floor);
    Vec3<A> u = clip.u_in + lam * du;
    vmask<A> const refine = found && general;
    if (refine_steps > 0 && simd::any(refine)) {
      vfloat<A> const t_lo = clip.t_in + lo * dt, t_hi = clip.t_in + hi * dt;
      for (int s = 0; s < refine_steps; ++s) {
        vmask<A> conv;
        u = isa_detail::invert_on_ray(c, o + t * d, u, refine, 3, conv);
        vmask<A> gok;
        Vec3<A> const g = isa_detail::hex_world_gradient(c, u, &gok);
        vfloat<A> const f = isa_detail::trilerp<A>(c.s, u) - iso;
        vfloat<A> const nt = t - f / dot(g, d);
        // The root is inside the bracket by construction: a step past an end
        // (the inverted field and the canonical face value differ by
        // rounding, so a root at the face can land a hair outside) stops at
        // that end instead of being dropped.
        vmask<A> const take = refine && gok && simd::abs(nt) < vfloat<A>(inf);  // false for NaN
        t = simd::select(take, simd::max(simd::min(simd::max(nt, t_lo), t_hi), t_floor), t);
      }
    }
    // Nearest wins, ties keep the lower index (isa_detail::keep_nearest's rule).
    if (param) *param = select<A>(found && t < h.t, u, *param);
    isa_detail::keep_nearest<A>(h, found, t, k);
  }
  return h;
}

/// Neubauer's method with `steps` rounds (paper Fig. 5, N = 2 there) on the
/// field at points of the ray (each a warm-started trilinear inversion). A
/// hit needs end values on opposite sides of the isovalue, so a pair of
/// crossings inside one cell is missed and with three crossings any one may
/// be returned (measured in tests/test_cells_hex.cpp). Same hit/NaN rules as
/// iso_root_hex otherwise.
template <class A>
inline CellIsoHit<A> iso_root_hex_neubauer(RayBatch<A> const& ray, HexClip<A> const& clip, CellCorners<A, 8> const& c,
                                           float const* isovalues, int count, int steps) {
  Vec3<A> const du = clip.u_out - clip.u_in;
  vfloat<A> const dt = clip.t_out - clip.t_in;
  Vec3<A> const o = ray.origin(), d = ray.dir();
  // Paper Fig. 5 interpolates at points on the ray: invert each one (warm
  // start on the parametric segment, 4 Newton iterations), but for
  // parallelepipeds, whose parametric segment is the ray.
  return isa_detail::neubauer_crossings<A>(clip, clip.hit && !has_nan_value(c), isovalues, count, steps,
                                       [&](vfloat<A> const& lam, vmask<A> const& lanes) {
                                         Vec3<A> u = clip.u_in + lam * du;
                                         vmask<A> const general = lanes && !clip.affine;
                                         if (simd::any(general)) {
                                           vmask<A> conv;
                                           u = isa_detail::invert_on_ray(c, o + (clip.t_in + lam * dt) * d, u, general,
                                                                         4, conv);
                                         }
                                         return isa_detail::trilerp<A>(c.s, u);
                                       });
}

/// Neubauer on the straight parametric segment between entry and exit
/// (no inversions: cheaper, exact only for parallelepipeds). Kept for
/// callers without the ray at hand; prefer the overload taking the ray.
template <class A>
inline CellIsoHit<A> iso_root_hex_neubauer(HexClip<A> const& clip, CellCorners<A, 8> const& c, float const* isovalues,
                                           int count, int steps) {
  Vec3<A> const du = clip.u_out - clip.u_in;
  return isa_detail::neubauer_crossings<A>(
      clip, clip.hit && !has_nan_value(c), isovalues, count, steps,
      [&](vfloat<A> const& lam, vmask<A> const&) { return isa_detail::trilerp<A>(c.s, clip.u_in + lam * du); });
}

/// A tetrahedron stored as a hexahedron (CellOps<A, 8>::is_folded_tet), as a
/// packet leaf hands it on: its corners in the tet kernels' order, and
/// which corner of the hexahedron (0, 1, 2 or 4) each is.
template <class A> struct FoldedTet {
  CellCorners<A, 4> tet;
  int hex_corner[4];
};

/// What the traversals call for hexahedra, and wedges and pyramids as
/// hexahedra with repeated corners (cells/cell_ops.hpp).
template <class A> struct CellOps<A, 8> {
  using Clip = HexClip<A>;
  /// Trilinear: the field along a ray may exceed its end values.
  static constexpr bool linear_on_ray = false;
  /// Hits and located points keep their trilinear coordinates: the
  /// gradient and any per-vertex weights there need no second inversion.
  static constexpr bool keeps_param = true;
  static Clip clip(RayBatch<A> const& r, CellCorners<A, 8> const& c) {
    constexpr float inf = std::numeric_limits<float>::infinity();
    return clip_window(r, c, simd::all_lanes<A>(), vfloat<A>(-inf), vfloat<A>(inf));
  }
  /// When every lane holds a folded tet (is_folded_tet), the tet clip
  /// (Clip::linear; isa_detail::clip_folded_tets), else clip_hex_window.
  /// Lanes of mixed cells share the hexahedron clip, which crosses a folded
  /// tet's faces as the tet clip does: a tet clip beside it only added work
  /// (the flange, 16% tets: DVR 0.93-0.97x).
  static Clip clip_window(RayBatch<A> const& r, CellCorners<A, 8> const& c, vmask<A> const& lanes,
                          vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face = nullptr) {
    if (CELLRAY_UNLIKELY(simd::all(!lanes || isa_detail::folded_tet_lanes(c))))
      return isa_detail::clip_folded_tets(r, c, lanes, t_lo, t_hi, exit_face);
    return clip_hex_window(r, c, lanes, t_lo, t_hi, exit_face);
  }
  /// A march's clip: parallelepipeds (a structured grid's cells, as
  /// boxturb48's) by the slab test (clip_parallelepipeds), the other lanes
  /// by clip_window. A march goes on from where the last cell ended, so
  /// the rounding of a face seen from two sides opens no gap in DVR
  /// (boxturb48 DVR 1.5x, 1 thread: docs/performance.md); an AO ray's
  /// isovalue crossing exactly there can be missed (march_occluded), as
  /// primary rays did 3 in 1M times with this clip, noise far below an AO
  /// ray's own. The choice is per lane, a function of the cell alone, so
  /// the locate that starts a march (FirstCellQuery) and the march's step
  /// clip a cell alike: a located cell always lets the lane progress.
  static Clip march_clip_window(RayBatch<A> const& r, CellCorners<A, 8> const& c, vmask<A> const& lanes,
                                vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A>* exit_face) {
    vmask<A> const para = isa_detail::parallelepiped_lanes(c);
    vmask<A> const slab = lanes && para, general = lanes && !para;
    if (simd::none(general)) return clip_parallelepipeds(r, c, lanes, t_lo, t_hi, exit_face);
    if (simd::none(slab)) return clip_window(r, c, lanes, t_lo, t_hi, exit_face);
    vint<A> face_g(0), face_s(0);
    Clip k = clip_window(r, c, general, t_lo, t_hi, exit_face ? &face_g : nullptr);
    Clip const p = clip_parallelepipeds(r, c, slab, t_lo, t_hi, exit_face ? &face_s : nullptr);
    k.t_in = simd::select(slab, p.t_in, k.t_in), k.t_out = simd::select(slab, p.t_out, k.t_out);
    k.s_in = simd::select(slab, p.s_in, k.s_in), k.s_out = simd::select(slab, p.s_out, k.s_out);
    k.u_in = select<A>(slab, p.u_in, k.u_in), k.u_out = select<A>(slab, p.u_out, k.u_out);
    k.hit = k.hit || p.hit, k.affine = k.affine || p.affine, k.linear = k.linear && general;
    if (exit_face) *exit_face = simd::select(simd::to_int_mask(slab), face_s, face_g);
    return k;
  }
  static constexpr bool march_reuses_corners = false;
  static constexpr bool occlusion_in_pairs = false;

  /// Tetrahedra stored as hexahedra (0 1 2 2 3 3 3 3, fold_tets_into_hexes:
  /// a mixed mesh under one BVH) take the tet kernels where a packet leaf
  /// meets one (for_each_leaf_cell: FoldedTet): the same surface, at a
  /// tet's cost instead of a trilinear root search over 8 corners. Per-lane
  /// paths (SPMD leaves, marches) get the tet clip and a linear field from
  /// clip_window (Clip::linear).
  static constexpr bool holds_folded_tets = true;
  /// Packets from one origin (a camera's) clip a cell whose faces are all
  /// parallelograms from one setup (hex_window_setup; other cells: each
  /// packet its own clip_hex_window). Folded tets take the tets' setup.
  /// Not for marches: their clip of parallelepipeds is the slab test.
  static constexpr bool shares_window_setup = true;
  static constexpr bool march_clips_window = false;
  using WindowSetup = HexWindowSetup<A>;
  static WindowSetup window_setup(CellCorners<A, 8> const& c, Vec3<A> const& origin) {
    return hex_window_setup(c, origin);
  }
  static Clip clip_window_set(RayBatch<A> const& r, CellCorners<A, 8> const& c, WindowSetup const& s,
                              vmask<A> const& lanes, vfloat<A> const& t_lo, vfloat<A> const& t_hi) {
    if (!s.planar) return clip_window(r, c, lanes, t_lo, t_hi);
    return clip_hex_set(r, c, s, lanes, t_lo, t_hi);
  }
  /// Whether corner keys `key` (mesh order) are such a tetrahedron's (see
  /// isa_detail::is_folded_tet).
  static bool is_folded_tet(int32_t const (&k)[8]) { return isa_detail::is_folded_tet(k); }
  /// The tetrahedron of an is_folded_tet cell `k` in every lane.
  static FoldedTet<A> broadcast_folded_tet(float const* xyz, ScalarCorners<8> const& k) {
    FoldedTet<A> f;
    int* o = f.hex_corner;
    o[0] = 0, o[1] = 1, o[2] = 2, o[3] = 4;
    auto swap_if = [&](int i, int j) {
      if (k.key[o[i]] > k.key[o[j]]) std::swap(o[i], o[j]);
    };
    swap_if(0, 1), swap_if(2, 3), swap_if(0, 2), swap_if(1, 3), swap_if(1, 2);  // order_corners<4>'s network
    for (int i = 0; i < 4; ++i) {
      float const* q = xyz + 3 * k.v[o[i]];
      f.tet.x[i] = vfloat<A>(q[0]), f.tet.y[i] = vfloat<A>(q[1]), f.tet.z[i] = vfloat<A>(q[2]);
      f.tet.s[i] = vfloat<A>(k.s[o[i]]);
      f.tet.id[i] = vint<A>(k.key[o[i]]);
    }
    return f;
  }
  /// Trilinear coordinates (this type's) of points `p` in a FoldedTet.
  static Vec3<A> folded_tet_param(FoldedTet<A> const& f, Vec3<A> const& p) {
    Vec3<A> at[5];  // at[j]: hexahedron corner j (0, 1, 2, 4)
    for (int i = 0; i < 4; ++i) at[f.hex_corner[i]] = f.tet.p(i);
    vmask<A> solid, in;
    return isa_detail::folded_tet_param(at[0], at[1], at[2], at[4], p, solid, in);
  }

  /// `param`, if given, receives the trilinear coordinates of the hit in
  /// hit lanes (iso_root_hex's; for Neubauer one inversion at the root).
  /// `t_from`: the exact method's search start (see iso_root_hex);
  /// Neubauer, which misses pairs of crossings in a cell anyway, ignores it.
  static CellIsoHit<A> iso(RayBatch<A> const& r, Clip const& k, CellCorners<A, 8> const& c, float const* isos,
                           int count, CellIsoOptions const& o, Vec3<A>* param = nullptr,
                           vfloat<A> const* t_from = nullptr) {
    if (o.method == CellIsoMethod::exact) return iso_root_hex(r, k, c, isos, count, o.refine_steps, param, t_from);
    CellIsoHit<A> const h = iso_root_hex_neubauer(r, k, c, isos, count, o.neubauer_steps);
    if (param && simd::any(h.hit)) {
      vfloat<A> const dt = k.t_out - k.t_in;
      vfloat<A> const lam = simd::select(h.hit, (h.t - k.t_in) / dt, vfloat<A>(0.f));
      Vec3<A> u = k.u_in + lam * (k.u_out - k.u_in);  // a parallelepiped's point (as above)
      vmask<A> const general = h.hit && !k.affine;
      if (simd::any(general)) {
        vmask<A> conv;
        u = isa_detail::invert_on_ray(c, r.origin() + simd::select(h.hit, h.t, k.t_in) * r.dir(), u, general,
                                      hex_newton_cap, conv);
      }
      *param = select<A>(h.hit, u, *param);
    }
    return h;
  }
  static Located<A> locate(PointBatch<A> const& p, CellCorners<A, 8> const& c) { return locate_hex(p, c); }
  /// Only the lanes in `lanes` (the iteration ends when they converge).
  static Located<A> locate(PointBatch<A> const& p, CellCorners<A, 8> const& c, vmask<A> const& lanes) {
    return locate_hex(p, c, lanes);
  }
  /// None: locate_hex's containment is widened already (hex_inside_tolerance).
  static vmask<A> nearly_inside(Located<A> const& /*loc*/, float /*tol*/) { return simd::no_lanes<A>(); }
  static Vec3<A> gradient(CellCorners<A, 8> const& c, Vec3<A> const& p, GradientMethod m, float h) {
    Located<A> const l = locate_hex(PointBatch<A>{p.x, p.y, p.z}, c);
    return m != GradientMethod::central ? gradient_hex(c, l.param) : gradient_central_hex(c, p, l.param, h);
  }
  static Vec3<A> gradient_at(CellCorners<A, 8> const& c, Vec3<A> const& param) { return gradient_hex(c, param); }
  /// Trilinear, in VTK corner order (the mesh's own, as the kernels keep it).
  static void shape_weights(Vec3<A> const& param, vfloat<A> (&w)[8]) { trilinear_weights<A>(param, w); }
  /// Kept coordinates that can stand for a located point (see hex_param_in_cell).
  static vmask<A> param_in_cell(Vec3<A> const& param) { return hex_param_in_cell<A>(param); }

  /// The field on the ray at lambda of the clip's segment: its value, and
  /// its trilinear coordinates in `u`. A lane whose inversion neither
  /// converges nor stays near the cell keeps the parametric guess (never a
  /// wild value).
  static vfloat<A> field_on_ray(RayBatch<A> const& ray, CellCorners<A, 8> const& c, Clip const& k,
                                vmask<A> const& lanes, float lam, Vec3<A>& u) {
    // The hexahedra's path as it was (hex DVR lost 3% to the pyramids'
    // branch inlined here: code placement, scripts/ab-builds.sh).
    if (CELLRAY_UNLIKELY(isa_detail::top_collapsed(c, lanes))) return pyramid_field_on_ray(ray, c, k, lanes, lam, u);
    vfloat<A> const l(lam);
    Vec3<A> const guess = k.u_in + l * (k.u_out - k.u_in);
    // Parallelepipeds (Clip::affine): the parametric segment is the ray, as
    // in iso_root_hex, so the guess is the point; Newton only for the rest.
    vmask<A> const general = lanes && !k.affine;
    if (simd::any(general)) {
      vmask<A> conv;
      u = isa_detail::invert_hex(c, ray.origin() + (k.t_in + l * (k.t_out - k.t_in)) * ray.dir(), guess, general, 6,
                                 conv);
      u = select<A>(conv || isa_detail::in_unit_cube<A>(u, 0.05f), u, guess);
    } else {
      u = guess;
    }
    return isa_detail::trilerp<A>(c.s, u);
  }

  /// field_on_ray where some lane's top is collapsed: pyramids located in
  /// closed form (isa_detail::invert_pyramids_on_ray).
  CELLRAY_NOINLINE static vfloat<A> pyramid_field_on_ray(RayBatch<A> const& ray, CellCorners<A, 8> const& c,
                                                         Clip const& k, vmask<A> const& lanes, float lam, Vec3<A>& u) {
    vfloat<A> const l(lam);
    Vec3<A> const guess = k.u_in + l * (k.u_out - k.u_in);
    vmask<A> conv;
    u = isa_detail::invert_pyramids_on_ray(c, ray.origin() + (k.t_in + l * (k.t_out - k.t_in)) * ray.dir(), guess,
                                           lanes, 6, conv);
    u = select<A>(conv || isa_detail::in_unit_cube<A>(u, 0.05f), u, guess);
    return isa_detail::trilerp<A>(c.s, u);
  }

  /// The field on the clip's segment (see the tet's): the cubic through its
  /// values at lambda = 0, 1/3, 2/3, 1 (the ends: the clip's face values;
  /// inside: inversions warm-started on the parametric segment), and the
  /// gradient as the cubic through the analytic gradients there. Exact for
  /// parallelepipeds; folded tets (Clip::linear) get folded_tet_field.
  static void segment_field(RayBatch<A> const& ray, CellCorners<A, 8> const& c, Clip const& k,
                            vmask<A> const& lanes, isa_detail::Cubic<A>& f, isa_detail::Cubic<A>* g) {
    vmask<A> const folded = lanes && k.linear, trilinear = lanes && !k.linear;
    if (simd::any(trilinear)) {
      Vec3<A> u1, u2;
      vfloat<A> const v1 = field_on_ray(ray, c, k, trilinear, 1.f / 3.f, u1);
      vfloat<A> const v2 = field_on_ray(ray, c, k, trilinear, 2.f / 3.f, u2);
      f = isa_detail::cubic_through<A>(k.s_in, v1, v2, k.s_out);
      if (g) {
        Vec3<A> const g0 = isa_detail::hex_world_gradient(c, k.u_in), g1 = isa_detail::hex_world_gradient(c, u1);
        Vec3<A> const g2 = isa_detail::hex_world_gradient(c, u2), g3 = isa_detail::hex_world_gradient(c, k.u_out);
        g[0] = isa_detail::cubic_through<A>(g0.x, g1.x, g2.x, g3.x);
        g[1] = isa_detail::cubic_through<A>(g0.y, g1.y, g2.y, g3.y);
        g[2] = isa_detail::cubic_through<A>(g0.z, g1.z, g2.z, g3.z);
      }
    } else {
      vfloat<A> const zero(0.f);
      f = {zero, zero, zero, zero};
      if (g) g[0] = g[1] = g[2] = f;
    }
    if (simd::any(folded)) folded_tet_field(c, k, folded, f, g);
  }

  /// segment_field of the folded-tet lanes `folded` (Clip::linear), written
  /// into f and g in those lanes only: the line between the clip's end
  /// values, and the tet's constant gradient.
  static void folded_tet_field(CellCorners<A, 8> const& c, Clip const& k, vmask<A> const& folded,
                               isa_detail::Cubic<A>& f, isa_detail::Cubic<A>* g) {
    vfloat<A> const zero(0.f);
    auto merge = [&](isa_detail::Cubic<A>& x, vfloat<A> const& c0, vfloat<A> const& c1) {
      x.c0 = simd::select(folded, c0, x.c0), x.c1 = simd::select(folded, c1, x.c1);
      x.c2 = simd::select(folded, zero, x.c2), x.c3 = simd::select(folded, zero, x.c3);
    };
    merge(f, k.s_in, k.s_out - k.s_in);
    if (!g) return;
    Vec3<A> const gt = gradient_tet(isa_detail::folded_tet_corners(c));
    merge(g[0], gt.x, zero), merge(g[1], gt.y, zero), merge(g[2], gt.z, zero);
  }
};

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
