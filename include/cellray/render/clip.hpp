#pragma once
// Clipping: what a render keeps of the scene is the intersection of
// half-spaces (clip planes; a clip box is six). Rays start and end where they
// enter and leave that region, so the inside shows (ParaView's Clip with a
// volume). One mechanism for a user's clip planes and box and for a
// distributed render's region (issue #22): both are convex regions.
//
// Isosurfaces: a ray starts at its region entry; with `caps` the cut face
// itself is drawn where it lies inside the mesh, coloured by the field
// through `cap_colors` (opaque, Lambert-shaded with the plane's normal).
// DVR: each ray integrates only the part inside the region (the cut face is
// where the volume starts: no cap needed). Shadow and ambient-occlusion rays
// are clipped too: the part cut away casts no shadow.

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "../error.hpp"
#include "transfer_function.hpp"

namespace cellray {

/// One plane through `point`; the render keeps the points p with
/// dot(normal, p - point) <= 0: the normal points into the part cut away.
/// `normal` need not be unit length (it is normalised), but must not be zero.
struct ClipPlane {
  glm::vec3 point{0.f};
  glm::vec3 normal{0.f, 0.f, 1.f};
};

/// The six planes that keep the box [lo, hi].
inline std::vector<ClipPlane> clip_box(glm::vec3 const& lo, glm::vec3 const& hi) {
  return {{lo, {-1.f, 0.f, 0.f}}, {hi, {1.f, 0.f, 0.f}}, {lo, {0.f, -1.f, 0.f}},
          {hi, {0.f, 1.f, 0.f}},  {lo, {0.f, 0.f, -1.f}}, {hi, {0.f, 0.f, 1.f}}};
}

/// What a render keeps. Empty (no planes): everything. A render parameter:
/// changing it never rebuilds or refits anything.
struct Clip {
  static constexpr int max_planes = 16;
  std::vector<ClipPlane> planes;  ///< kept: the intersection of their kept sides
  /// Isosurfaces: draw the cut faces where they lie inside the mesh,
  /// coloured by the field there through `cap_colors` (DVR ignores this).
  bool caps = false;
  /// Colours of the caps over the field's values (alpha ignored). Empty: grey.
  TransferFunction cap_colors;

  bool empty() const { return planes.empty(); }

  /// @throws InvalidArgument for more than max_planes planes, a zero or
  /// non-finite normal or a non-finite point, or a bad cap colour map.
  void check() const {
    if (planes.size() > size_t(max_planes))
      throw InvalidArgument("at most " + std::to_string(max_planes) + " clip planes, got " + std::to_string(planes.size()));
    for (size_t i = 0; i < planes.size(); ++i) {
      ClipPlane const& p = planes[i];
      float const len = glm::length(p.normal);
      if (!(len > 0.f) || !std::isfinite(len) || !std::isfinite(p.point.x + p.point.y + p.point.z))
        throw InvalidArgument("clip plane " + std::to_string(i) + " needs a finite point and a nonzero finite normal");
    }
    if (caps && !cap_colors.values.empty()) cap_colors.check();
  }
};

/// The clip planes as the renderer uses them (unit normal n, kept n.p <= d)
/// and the cap colours as a table: plain data the ISA units read.
struct PreparedClip {
  int count = 0;
  float nx[Clip::max_planes] = {}, ny[Clip::max_planes] = {}, nz[Clip::max_planes] = {}, d[Clip::max_planes] = {};
  bool caps = false;
  ColorTable cap_colors;  ///< grey without a colour map

  /// From a checked Clip (which must outlive this).
  static PreparedClip from(Clip const& c) {
    PreparedClip out;
    out.count = int(c.planes.size());
    for (int i = 0; i < out.count; ++i) {
      glm::vec3 const n = glm::normalize(c.planes[size_t(i)].normal);
      out.nx[i] = n.x, out.ny[i] = n.y, out.nz[i] = n.z;
      out.d[i] = glm::dot(n, c.planes[size_t(i)].point);
    }
    out.caps = c.caps;
    if (c.caps) out.cap_colors = ColorTable::of(c.cap_colors, glm::vec3(0.75f));
    return out;
  }
};

/// The part [t0, t1] of the ray o + t d inside the region of `c` (its
/// prepared planes), narrowed from the given [t0, t1]; `entry` becomes the
/// index of the plane the ray enters through at t0 (-1: t0 was not moved).
/// Empty when t0 > t1. Double precision: the reference renderer's version.
inline void clip_span(PreparedClip const& c, glm::dvec3 const& o, glm::dvec3 const& d, double& t0, double& t1,
                      int& entry) {
  entry = -1;
  for (int i = 0; i < c.count; ++i) {
    glm::dvec3 const n(c.nx[i], c.ny[i], c.nz[i]);
    double const s = glm::dot(n, d), q = glm::dot(n, o) - double(c.d[i]);
    if (s == 0) {
      if (q > 0) t0 = std::numeric_limits<double>::infinity();
      continue;
    }
    double const t = -q / s;
    if (s < 0 && t > t0) t0 = t, entry = i;
    if (s > 0 && t < t1) t1 = t;
  }
}

}  // namespace cellray
