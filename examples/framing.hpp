#pragma once
// cellray-render's default view: the camera distance that makes a box's
// perspective projection span a given fraction of the image's shorter side,
// from a direction given by azimuth and elevation about the box's centre
// (ParaView's "Reset Camera" fits the bounding sphere, which leaves a long
// part small: component8 filled a third of the width).

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <cellray/render/camera.hpp>

namespace cellray_render {

/// The default view direction, from the look-at point towards the eye: the
/// fixed oblique view of `fit_camera`, turned by `azimuth_deg` about +y
/// (positive: counter-clockwise seen from above) and raised by
/// `elevation_deg` towards +y. The elevation is clamped to [-89, 89] degrees
/// so that +y stays a usable up vector.
inline glm::dvec3 view_direction(double azimuth_deg, double elevation_deg) {
  constexpr double deg = 3.14159265358979323846 / 180.0;
  glm::dvec3 const d0 = glm::normalize(glm::dvec3(0.55, 0.45, 1.0));
  double const az = std::atan2(d0.x, d0.z) + azimuth_deg * deg;
  double const el = std::clamp(std::asin(d0.y) / deg + elevation_deg, -89.0, 89.0) * deg;
  return {std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az)};
}

/// A view of the box [lo, hi] from direction `dir` (unit, from the box
/// towards the eye) at distance `dist` from its centre, moved sideways in
/// the image plane so that the box's projected corners are centred in the
/// image (perspective draws the near corners larger: without it a long part
/// seen obliquely runs off one side). Up is +y.
struct BoxView {
  glm::dvec3 eye, at;
  double extent_px;  ///< max(horizontal, vertical) span of the projected corners; infinite if one is behind the eye
};

/// The value `a` in [a0, a1] where the decreasing function `f` crosses 0.
template <class F> double bisect_root(F const& f, double a0, double a1) {
  for (int i = 0; i < 100; ++i) {
    double const mid = 0.5 * (a0 + a1);
    (f(mid) > 0.0 ? a0 : a1) = mid;
  }
  return 0.5 * (a0 + a1);
}

inline BoxView centred_view(glm::dvec3 lo, glm::dvec3 hi, glm::dvec3 dir, double dist, double fov_deg, int width,
                            int height) {
  glm::dvec3 const centre = 0.5 * (lo + hi), eye = centre + dir * dist;
  glm::dvec3 const forward = -dir;
  glm::dvec3 const right = glm::normalize(glm::cross(forward, glm::dvec3(0, 1, 0)));
  glm::dvec3 const up = glm::cross(right, forward);
  double const t = std::tan(0.5 * fov_deg * 3.14159265358979323846 / 180.0);
  double const aspect = double(width) / double(height);
  // Moving the eye by a * right + b * up keeps every corner's depth z:
  // u = (x - a) / (z t aspect), v = (y - b) / (z t), so a and b centre u and
  // v independently, each a decreasing function.
  double x[8], y[8], z[8];
  for (int c = 0; c < 8; ++c) {
    glm::dvec3 const r = glm::dvec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z) - eye;
    x[c] = glm::dot(r, right), y[c] = glm::dot(r, up), z[c] = glm::dot(r, forward);
    if (!(z[c] > 0.0)) return {eye, centre, HUGE_VAL};
  }
  auto span = [&](double const* q, double shift, double scale, double& mid) {
    double mn = HUGE_VAL, mx = -HUGE_VAL;
    for (int c = 0; c < 8; ++c) {
      double const u = (q[c] - shift) / (z[c] * scale);
      mn = std::min(mn, u), mx = std::max(mx, u);
    }
    mid = 0.5 * (mn + mx);
    return mx - mn;
  };
  auto centring = [&](double const* q, double scale) {
    double lo_q = q[0], hi_q = q[0];
    for (int c = 1; c < 8; ++c) lo_q = std::min(lo_q, q[c]), hi_q = std::max(hi_q, q[c]);
    return bisect_root(
        [&](double s) {
          double mid = 0;
          span(q, s, scale, mid);
          return mid;
        },
        lo_q, hi_q);
  };
  double const a = centring(x, t * aspect), b = centring(y, t);
  double mid = 0;
  double const su = span(x, a, t * aspect, mid), sv = span(y, b, t, mid);
  glm::dvec3 const shift = a * right + b * up;
  return {eye + shift, centre + shift, std::max(0.5 * su * width, 0.5 * sv * height)};
}

/// The distance from the box's centre along `dir` at which its centred
/// projection (`centred_view`) spans `fill` times the shorter image side;
/// bisection in double (the span falls as the eye moves away). A flat or
/// point-like box counts as one of size 1e-6 of its coordinates, or 1e-30.
inline double fit_distance(glm::dvec3 lo, glm::dvec3 hi, glm::dvec3 dir, double fill, double fov_deg, int width,
                           int height) {
  glm::dvec3 const centre = 0.5 * (lo + hi);
  double const floor_size = std::max(1e-6 * std::max(glm::length(lo), glm::length(hi)), 1e-30);
  if (!(glm::length(hi - lo) > floor_size)) {
    lo = centre - glm::dvec3(0.5 * floor_size);
    hi = centre + glm::dvec3(0.5 * floor_size);
  }
  double const target = fill * double(std::min(width, height));
  auto extent = [&](double d) { return centred_view(lo, hi, dir, d, fov_deg, width, height).extent_px; };
  // Nearest: the corner farthest along dir is in the eye's plane.
  double near = 0.0;
  for (int c = 0; c < 8; ++c)
    near = std::max(near, glm::dot(glm::dvec3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z) - centre, dir));
  double far = std::max(2.0 * near, glm::length(hi - lo));
  for (int i = 0; i < 200 && extent(far) > target; ++i) far *= 2.0;
  for (int i = 0; i < 100; ++i) {
    double const mid = 0.5 * (near + far);
    (extent(mid) > target ? near : far) = mid;
  }
  return far;
}

/// The camera of `centred_view`.
inline cellray::Camera box_camera(glm::dvec3 lo, glm::dvec3 hi, glm::dvec3 dir, double dist, float fov_deg,
                                  int width, int height) {
  BoxView const v = centred_view(lo, hi, dir, dist, fov_deg, width, height);
  return cellray::Camera::look_at(glm::vec3(v.eye), glm::vec3(v.at), glm::vec3(0.f, 1.f, 0.f), fov_deg, width, height);
}

/// `p` turned by `deg` degrees about the vertical (+y) axis through `centre`
/// (the same sense as the azimuth of `view_direction`).
inline glm::vec3 turn_about_y(glm::vec3 p, glm::vec3 centre, double deg) {
  double const a = deg * 3.14159265358979323846 / 180.0;
  double const c = std::cos(a), s = std::sin(a);
  glm::dvec3 const r = glm::dvec3(p) - glm::dvec3(centre);
  return glm::vec3(glm::dvec3(c * r.x + s * r.z, r.y, -s * r.x + c * r.z) + glm::dvec3(centre));
}

}  // namespace cellray_render
