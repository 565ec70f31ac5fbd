#pragma once
// The scalar double-precision oracle for every cell kernel (tet.hpp,
// hex.hpp). Slow on purpose: straightforward formulas in double, Newton to
// 1e-13 with multi-start, roots by dense bracketing and bisection to machine
// precision. Used by the tests, the accuracy measurements and the reference
// renderer; never a fast path. Same face models as the SIMD kernels (tet
// planes, hex bilinear patches), so results are comparable one to one.
//
// All functions are thread-safe (no state). NaN corner values propagate into
// values; iso functions report no crossing for a cell with a NaN value.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "../mesh/cell_mesh.hpp"
#include "../simd/arch.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace ref {

using dvec3 = glm::dvec3;

/// One cell in double: corner positions and values in mesh order (VTK order
/// for hexes), and global vertex ids (for the canonical face order).
template <int N> struct Cell {
  dvec3 p[N];
  double s[N];
  uint64_t id[N];
};
using Tet = Cell<4>;
using Hex = Cell<8>;

/// A line o + t d (d need not be unit length).
struct Ray {
  dvec3 o, d;
};

/// See CellClip / HexClip in tet.hpp / hex.hpp. `u_in`/`u_out` are trilinear
/// coordinates for hexes and unused for tets.
struct Clip {
  bool hit = false;
  double t_in = 0, t_out = 0, s_in = 0, s_out = 0;
  dvec3 u_in{0}, u_out{0};
};

/// See Located in tet.hpp. `param`: tet barycentric weights of mesh-order
/// corners 1..3; hex (u, v, w). Closed containment (boundary is inside).
struct Location {
  bool inside = false, converged = false;
  double value = 0;
  dvec3 param{0};
};

/// The nearest crossing of any isovalue (index into the list), or none.
struct IsoRoot {
  bool hit = false;
  double t = std::numeric_limits<double>::infinity();
  int index = -1;
};

/// Cell `cell` of `mesh` in double (active array; NaN values if none, and
/// for +-inf values: such a cell is invisible, as in the fast kernels).
template <int N> inline Cell<N> load(CellMesh<N> const& mesh, uint64_t cell) {
  Cell<N> c;
  for (int i = 0; i < N; ++i) {
    uint64_t const v = mesh.vertex(cell, i);
    glm::vec3 const p = mesh.position(v);
    c.p[i] = dvec3(p);
    double const s = mesh.has_values() ? double(mesh.value(v)) : std::numeric_limits<double>::quiet_NaN();
    c.s[i] = std::isfinite(s) ? s : std::numeric_limits<double>::quiet_NaN();
    c.id[i] = v;
  }
  return c;
}

template <int N> inline bool has_nan(Cell<N> const& c) {
  for (double s : c.s)
    if (std::isnan(s)) return true;
  return false;
}

// ---------------------------------------------------------------- tets

/// Ray clip against the four face planes (canonical: face corners sorted by
/// id), values at the crossings by barycentric interpolation on the face.
inline Clip clip(Tet const& tet, Ray const& ray) {
  int ord[4] = {0, 1, 2, 3};
  std::sort(ord, ord + 4, [&](int a, int b) { return tet.id[a] < tet.id[b]; });
  static constexpr int faces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  Clip r;
  r.t_in = -std::numeric_limits<double>::infinity();
  r.t_out = std::numeric_limits<double>::infinity();
  for (int f = 0; f < 4; ++f) {
    int const ia = ord[faces[f][0]], ib = ord[faces[f][1]], ic = ord[faces[f][2]], io = ord[f];
    dvec3 const a = tet.p[ia], e1 = tet.p[ib] - a, e2 = tet.p[ic] - a;
    dvec3 const n = glm::cross(e1, e2);
    double const side = glm::dot(n, tet.p[io] - a);
    if (side == 0 || std::isnan(side)) return Clip{};
    double const num = glm::dot(n, a - ray.o), den = glm::dot(n, ray.d);
    if (den == 0) {
      if ((side > 0 && num > 0) || (side < 0 && num < 0)) return Clip{};  // parallel, outside
      continue;
    }
    double const t = num / den;
    dvec3 const rel = ray.o + t * ray.d - a;
    double const nn = glm::dot(n, n);
    double const beta = glm::dot(glm::cross(rel, e2), n) / nn, gamma = glm::dot(glm::cross(e1, rel), n) / nn;
    double const s = tet.s[ia] + beta * (tet.s[ib] - tet.s[ia]) + gamma * (tet.s[ic] - tet.s[ia]);
    bool const enter = (den > 0) == (side > 0);
    if (enter && t > r.t_in) r.t_in = t, r.s_in = s;
    if (!enter && t < r.t_out) r.t_out = t, r.s_out = s;
  }
  r.hit = r.t_in < r.t_out;
  return r;
}

