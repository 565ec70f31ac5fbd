#pragma once
// The reference renderer: the same image model as render.hpp (camera rays
// through pixel centres, headlight Blinn-Phong, two-sided normals, shadows,
// ambient occlusion, up to 16 transparent layers; emission-absorption DVR
// with early termination), computed in double precision with exact methods,
// one ray at a time. Slow on purpose: it is the oracle the image tests and
// the accuracy charts compare the fast renderer against, and what
// `cellray-render --reference` draws. Baseline code (no SIMD, no ISA units),
// TBB-parallel over tiles.
//
// What "exact" means here:
// * Ray-cell intervals: cells/reference.hpp's double clips, same face models
//   as the fast path (tet planes, hex bilinear patches).
// * Isosurface roots: tets, the linear field's root between the clip's face
//   values (same hit rule as the fast path). Hexes, the field on the ray
//   itself (trilinear inversion, not a polynomial in t in general) sampled at
//   `hex_root_samples` points with its exact ray derivative; a sign change is
//   bisected to machine precision, and each sample interval's Hermite cubic
//   flags an interior extremum, evaluated exactly, so a root pair closer
//   than the sample spacing (a grazing ray) is still found.
// * Gradients: analytic (tet: constant; hex: J^-T grad_uvw at the hit).
// * DVR: the ray cut at every cell boundary, each cell segment cut again at
//   the transfer function's control values (tets: exactly, the value is
//   linear along the segment; hexes: where the sampled field crosses them),
//   and every piece integrated by adaptive Gauss-Legendre quadrature of the
//   emission-absorption equations with the extinction
//   sigma(v) = -ln(1 - a(v)) / unit_distance (the continuous limit of the
//   fast path's 1 - (1 - a)^(step / unit)). Early termination stops exactly
//   where the accumulated opacity reaches DvrParams::termination (the fast
//   path counts the step that crosses it only up to there, too).
//   Tolerance: the error estimate of each accepted interval is at most
//   `dvr_tolerance` x (interval length / scene diagonal), so a pixel's
//   estimated error is below `dvr_tolerance` (colour and opacity in [0, 1]);
//   tests/test_render_reference.cpp checks it by halving the tolerance.
// * DVR gradient shading (DvrShading): the same formula as the fast path,
//   with the exact gradient at every quadrature point (tet: constant; hex:
//   J^-T grad_uvw at the inverted point).
// NaN values: a cell with any NaN vertex value is invisible (as in the fast
// path). Degenerate (zero-volume) cells clip to nothing.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

#include "../cells/reference.hpp"
#include "render.hpp"