/// Barycentric location; inside when every weight >= 0 (closed).
inline Location locate(Tet const& tet, dvec3 const& p) {
  dvec3 const e1 = tet.p[1] - tet.p[0], e2 = tet.p[2] - tet.p[0], e3 = tet.p[3] - tet.p[0], r = p - tet.p[0];
  double const det = glm::dot(e1, glm::cross(e2, e3));
  Location L;
  L.converged = true;
  if (det == 0 || std::isnan(det)) return L;
  double const w1 = glm::dot(r, glm::cross(e2, e3)) / det;
  double const w2 = glm::dot(e1, glm::cross(r, e3)) / det;
  double const w3 = glm::dot(e1, glm::cross(e2, r)) / det;
  double const w0 = 1 - w1 - w2 - w3;
  L.param = {w1, w2, w3};
  L.value = w0 * tet.s[0] + w1 * tet.s[1] + w2 * tet.s[2] + w3 * tet.s[3];
  L.inside = w0 >= 0 && w1 >= 0 && w2 >= 0 && w3 >= 0;
  return L;
}

/// Constant gradient of the linear field; zero for a zero-volume tet.
inline dvec3 gradient(Tet const& tet) {
  dvec3 const e1 = tet.p[1] - tet.p[0], e2 = tet.p[2] - tet.p[0], e3 = tet.p[3] - tet.p[0];
  double const det = glm::dot(e1, glm::cross(e2, e3));
  if (det == 0) return dvec3(0);
  double const d1 = tet.s[1] - tet.s[0], d2 = tet.s[2] - tet.s[0], d3 = tet.s[3] - tet.s[0];
  return (d1 * glm::cross(e2, e3) + d2 * glm::cross(e3, e1) + d3 * glm::cross(e1, e2)) / det;
}

/// Every isovalue crossing in the clip interval (the field is linear there:
/// at most one; end values compared with >= iso as in the SIMD kernels).
inline std::vector<double> crossings(Tet const& tet, Ray const&, Clip const& c, double iso) {
  if (!c.hit || has_nan(tet) || (c.s_in >= iso) == (c.s_out >= iso)) return {};
  return {c.t_in + (c.t_out - c.t_in) * std::clamp((iso - c.s_in) / (c.s_out - c.s_in), 0.0, 1.0)};
}

// ---------------------------------------------------------------- hexes