namespace cellray {

/// Knobs of the reference renderer (defaults: the accuracy the tests and
/// charts use; there is no reason to loosen them but speed).
struct ReferenceOptions {
  /// DVR: bound on the estimated error per pixel, colour and opacity in [0, 1].
  double dvr_tolerance = 1e-6;
  /// Hex isosurfaces: field samples per cell segment before bisection.
  int hex_root_samples = 64;
  /// Pixels per tile side (TBB work item).
  int tile_size = 16;
};

/// Differences between two images of the same size, in 8-bit units (the
/// clamped [0, 1] colours times 255, RGB only, not quantized).
struct ImageDiff {
  double rmse = 0;         ///< root mean square over every RGB channel
  double max = 0;          ///< largest channel difference
  double frac_over = 0;    ///< fraction of pixels with some channel off by more than `threshold`
  double threshold = 1;    ///< the threshold used, 8-bit units
  uint64_t nonfinite = 0;  ///< channels that are NaN or infinite in either image
};

/// Compares `a` to `b` (sizes must match). @throws InvalidArgument otherwise.
inline ImageDiff compare_images(Image const& a, Image const& b, double threshold = 1.0) {
  if (a.width != b.width || a.height != b.height) throw InvalidArgument("compare_images: image sizes differ");
  ImageDiff d;
  d.threshold = threshold;
  uint64_t const n = uint64_t(a.width) * uint64_t(a.height);
  double sum = 0;
  uint64_t over = 0;
  for (uint64_t i = 0; i < n; ++i) {
    double worst = 0;
    for (int c = 0; c < 3; ++c) {
      float const x = a.rgba[4 * i + uint64_t(c)], y = b.rgba[4 * i + uint64_t(c)];
      if (!std::isfinite(x) || !std::isfinite(y)) {
        ++d.nonfinite;
        worst = 255;
        continue;
      }
      double const e = 255.0 * std::abs(double(std::clamp(x, 0.f, 1.f)) - double(std::clamp(y, 0.f, 1.f)));
      sum += e * e;
      worst = std::max(worst, e);
    }
    d.max = std::max(d.max, worst);
    if (worst > threshold) ++over;
  }
  d.rmse = n ? std::sqrt(sum / double(3 * n)) : 0.0;
  d.frac_over = n ? double(over) / double(n) : 0.0;
  return d;
}

/// Reference isosurface image (see the file comment). Same parameters as
/// render_iso; `p.roots` and `p.normals` are ignored (always exact).
/// Thread-safe; runs on the calling thread's TBB arena.
/// @throws as render_iso for bad parameters or scenes.
Image render_iso_reference(Scene const& scene, Camera const& cam, IsoParams const& p, ReferenceOptions const& o = {});

/// Reference DVR image (see the file comment). Same parameters as
/// render_dvr; `step`, `group_size`, `mode` and `empty_space_skipping` are
/// ignored (the integral is computed to `o.dvr_tolerance`).
/// @throws as render_dvr for bad parameters or scenes.
Image render_dvr_reference(Scene const& scene, Camera const& cam, DvrParams const& p, ReferenceOptions const& o = {});

inline namespace CELLRAY_ISA_NS {
namespace ref_render {

using dvec3 = glm::dvec3;
constexpr double inf = std::numeric_limits<double>::infinity();

/// One part of the scene as the reference reads it: the fast path's (its
/// tree, mesh, gradients and colour array; face neighbours unused).
using Part = PreparedPart;

struct Setup {
  std::vector<Part> parts;
  double diagonal = 1;
  PreparedClip clip;  ///< the render's clip region (clip.hpp): the planes as the fast path has them
};

/// From the fast path's preparation (the same checks, clip and arrays).
inline Setup prepare(PreparedScene const& s) {
  Setup out;
  out.parts = s.parts;
  out.diagonal = double(s.diagonal);
  out.clip = s.clip;
  return out;
}

inline Setup prepare(Scene const& scene) { return prepare(render_detail::prepare(scene)); }

/// Shape-function weights of `cell` at `q` (exact location; mesh order),
/// for per-vertex quantities; false when the location fails.
template <int N>
inline bool weights_at(CellMesh<N> const& mesh, uint64_t cell, dvec3 const& q, double (&w)[N], uint64_t (&v)[N]) {
  ref::Cell<N> const c = ref::load(mesh, cell);
  ref::Location const L = ref::locate(c, q);
  if (!L.converged || !std::isfinite(L.param.x + L.param.y + L.param.z)) return false;
  for (int i = 0; i < N; ++i) v[i] = c.id[i];
  ref::shape_weights(c, L.param, w);
  return true;
}

/// The normalized camera ray through pixel centre (x, y), as the fast path
/// computes it (float direction, then normalized), in double.
inline ref::Ray camera_ray(Camera const& cam, int x, int y) {
  glm::vec3 const d = cam.direction(float(x), float(y));
  return {dvec3(cam.eye), glm::normalize(dvec3(d))};
}

/// Every cell (item-list slot) whose node boxes the ray meets in [t0, t1],
/// below nodes `keep(vmin, vmax)` accepts. Scalar double slab test, boxes
/// padded by a relative 1e-7 so rounding never drops a cell.
template <class Keep, class F>
inline void visit_cells(TreeView const& tree, ref::Ray const& r, double t0, double t1, Keep const& keep, F const& f) {
  if (tree.empty()) return;
  uint64_t stack[2 * MinMaxBvh::max_depth + 2];
  int sp = 0;
  stack[sp++] = 0;
  while (sp) {
    uint64_t const n = stack[--sp];
    Node const& node = tree.nodes[n];
    if (!keep(tree.ranges[2 * n], tree.ranges[2 * n + 1])) continue;
    double lo = t0, hi = t1;
    bool miss = false;
    for (int k = 0; k < 3 && !miss; ++k) {
      double const pad = 1e-7 * (std::abs(double(node.lo[k])) + std::abs(double(node.hi[k])) + 1e-30);
      double const a = double(node.lo[k]) - pad, b = double(node.hi[k]) + pad;
      if (r.d[k] == 0) {
        if (r.o[k] < a || r.o[k] > b) miss = true;
        continue;
      }
      double ta = (a - r.o[k]) / r.d[k], tb = (b - r.o[k]) / r.d[k];
      if (ta > tb) std::swap(ta, tb);
      lo = std::max(lo, ta), hi = std::min(hi, tb);
      if (lo > hi) miss = true;
    }
    if (miss) continue;
    if (node.is_leaf()) {
      for (uint64_t i = node.first_item(); i < node.first_item() + node.item_count(); ++i) f(tree.item(i));
    } else {
      stack[sp++] = node.right();
      stack[sp++] = node.left();
    }
  }
}

// -------------------------------------------------------------- isosurfaces

struct Crossing {
  double t;
  int iso;
  int part;
  uint64_t cell;
};

template <int N> inline bool cell_range(CellMesh<N> const& mesh, uint64_t cell, double& lo, double& hi) {
  lo = inf, hi = -inf;
  for (int k = 0; k < N; ++k) {
    float const v = mesh.value(mesh.vertex(cell, k));
    if (!std::isfinite(v)) return false;  // NaN and +-inf: an invisible cell
    lo = std::min(lo, double(v)), hi = std::max(hi, double(v));
  }
  return true;
}

/// Every crossing of any isovalue at t >= t_lo along r, sorted by t (ties:
/// lower isovalue index first).
inline void iso_crossings(Setup const& s, ref::Ray const& r, double t_lo, double t_hi, IsoParams const& p,
                          ReferenceOptions const& o, std::vector<Crossing>& out) {
  out.clear();
  auto keep = [&](float vmin, float vmax) {
    for (auto const& surf : p.surfaces)
      if (surf.value >= vmin && surf.value <= vmax) return true;
    return false;
  };
  std::vector<double> xs;
  for (size_t pi = 0; pi < s.parts.size(); ++pi) {
    Part const& part = s.parts[pi];
    part.visit([&](auto const& mesh, auto const*) {
      constexpr int N = std::decay_t<decltype(mesh)>::corners;
      visit_cells(part.tree, r, t_lo, t_hi, keep, [&](uint64_t cell) {
        double lo, hi;
        if (!cell_range(mesh, cell, lo, hi)) return;
        bool any = false;
        for (auto const& surf : p.surfaces) any = any || (surf.value >= lo && surf.value <= hi);
        if (!any) return;
        ref::FieldOnRay<N> const f(ref::load(mesh, cell), r, o.hex_root_samples);
        ref::Clip const& k = f.clip();
        if (!k.hit || k.t_out < t_lo || k.t_in > t_hi) return;
        for (size_t iso = 0; iso < p.surfaces.size(); ++iso) {
          double const v = double(p.surfaces[iso].value);
          if (!(v >= lo && v <= hi)) continue;
          xs.clear();
          f.crossings(v, xs);
          for (double t : xs)
            if (t >= t_lo && t <= t_hi) out.push_back({t, int(iso), int(pi), cell});
        }
      });
    });
  }
  std::sort(out.begin(), out.end(), [](Crossing const& a, Crossing const& b) {
    return a.t < b.t || (a.t == b.t && a.iso < b.iso);
  });
}

/// First crossing at t in [t_lo, t_hi], or nullptr.
inline bool first_crossing(Setup const& s, ref::Ray const& r, double t_lo, double t_hi, IsoParams const& p,
                           ReferenceOptions const& o, std::vector<Crossing>& scratch, Crossing& hit) {
  iso_crossings(s, r, t_lo, t_hi, p, o, scratch);
  if (scratch.empty()) return false;
  hit = scratch.front();
  return true;
}

/// Exact unit shading normal at a crossing, facing the ray origin; a zero
/// gradient gives -dir (as the fast path).
inline dvec3 exact_normal(Setup const& s, Crossing const& x, ref::Ray const& r) {
  Part const& part = s.parts[size_t(x.part)];
  dvec3 const p = r.o + x.t * r.d;
  dvec3 g(0);
  if (part.gradients) {  // smooth: the vertex gradients interpolated in the hit cell
    g = part.visit([&](auto const& mesh, auto const*) {
      constexpr int N = std::decay_t<decltype(mesh)>::corners;
      double w[N];
      uint64_t v[N];
      dvec3 sum(0);
      if (weights_at(mesh, x.cell, p, w, v))
        for (int i = 0; i < N; ++i)
          sum += w[i] * dvec3(part.gradients[3 * v[i]], part.gradients[3 * v[i] + 1], part.gradients[3 * v[i] + 2]);
      else
        sum = dvec3(std::numeric_limits<double>::quiet_NaN());
      return sum;
    });
    double const gg = glm::dot(g, g);
    if (gg > 0 && std::isfinite(gg)) {
      dvec3 n = glm::normalize(-g);
      return glm::dot(n, r.d) > 0 ? -n : n;
    }
    g = dvec3(0);  // as the fast path: the cell's analytic normal instead
  }
  g = part.visit([&](auto const& mesh, auto const*) {
    constexpr int N = std::decay_t<decltype(mesh)>::corners;
    return ref::FieldOnRay<N>(ref::load(mesh, x.cell), r).gradient_at(x.t);
  });
  double const gg = glm::dot(g, g);
  dvec3 n = gg > 0 && std::isfinite(gg) ? -g : -r.d;
  n = glm::normalize(n);
  if (glm::dot(n, r.d) > 0) n = -n;
  return n;
}

/// Colour by another array at a crossing: `base` becomes the colour map's
/// colour of the array interpolated in the hit cell (exactly), when finite.
inline bool part_color(Setup const& s, Crossing const& x, dvec3 const& q, dvec3& base, TransferFunction const& colors) {
  Part const& part = s.parts[size_t(x.part)];
  if (!part.color_values) return false;
  double const value = part.visit([&](auto const& mesh, auto const*) {
    constexpr int N = std::decay_t<decltype(mesh)>::corners;
    double w[N];
    uint64_t v[N];
    if (!weights_at(mesh, x.cell, q, w, v)) return std::numeric_limits<double>::quiet_NaN();
    double sum = 0;
    for (int i = 0; i < N; ++i) sum += w[i] * double(part.color_values[v[i]]);
    return sum;
  });
  if (!std::isfinite(value)) return false;
  base = colors.values.empty() ? dvec3(0.75) : dvec3(colors(float(value)));
  return true;
}

/// The field at `q` in the first cell (of any part) that holds it, by exact
/// point location; false outside the mesh and in NaN cells.
inline bool value_at(Setup const& s, dvec3 const& q, double& v) {
  ref::Ray const r{q, dvec3(1, 0, 0)};
  bool found = false;
  for (Part const& part : s.parts) {
    part.visit([&](auto const& mesh, auto const*) {
      visit_cells(part.tree, r, 0.0, 0.0, [](float, float) { return true; }, [&](uint64_t cell) {
        if (found) return;
        ref::Location const L = ref::locate(ref::load(mesh, cell), q);
        if (L.inside && std::isfinite(L.value)) v = L.value, found = true;
      });
    });
    if (found) return true;
  }
  return false;
}

/// Where a ray from a point inside the clip region leaves it (at most t1).
inline double clip_exit(Setup const& s, dvec3 const& o, dvec3 const& d, double t1) {
  double t0 = 0;
  int entry;
  clip_span(s.clip, o, d, t0, t1, entry);
  return t1;
}

inline void iso_pixel(Setup const& s, Camera const& cam, IsoParams const& p, ReferenceOptions const& o, int x, int y,
                      float* out) {
  ref::Ray const r = camera_ray(cam, x, y);
  double const eps = 1e-5 * s.diagonal;
  double const ao_radius = p.ao_radius > 0.f ? double(p.ao_radius) : 0.05 * s.diagonal;
  bool const headlight = !(glm::length(p.light_dir) > 0.f);
  dvec3 const light = headlight ? dvec3(0) : glm::normalize(dvec3(p.light_dir));
  auto background = [&](dvec3 const& color, double alpha) {
    dvec3 const c = color + (1 - alpha) * double(p.background.a) * dvec3(p.background);
    out[0] = float(c.x), out[1] = float(c.y), out[2] = float(c.z);
    out[3] = float(alpha + (1 - alpha) * double(p.background.a));
  };
  double t0 = 0, t1 = inf;
  int entry = -1;
  clip_span(s.clip, r.o, r.d, t0, t1, entry);
  if (!(t0 <= t1)) return background(dvec3(0), 0);
  double cap_value = 0;
  if (p.clip.caps && entry >= 0 && value_at(s, r.o + t0 * r.d, cap_value)) {
    dvec3 const n(s.clip.nx[entry], s.clip.ny[entry], s.clip.nz[entry]);
    dvec3 const to_l = headlight ? -r.d : light;
    double const ndl = std::max(0.0, glm::dot(n, to_l));
    double const ndh = std::max(0.0, glm::dot(n, glm::normalize(to_l - r.d)));
    double const spec = ndl > 0 ? double(p.specular) * std::pow(ndh, double(p.shininess)) : 0.0;
    glm::vec4 const cc = p.clip.cap_colors.values.empty() ? glm::vec4(0.75f) : p.clip.cap_colors(float(cap_value));
    dvec3 const c = glm::min(dvec3(cc) * (double(p.ambient) + double(p.diffuse) * ndl) + spec, 1.0);
    return background(c, 1);
  }
  std::vector<Crossing> all, scratch;
  iso_crossings(s, r, t0, t1, p, o, all);
  dvec3 color(0);
  double alpha = 0, tmin = t0;
  size_t next = 0;
  for (int layer = 0; layer < 16; ++layer) {
    while (next < all.size() && all[next].t < tmin) ++next;
    if (next >= all.size()) break;
    Crossing const hit = all[next];
    dvec3 const pos = r.o + hit.t * r.d;
    dvec3 const n = exact_normal(s, hit, r);
    dvec3 const ldir = headlight ? -r.d : light;
    IsoSurface const& surf = p.surfaces[size_t(hit.iso)];
    dvec3 base(surf.color);
    part_color(s, hit, pos, base, p.color_by.colors);
    double visibility = 1, occlusion = 0;
    if (p.shadows) {
      ref::Ray const sr{pos + eps * n, ldir};
      Crossing sh{};
      if (first_crossing(s, sr, eps, std::max(eps, clip_exit(s, sr.o, sr.d, inf)), p, o, scratch, sh))
        visibility = 1 - double(p.surfaces[size_t(sh.iso)].opacity);
    }
    for (int k = 0; k < p.ao_samples; ++k) {
      uint32_t const pix = uint32_t(y) * uint32_t(cam.width) + uint32_t(x);
      double const u1 = pixel_hash01(pix, uint32_t(2 * k + 64 * layer));
      double const u2 = pixel_hash01(pix, uint32_t(2 * k + 1 + 64 * layer));
      double const rr = std::sqrt(u1), phi = 6.283185307179586 * u2;
      dvec3 const a = std::abs(n.x) > 0.5 ? dvec3(0, 1, 0) : dvec3(1, 0, 0);
      dvec3 const tx = glm::normalize(glm::cross(a, n)), ty = glm::cross(n, tx);
      dvec3 const d = rr * std::cos(phi) * tx + rr * std::sin(phi) * ty + std::sqrt(std::max(0.0, 1 - u1)) * n;
      Crossing ah{};
      ref::Ray const ar{pos + eps * n, d};
      if (first_crossing(s, ar, eps, std::max(eps, clip_exit(s, ar.o, ar.d, ao_radius)), p, o, scratch, ah))
        occlusion += 1.0 / p.ao_samples;
    }
    dvec3 const v = -r.d;
    double const ndl = std::max(0.0, glm::dot(n, ldir));
    dvec3 const hv = glm::normalize(ldir + v);
    double const spec = ndl > 0 ? std::pow(std::max(0.0, glm::dot(n, hv)), double(p.shininess)) : 0.0;
    dvec3 const shade = base * (double(p.ambient) * (1 - occlusion) + double(p.diffuse) * ndl * visibility) +
                        dvec3(double(p.specular) * spec * visibility);
    double const a = double(surf.opacity) * (1 - alpha);
    color += a * shade;
    alpha += a;
    if (alpha >= 0.99) break;
    tmin = hit.t + std::max(eps, 1e-5 * hit.t);
  }
  background(color, alpha);
}

// ---------------------------------------------------------------------- DVR

/// The transfer function in double: colour and extinction per unit length.
struct TfEval {
  TransferFunction const* tf;
  double unit;

  /// rgb and sigma = -ln(1 - min(a, 0.999999)) / unit; NaN: transparent.
  void operator()(double v, double& r, double& g, double& b, double& sigma) const {
    auto const& vs = tf->values;
    auto const& cs = tf->rgba;
    if (std::isnan(v)) {
      r = g = b = sigma = 0;
      return;
    }
    double c[4];
    if (v <= double(vs.front())) {
      for (int k = 0; k < 4; ++k) c[k] = double(cs.front()[k]);
    } else if (v >= double(vs.back())) {
      for (int k = 0; k < 4; ++k) c[k] = double(cs.back()[k]);
    } else {
      size_t const i = size_t(std::upper_bound(vs.begin(), vs.end(), v, [](double x, float y) { return x < double(y); }) -
                              vs.begin());
      double const t = (v - double(vs[i - 1])) / (double(vs[i]) - double(vs[i - 1]));
      for (int k = 0; k < 4; ++k) c[k] = double(cs[i - 1][k]) + t * (double(cs[i][k]) - double(cs[i - 1][k]));
    }
    r = c[0], g = c[1], b = c[2];
    sigma = -std::log1p(-std::min(c[3], 0.999999)) / unit;
  }
};

/// Emission-absorption over an interval: colour emitted inside it
/// (attenuated inside it only) and optical depth.
struct Piece {
  double r = 0, g = 0, b = 0, tau = 0;
};

inline Piece combine(Piece const& a, Piece const& b) {
  double const T = std::exp(-a.tau);
  return {a.r + T * b.r, a.g + T * b.g, a.b + T * b.b, a.tau + b.tau};
}

/// 6-point Gauss-Legendre on [0, 1] and its integration matrix
/// S[i][j] = integral from 0 to x_i of the j-th Lagrange basis polynomial,
/// so tau(x_i) = h sum_j S[i][j] sigma_j (exact for sigma of degree <= 5).
struct Gauss6 {
  static constexpr int n = 6;
  double x[n], w[n], S[n][n];
  Gauss6() {
    double const xs[3] = {0.2386191860831969086305017, 0.6612093864662645136613996, 0.9324695142031520278123016};
    double const ws[3] = {0.4679139345726910473898703, 0.3607615730481386075698335, 0.1713244923791703450402961};
    for (int k = 0; k < 3; ++k) {
      x[2 - k] = 0.5 * (1 - xs[k]), w[2 - k] = 0.5 * ws[k];
      x[3 + k] = 0.5 * (1 + xs[k]), w[3 + k] = 0.5 * ws[k];
    }
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        double acc = 0;  // the same rule on [0, x_i] is exact for degree 5
        for (int q = 0; q < n; ++q) {
          double const s = x[q] * x[i], wq = w[q] * x[i];
          double L = 1;
          for (int m = 0; m < n; ++m)
            if (m != j) L *= (s - x[m]) / (x[j] - x[m]);
          acc += wq * L;
        }
        S[i][j] = acc;
      }
  }
};

inline Gauss6 const& gauss6() {
  static Gauss6 const g;
  return g;
}

/// DVR gradient shading in double (render.hpp, DvrShading; the same formula
/// as the fast path's shade_color).
struct ShadeEval {
  DvrShading sh;
  double inv_gradient_full;  ///< render_detail::inverse_gradient_full
  dvec3 d;                   ///< unit ray direction

  void operator()(dvec3 const& g, double& r, double& gr, double& b) const {
    double const len = glm::length(g);
    if (!(len > 0) || !std::isfinite(len)) return;
    double const ndl = std::min(1.0, std::abs(glm::dot(g, d)) / len);
    double const m = std::min(1.0, len * inv_gradient_full);
    double const lit = double(sh.ambient) + double(sh.diffuse) * ndl;
    double const spec = double(sh.specular) * std::pow(ndl, double(sh.shininess));
    r += m * (std::min(1.0, r * lit + spec) - r);
    gr += m * (std::min(1.0, gr * lit + spec) - gr);
    b += m * (std::min(1.0, b * lit + spec) - b);
  }
};

/// Integrates one smooth piece [a, b] to the tolerance `tol_per_length` x
/// length (see the file comment). `sample(t, r, g, b, sigma)` gives the
/// (shaded) colour and extinction at t.
template <class Sample> struct PieceIntegrator {
  Sample const& sample;
  double tol_per_length;

  Piece base(double a, double b) const {
    Gauss6 const& G = gauss6();
    double const h = b - a;
    double r[6], g[6], bl[6], sg[6];
    bool any = false;
    for (int i = 0; i < 6; ++i) {
      sample(a + G.x[i] * h, r[i], g[i], bl[i], sg[i]);
      any = any || sg[i] > 0;
    }
    Piece p;
    if (!any) return p;
    for (int i = 0; i < 6; ++i) {
      double tau_i = 0;
      for (int j = 0; j < 6; ++j) tau_i += G.S[i][j] * sg[j];
      double const wt = G.w[i] * sg[i] * std::exp(-h * tau_i) * h;
      p.r += wt * r[i], p.g += wt * g[i], p.b += wt * bl[i];
      p.tau += G.w[i] * sg[i] * h;
    }
    return p;
  }

  Piece adaptive(double a, double b, Piece const& whole, int depth) const {
    double const m = 0.5 * (a + b);
    Piece const L = base(a, m), R = base(m, b), both = combine(L, R);
    double const err = std::max({std::abs(whole.r - both.r), std::abs(whole.g - both.g), std::abs(whole.b - both.b),
                                 std::abs(std::exp(-whole.tau) - std::exp(-both.tau))});
    if (err <= tol_per_length * (b - a) || depth >= 48 || !(m > a && m < b)) return both;
    return combine(adaptive(a, m, L, depth + 1), adaptive(m, b, R, depth + 1));
  }

  Piece operator()(double a, double b) const { return adaptive(a, b, base(a, b), 0); }
};

/// Front-to-back accumulation along one ray with exact early termination.
struct Accum {
  double r = 0, g = 0, b = 0, T = 1;
  double stop_T;  ///< 1 - termination
  bool done() const { return T <= stop_T; }
};

/// Adds [a, b] to `acc`, stopping exactly where T reaches stop_T.
template <class Integ> inline void add_piece(Integ const& integ, double a, double b, Accum& acc) {
  if (!(b > a) || acc.done()) return;
  Piece const p = integ(a, b);
  double const T1 = acc.T * std::exp(-p.tau);
  if (T1 > acc.stop_T) {
    acc.r += acc.T * p.r, acc.g += acc.T * p.g, acc.b += acc.T * p.b, acc.T = T1;
    return;
  }
  // The termination point: bisection on the accumulated optical depth.
  double lo = a, hi = b;
  for (int k = 0; k < 60 && hi - lo > 1e-13 * (std::abs(a) + std::abs(b) + 1e-300); ++k) {
    double const m = 0.5 * (lo + hi);
    if (acc.T * std::exp(-integ(a, m).tau) > acc.stop_T) lo = m;
    else hi = m;
  }
  Piece const q = integ(a, hi);
  acc.r += acc.T * q.r, acc.g += acc.T * q.g, acc.b += acc.T * q.b;
  acc.T = acc.stop_T;
}

struct Segment {
  double t_in, t_out;
  int part;
  uint64_t cell;
};

inline void dvr_pixel(Setup const& s, Camera const& cam, DvrParams const& p, ReferenceOptions const& o, int x, int y,
                      std::vector<Segment>& segs, float* out) {
  ref::Ray const r = camera_ray(cam, x, y);
  TfEval const tf{&p.tf, double(p.tf.unit_distance)};
  // Exact culling only: a subtree whose values all map to zero opacity
  // contributes nothing (the field in a cell lies within its corner range).
  auto keep = [&](float vmin, float vmax) { return vmin <= vmax && p.tf.max_alpha(vmin, vmax) > 0.f; };
  segs.clear();
  double t0 = 0, t1 = inf;
  int entry = -1;
  clip_span(s.clip, r.o, r.d, t0, t1, entry);
  for (size_t pi = 0; pi < s.parts.size() && t0 < t1; ++pi) {
    Part const& part = s.parts[pi];
    part.visit([&](auto const& mesh, auto const*) {
      visit_cells(part.tree, r, t0, t1, keep, [&](uint64_t cell) {
        double lo, hi;
        if (!cell_range(mesh, cell, lo, hi) || !(p.tf.max_alpha(float(lo), float(hi)) > 0.f)) return;
        ref::Clip const k = ref::clip(ref::load(mesh, cell), r);
        if (k.hit && k.t_out > 0) segs.push_back({std::max(0.0, k.t_in), k.t_out, int(pi), cell});
      });
    });
  }
  std::sort(segs.begin(), segs.end(), [](Segment const& a, Segment const& b) { return a.t_in < b.t_in; });
  bool const shade = p.shading.enabled;
  ShadeEval const shading{p.shading, double(render_detail::inverse_gradient_full(p, float(s.diagonal))), r.d};
  Accum acc;
  acc.stop_T = 1 - double(p.termination);
  double const tol = o.dvr_tolerance / s.diagonal;
  double prev = t0;
  std::vector<double> cuts;
  for (Segment const& sg : segs) {
    if (acc.done()) break;
    double const a = std::max(sg.t_in, prev), b = std::min(sg.t_out, t1);
    if (!(b > a)) continue;
    prev = b;
    Part const& part = s.parts[size_t(sg.part)];
    cuts.assign({a, b});
    part.visit([&](auto const& mesh, auto const*) {
      constexpr int N = std::decay_t<decltype(mesh)>::corners;
      ref::FieldOnRay<N> const f(ref::load(mesh, sg.cell), r);
      // Cut where the field crosses a control value (tets: exactly, the
      // value is linear along the segment).
      f.cuts(a, b, p.tf.values, cuts);
      std::sort(cuts.begin(), cuts.end());
      auto sample = [&](double t, double& cr, double& cg, double& cb, double& sigma) {
        double v = 0;
        dvec3 grad;
        if (!f.at(t, v, shade ? &grad : nullptr)) {
          cr = cg = cb = sigma = 0;  // NaN value: transparent
          return;
        }
        tf(v, cr, cg, cb, sigma);
        if (shade) shading(grad, cr, cg, cb);
      };
      PieceIntegrator<decltype(sample)> const integ{sample, tol};
      for (size_t i = 0; i + 1 < cuts.size(); ++i) add_piece(integ, cuts[i], cuts[i + 1], acc);
    });
  }
  double const alpha = 1 - acc.T;
  double const rest = acc.T * double(p.background.a);
  out[0] = float(acc.r + rest * double(p.background.r));
  out[1] = float(acc.g + rest * double(p.background.g));
  out[2] = float(acc.b + rest * double(p.background.b));
  out[3] = float(alpha + rest);
}

template <class F> void for_tiles(Camera const& cam, int tile_size, F const& f) {
  int const ts = std::max(1, tile_size);
  int const nx = (cam.width + ts - 1) / ts, ny = (cam.height + ts - 1) / ts;
  tbb::parallel_for(tbb::blocked_range2d<int>(0, ny, 1, 0, nx, 1), [&](tbb::blocked_range2d<int> const& r) {
    for (int ty = r.rows().begin(); ty < r.rows().end(); ++ty)
      for (int tx = r.cols().begin(); tx < r.cols().end(); ++tx)
        f(tx * ts, ty * ts, std::min(cam.width, (tx + 1) * ts), std::min(cam.height, (ty + 1) * ts));
  });
}

}  // namespace ref_render
}  // namespace CELLRAY_ISA_NS