namespace detail {
inline constexpr int hex_faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                        {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};
inline constexpr double hex_uvw[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                         {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

template <class T> inline T trilerp(T const* v, dvec3 const& u) {
  T const b0 = (1 - u.y) * ((1 - u.x) * v[0] + u.x * v[1]) + u.y * ((1 - u.x) * v[3] + u.x * v[2]);
  T const b1 = (1 - u.y) * ((1 - u.x) * v[4] + u.x * v[5]) + u.y * ((1 - u.x) * v[7] + u.x * v[6]);
  return (1 - u.z) * b0 + u.z * b1;
}
template <class T> inline void trilerp_grad(T const* v, dvec3 const& u, T& du, T& dv, T& dw) {
  double const mu = 1 - u.x, mv = 1 - u.y, mw = 1 - u.z;
  du = mw * (mv * (v[1] - v[0]) + u.y * (v[2] - v[3])) + u.z * (mv * (v[5] - v[4]) + u.y * (v[6] - v[7]));
  dv = mw * (mu * (v[3] - v[0]) + u.x * (v[2] - v[1])) + u.z * (mu * (v[7] - v[4]) + u.x * (v[6] - v[5]));
  dw = mv * (mu * (v[4] - v[0]) + u.x * (v[5] - v[1])) + u.y * (mu * (v[7] - v[3]) + u.x * (v[6] - v[2]));
}

/// Newton from `u` with a backtracking line search on |x(u) - p|. Returns
/// true when the step fell below 1e-13.
inline bool newton(Hex const& h, dvec3 const& p, dvec3& u, int cap) {
  auto resid = [&](dvec3 const& q) { return trilerp(h.p, q) - p; };
  dvec3 r = resid(u);
  for (int it = 0; it < cap; ++it) {
    dvec3 ju, jv, jw;
    trilerp_grad(h.p, u, ju, jv, jw);
    dvec3 const cvw = glm::cross(jv, jw), cwu = glm::cross(jw, ju), cuv = glm::cross(ju, jv);
    double const det = glm::dot(ju, cvw);
    if (det == 0 || !std::isfinite(det)) return false;
    dvec3 const step = dvec3(glm::dot(r, cvw), glm::dot(r, cwu), glm::dot(r, cuv)) / det;
    double lam = 1;
    dvec3 nu = u - step, nr = resid(nu);
    while (glm::length(nr) > glm::length(r) && lam > 1e-4) {
      lam *= 0.5;
      nu = u - lam * step;
      nr = resid(nu);
    }
    u = nu, r = nr;
    double const size = std::max({std::abs(step.x), std::abs(step.y), std::abs(step.z)}) * lam;
    if (!std::isfinite(size) || glm::length(u) > 1e6) return false;
    if (size < 1e-13 || glm::length(r) == 0) return true;
  }
  return glm::length(r) <= 1e-12 * (1 + glm::length(p));
}
}  // namespace detail

/// World position at trilinear coordinates u (extrapolates outside [0,1]^3).
inline dvec3 position(Hex const& h, dvec3 const& u) { return detail::trilerp(h.p, u); }
/// Field value at trilinear coordinates u.
inline double value(Hex const& h, dvec3 const& u) { return detail::trilerp(h.s, u); }

/// Trilinear inversion: Newton with line search from the centre, then from
/// the 8 corners, 6 face centres and 12 edge midpoints until a converged
/// solution lies in [0,1]^3 (within 1e-9). A point outside the cell reports
/// the converged solution (outside the cube) or converged = false.
inline Location locate(Hex const& h, dvec3 const& p, dvec3 const* warm = nullptr) {
  Location L;
  std::vector<dvec3> starts;
  if (warm) starts.push_back(*warm);
  starts.push_back(dvec3(0.5));
  for (int i = 0; i < 27; ++i)
    if (i != 13) starts.push_back(dvec3(0.5 * (i % 3), 0.5 * (i / 3 % 3), 0.5 * (i / 9)));
  for (dvec3 const& s : starts) {
    dvec3 u = s;
    if (!detail::newton(h, p, u, 60)) continue;
    bool const in = u.x >= -1e-9 && u.x <= 1 + 1e-9 && u.y >= -1e-9 && u.y <= 1 + 1e-9 && u.z >= -1e-9 &&
                    u.z <= 1 + 1e-9;
    if (!L.converged || in) {
      L.converged = true, L.param = u, L.inside = in, L.value = value(h, u);
      if (in) break;
    }
  }
  return L;
}

/// World-space gradient of the trilinear field at trilinear coordinates u.
inline dvec3 gradient(Hex const& h, dvec3 const& u) {
  dvec3 ju, jv, jw;
  detail::trilerp_grad(h.p, u, ju, jv, jw);
  double ds[3];
  detail::trilerp_grad(h.s, u, ds[0], ds[1], ds[2]);
  dvec3 const cvw = glm::cross(jv, jw), cwu = glm::cross(jw, ju), cuv = glm::cross(ju, jv);
  double const det = glm::dot(ju, cvw);
  if (det == 0) return dvec3(0);
  return (ds[0] * cvw + ds[1] * cwu + ds[2] * cuv) / det;
}

/// Ray clip by the six bilinear face patches (Reshetov's ray/patch solution
/// in double, patch coordinates accepted within 1e-9 of [0,1]): the hull of
/// all crossings, with values and trilinear coordinates there.
inline Clip clip(Hex const& h, Ray const& ray) {
  Clip r;
  r.t_in = std::numeric_limits<double>::infinity();
  r.t_out = -r.t_in;
  double const tol = 1e-9;
  for (auto const& face : detail::hex_faces) {
    int const i00 = face[0], i10 = face[1], i11 = face[2], i01 = face[3];
    dvec3 const q00 = h.p[i00] - ray.o, q10 = h.p[i10] - ray.o, q11 = h.p[i11] - ray.o, q01 = h.p[i01] - ray.o;
    dvec3 const e10 = q10 - q00, e11 = q11 - q10, e00 = q01 - q00;
    dvec3 const qn = glm::cross(e10, q01 - q11);
    double const a = glm::dot(glm::cross(q00, ray.d), e00);
    double const c = glm::dot(qn, ray.d);
    double const b = glm::dot(glm::cross(q10, ray.d), e11) - (a + c);
    double const disc = b * b - 4 * a * c;
    if (disc < 0) continue;
    double us[2];
    int nu = 0;
    if (c == 0) {
      if (b != 0) us[nu++] = -a / b;
    } else {
      double const q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
      us[nu++] = q / c;
      if (q != 0) us[nu++] = a / q;
    }
    for (int k = 0; k < nu; ++k) {
      double const u = us[k];
      if (!(u >= -tol && u <= 1 + tol)) continue;
      dvec3 const pa = q00 + u * (q10 - q00), pb = e00 + u * (e11 - e00);
      dvec3 n = glm::cross(ray.d, pb);
      double const det = glm::dot(n, n);
      if (det <= 0) continue;
      n = glm::cross(n, pa);
      double const t = glm::dot(n, pb) / det, v = glm::dot(n, ray.d) / det;
      if (!(v >= -tol && v <= 1 + tol)) continue;
      double const s = (1 - v) * ((1 - u) * h.s[i00] + u * h.s[i10]) + v * ((1 - u) * h.s[i01] + u * h.s[i11]);
      dvec3 const P00(detail::hex_uvw[i00][0], detail::hex_uvw[i00][1], detail::hex_uvw[i00][2]);
      dvec3 const P10(detail::hex_uvw[i10][0], detail::hex_uvw[i10][1], detail::hex_uvw[i10][2]);
      dvec3 const P01(detail::hex_uvw[i01][0], detail::hex_uvw[i01][1], detail::hex_uvw[i01][2]);
      dvec3 const uvw = P00 + u * (P10 - P00) + v * (P01 - P00);
      if (t < r.t_in) r.t_in = t, r.s_in = s, r.u_in = uvw;
      if (t > r.t_out) r.t_out = t, r.s_out = s, r.u_out = uvw;
    }
  }
  r.hit = r.t_in < r.t_out;
  return r;
}

/// Field value on the ray at t, by inversion warm-started at `u` (updated).
inline double value_on_ray(Hex const& h, Ray const& ray, double t, dvec3& u) {
  Location const L = locate(h, ray.o + t * ray.d, &u);
  if (L.converged) u = L.param;
  return L.converged ? L.value : std::numeric_limits<double>::quiet_NaN();
}

/// Every isovalue crossing along the ray in [t_in, t_out], ascending: the
/// field sampled at 512 equal steps (exact trilinear inversion at each,
/// clip's end values at the ends), each change of (value >= iso) bisected to
/// machine precision. Crossing pairs closer than a step apart can be missed;
/// the SIMD kernels are compared against what this finds.
inline std::vector<double> crossings(Hex const& h, Ray const& ray, Clip const& c, double iso) {
  std::vector<double> out;
  if (!c.hit || has_nan(h)) return out;
  int const M = 512;
  dvec3 u = c.u_in;
  double t0 = c.t_in, f0 = c.s_in - iso;
  for (int i = 1; i <= M; ++i) {
    double const t1 = i == M ? c.t_out : c.t_in + (c.t_out - c.t_in) * i / M;
    dvec3 const u0 = u;
    double const f1 = i == M ? c.s_out - iso : value_on_ray(h, ray, t1, u) - iso;
    if ((f0 >= 0) != (f1 >= 0)) {
      double a = t0, b = t1;
      dvec3 ub = u0;
      for (int k = 0; k < 200 && b - a > 0; ++k) {
        double const m = 0.5 * (a + b);
        if (m <= a || m >= b) break;
        if ((value_on_ray(h, ray, m, ub) - iso >= 0) == (f0 >= 0)) a = m;
        else b = m;
      }
      out.push_back(0.5 * (a + b));
    }
    t0 = t1, f0 = f1;
  }
  return out;
}

/// The nearest crossing of any of `count` isovalues (ties: lower index).
template <int N>
inline IsoRoot iso_root(Cell<N> const& cell, Ray const& ray, Clip const& c, float const* isovalues, int count) {
  IsoRoot r;
  for (int k = 0; k < count; ++k) {
    std::vector<double> const x = crossings(cell, ray, c, double(isovalues[k]));
    if (!x.empty() && x.front() < r.t) r.hit = true, r.t = x.front(), r.index = k;
  }
  return r;
}


// ------------------------------------------- the field along a ray (renderer)

/// Shape-function weights of the corners (mesh order) at cell coordinates
/// `param` (a Location's): barycentric in a tet, trilinear (clamped to the
/// cube) in a hex.
inline void shape_weights(Tet const&, dvec3 const& param, double (&w)[4]) {
  w[1] = param.x, w[2] = param.y, w[3] = param.z, w[0] = 1 - w[1] - w[2] - w[3];
}
inline void shape_weights(Hex const&, dvec3 const& param, double (&w)[8]) {
  dvec3 const u = glm::clamp(param, dvec3(0), dvec3(1));
  for (int i = 0; i < 8; ++i)
    w[i] = (detail::hex_uvw[i][0] ? u.x : 1 - u.x) * (detail::hex_uvw[i][1] ? u.y : 1 - u.y) *
           (detail::hex_uvw[i][2] ? u.z : 1 - u.z);
}

/// Trilinear coordinates of world point p, Newton from `u` (the guess) with
/// the multi-start fallback of locate. False when nothing converged.
inline bool invert(Hex const& h, dvec3 const& p, dvec3& u) {
  dvec3 v = u;
  if (detail::newton(h, p, v, 40) && std::isfinite(v.x + v.y + v.z)) {
    u = v;
    return true;
  }
  Location const L = locate(h, p, &u);
  if (L.converged) u = L.param;
  return L.converged;
}

/// The hex field on the ray: value and d/dt at t, coordinates warm-started.
struct RaySample {
  double t = 0, f = 0, df = 0;
  dvec3 u{0.5};
};

inline RaySample hex_sample(Hex const& h, Ray const& r, double t, dvec3 guess) {
  RaySample s;
  s.t = t;
  s.u = guess;
  if (!invert(h, r.o + t * r.d, s.u)) {
    s.f = std::numeric_limits<double>::quiet_NaN();
    return s;
  }
  s.f = value(h, s.u);
  s.df = glm::dot(gradient(h, s.u), r.d);
  return s;
}

/// Trilinear coordinates on the straight parametric segment between the
/// clip's entry and exit: the warm start for the point at t.
inline dvec3 hex_guess(Clip const& c, double t) {
  double const lam = c.t_out > c.t_in ? std::clamp((t - c.t_in) / (c.t_out - c.t_in), 0.0, 1.0) : 0.5;
  return c.u_in + lam * (c.u_out - c.u_in);
}

/// Samples of the field along the clip interval; the ends take the clip's
/// face values (canonical: neighbours agree), derivatives by inversion.
inline std::vector<RaySample> hex_ray_samples(Hex const& h, Ray const& r, Clip const& c, int m) {
  std::vector<RaySample> s(size_t(m) + 1);
  for (int i = 0; i <= m; ++i) {
    double const t = i == m ? c.t_out : c.t_in + (c.t_out - c.t_in) * i / m;
    s[size_t(i)] = hex_sample(h, r, t, i == 0 ? c.u_in : i == m ? c.u_out : hex_guess(c, t));
  }
  s.front().f = c.s_in;
  s.back().f = c.s_out;
  return s;
}

/// Bisection of (f(t) >= iso) between a and b (predicates differ at the
/// ends; `fa_pos` is the predicate at a), to machine precision.
inline double hex_bisect(Hex const& h, Ray const& r, Clip const& c, double a, double b, bool fa_pos,
                         double iso) {
  for (int k = 0; k < 200; ++k) {
    double const m = 0.5 * (a + b);
    if (m <= a || m >= b) break;
    RaySample const s = hex_sample(h, r, m, hex_guess(c, m));
    if ((s.f - iso >= 0) == fa_pos) a = m;
    else b = m;
  }
  return 0.5 * (a + b);
}

/// Every crossing of `iso` in the clip interval, ascending: a sign change
/// between samples bisected; each sample interval's Hermite cubic flags an
/// interior extremum across iso, evaluated exactly, so a root pair closer
/// than the sample spacing (a grazing ray) is still found.
inline void hex_crossings(Hex const& h, Ray const& r, Clip const& c,
                          std::vector<RaySample> const& s, double iso, std::vector<double>& out) {
  for (size_t i = 0; i + 1 < s.size(); ++i) {
    RaySample const& a = s[i];
    RaySample const& b = s[i + 1];
    if (std::isnan(a.f) || std::isnan(b.f)) continue;
    bool const pa = a.f - iso >= 0, pb = b.f - iso >= 0;
    if (pa != pb) {
      out.push_back(hex_bisect(h, r, c, a.t, b.t, pa, iso));
      continue;
    }
    // Same predicate at both ends: an interior extremum of the Hermite cubic
    // on the other side of iso hints at a root pair; check it exactly.
    double const len = b.t - a.t;
    double const f0 = a.f - iso, f1 = b.f - iso, g0 = a.df * len, g1 = b.df * len;
    // H(x) = f0 h00 + g0 h10 + f1 h01 + g1 h11; H'(x) = A x^2 + B x + C.
    double const A = 6 * f0 + 3 * g0 - 6 * f1 + 3 * g1, B = -6 * f0 - 4 * g0 + 6 * f1 - 2 * g1, C = g0;
    double xs[2];
    int nx = 0;
    if (A == 0) {
      if (B != 0) xs[nx++] = -C / B;
    } else {
      double const disc = B * B - 4 * A * C;
      if (disc >= 0) {
        double const q = -0.5 * (B + std::copysign(std::sqrt(disc), B));
        if (q != 0) xs[nx++] = C / q;
        xs[nx++] = q / A;
      }
    }
    double best_x = -1, best_v = 0;
    for (int k = 0; k < nx; ++k) {
      double const x = xs[k];
      if (!(x > 0 && x < 1)) continue;
      double const x2 = x * x, x3 = x2 * x;
      double const v = f0 * (2 * x3 - 3 * x2 + 1) + g0 * (x3 - 2 * x2 + x) + f1 * (-2 * x3 + 3 * x2) + g1 * (x3 - x2);
      if ((v >= 0) != pa && (best_x < 0 || std::abs(v) > std::abs(best_v))) best_x = x, best_v = v;
    }
    if (best_x < 0) continue;
    double const tm = a.t + best_x * len;
    RaySample const m = hex_sample(h, r, tm, hex_guess(c, tm));
    if (std::isnan(m.f) || (m.f - iso >= 0) == pa) continue;
    out.push_back(hex_bisect(h, r, c, a.t, tm, pa, iso));
    out.push_back(hex_bisect(h, r, c, tm, b.t, !pa, iso));
  }
}

/// What the reference renderer asks of a cell along one ray, per type (the
/// renderer itself never branches on the type): the clip, the field and its
/// gradient at t, every crossing of an isovalue, and where the field crosses
/// given values (the transfer function's control points) on [a, b].
template <int N> class FieldOnRay;

/// A tet's field is linear along the ray: everything from the clip exactly.
template <> class FieldOnRay<4> {
 public:
  /// `root_samples` is unused (a hex's sampling density for crossings).
  FieldOnRay(Tet const& c, Ray const& r, int /*root_samples*/ = 2) : c_(c), r_(r), k_(ref::clip(c, r)) {}
  Clip const& clip() const { return k_; }
  /// The value at t (on the clip's line) and the constant gradient; false never.
  bool at(double t, double& value, dvec3* grad) const {
    double const len = k_.t_out - k_.t_in;
    value = len > 0 ? k_.s_in + (t - k_.t_in) / len * (k_.s_out - k_.s_in) : k_.s_in;
    if (grad) *grad = gradient(c_);
    return true;
  }
  dvec3 gradient_at(double) const { return gradient(c_); }
  void crossings(double iso, std::vector<double>& out) const { out = ref::crossings(c_, r_, k_, iso); }
  /// Appends where the field crosses each of `values` strictly inside (a, b).
  void cuts(double a, double b, std::vector<float> const& values, std::vector<double>& out) const {
    double va, vb;
    at(a, va, nullptr), at(b, vb, nullptr);
    for (float cv : values) {
      double const v = double(cv);
      if ((v > va && v < vb) || (v < va && v > vb)) out.push_back(a + (v - va) / (vb - va) * (b - a));
    }
  }

 private:
  Tet c_;
  Ray r_;
  Clip k_;
};

/// A hex's field along the ray is not a polynomial in t in general: values
/// by inversion warm-started on the clip's parametric segment, crossings
/// from `root_samples` samples shared by every isovalue (hex_crossings),
/// control-value cuts from 8 samples bisected.
template <> class FieldOnRay<8> {
 public:
  FieldOnRay(Hex const& h, Ray const& r, int root_samples = 2)
      : h_(h), r_(r), k_(ref::clip(h, r)), root_samples_(std::max(2, root_samples)) {}
  Clip const& clip() const { return k_; }
  /// The value (and gradient) at t; false where the inversion fails.
  bool at(double t, double& value, dvec3* grad) const {
    dvec3 u = hex_guess(k_, t);
    if (!invert(h_, r_.o + t * r_.d, u)) {
      value = std::numeric_limits<double>::quiet_NaN();
      return false;
    }
    value = ref::value(h_, u);
    if (grad) *grad = gradient(h_, u);
    return true;
  }
  /// The analytic gradient at t; zero where the inversion fails.
  dvec3 gradient_at(double t) const {
    dvec3 u(0.5);
    if (k_.hit) u = hex_guess(k_, t);
    return invert(h_, r_.o + t * r_.d, u) ? gradient(h_, u) : dvec3(0);
  }
  void crossings(double iso, std::vector<double>& out) const {
    if (samples_.empty()) samples_ = hex_ray_samples(h_, r_, k_, root_samples_);
    hex_crossings(h_, r_, k_, samples_, iso, out);
  }
  /// Cuts where the sampled field crosses a control value; kinks between
  /// samples are left to the integrator's adaptive refinement.
  void cuts(double a, double b, std::vector<float> const& values, std::vector<double>& out) const {
    auto value = [&](double t) {
      double v = 0;
      at(t, v, nullptr);
      return v;
    };
    int const m = 8;
    double tp = a, vp = value(a);
    for (int i = 1; i <= m; ++i) {
      double const t = a + (b - a) * i / m, v = value(t);
      for (float cv : values) {
        double const c = double(cv);
        if (std::isnan(vp) || std::isnan(v) || !((c > vp && c < v) || (c < vp && c > v))) continue;
        double lo = tp, hi = t;
        bool const lo_below = vp < c;
        for (int it = 0; it < 60; ++it) {
          double const mid = 0.5 * (lo + hi);
          if (!(mid > lo && mid < hi)) break;
          if ((value(mid) < c) == lo_below) lo = mid;
          else hi = mid;
        }
        out.push_back(0.5 * (lo + hi));
      }
      tp = t, vp = v;
    }
  }

 private:
  Hex h_;
  Ray r_;
  Clip k_;
  int root_samples_;
  mutable std::vector<RaySample> samples_;
};

}  // namespace ref
}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