inline Image render_iso_reference(Scene const& scene, Camera const& cam, IsoParams const& p,
                                  ReferenceOptions const& o) {
  render_detail::check_camera(cam);
  render_detail::check_iso(p);
  PreparedScene const prepared = render_detail::prepare_iso(scene, p);  // the fast path's checks and arrays
  ref_render::Setup const s = ref_render::prepare(prepared);
  Image img(cam.width, cam.height);
  ref_render::for_tiles(cam, o.tile_size, [&](int x0, int y0, int x1, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) ref_render::iso_pixel(s, cam, p, o, x, y, img.pixel(x, y));
  });
  return img;
}

inline Image render_dvr_reference(Scene const& scene, Camera const& cam, DvrParams const& p,
                                  ReferenceOptions const& o) {
  render_detail::check_camera(cam);
  render_detail::DvrSetup checked;  // the fast path's parameter checks
  render_detail::prepare_dvr(scene, p, checked);
  if (!(o.dvr_tolerance > 0)) throw InvalidArgument("reference DVR tolerance must be positive");
  ref_render::Setup const s = ref_render::prepare(checked.scene);
  Image img(cam.width, cam.height);
  ref_render::for_tiles(cam, o.tile_size, [&](int x0, int y0, int x1, int y1) {
    std::vector<ref_render::Segment> segs;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) ref_render::dvr_pixel(s, cam, p, o, x, y, segs, img.pixel(x, y));
  });
  return img;
}

}  // namespace cellray
