#pragma once
// The pinhole camera shared with the peer measurements (DESIGN.md): eye,
// look-at point, up vector, vertical field of view in degrees, width x height;
// pixel (0,0) is the top-left; rays go through pixel centres; right-handed.

#include <cmath>
#include <string>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "../error.hpp"

namespace cellray {

struct Camera {
  glm::vec3 eye{0.f, 0.f, 3.f};
  glm::vec3 forward{0.f, 0.f, -1.f};  ///< unit, towards the look-at point
  glm::vec3 right{1.f, 0.f, 0.f};     ///< unit, image +x
  glm::vec3 up{0.f, 1.f, 0.f};        ///< unit, image -y (row 0 is the top)
  float tan_half_fov = 0.41421356f;   ///< tan(vertical fov / 2)
  int width = 1, height = 1;          ///< pixels, >= 1

  /// @param fov_deg vertical field of view, in (0, 180) degrees.
  /// @throws InvalidArgument for a zero-size image, a fov out of range, eye
  ///         equal to `at`, or `up` parallel to the view direction.
  static Camera look_at(glm::vec3 eye, glm::vec3 at, glm::vec3 up, float fov_deg, int width, int height) {
    if (width < 1 || height < 1)
      throw InvalidArgument("image size " + std::to_string(width) + "x" + std::to_string(height) +
                            ": both must be at least 1");
    if (!(fov_deg > 0.f && fov_deg < 180.f))
      throw InvalidArgument("field of view " + std::to_string(fov_deg) + " degrees: must be in (0, 180)");
    glm::vec3 const d = at - eye;
    if (!(glm::length(d) > 0.f) || !std::isfinite(glm::length(d)))
      throw InvalidArgument("camera eye and look-at point must differ and be finite");
    Camera c;
    c.eye = eye;
    c.forward = glm::normalize(d);
    glm::vec3 const r = glm::cross(c.forward, up);
    if (!(glm::length(r) > 1e-6f * glm::length(up)))
      throw InvalidArgument("camera up vector is zero or parallel to the view direction");
    c.right = glm::normalize(r);
    c.up = glm::cross(c.right, c.forward);
    c.tan_half_fov = std::tan(fov_deg * 0.5f * 3.14159265358979f / 180.f);
    c.width = width;
    c.height = height;
    return c;
  }

  /// Unnormalized direction through the centre of pixel (x, y); x may be
  /// fractional (sub-pixel positions for tests).
  glm::vec3 direction(float x, float y) const {
    float const aspect = float(width) / float(height);
    float const u = ((x + 0.5f) / float(width) * 2.f - 1.f) * tan_half_fov * aspect;
    float const v = (1.f - (y + 0.5f) / float(height) * 2.f) * tan_half_fov;
    return forward + u * right + v * up;
  }
};

/// A camera framing the box [lo, hi] from a fixed oblique direction (the
/// example renderer's default view): the bounding sphere fits the vertical fov.
inline Camera fit_camera(glm::vec3 lo, glm::vec3 hi, int width, int height, float fov_deg = 30.f) {
  glm::vec3 const centre = 0.5f * (lo + hi);
  float const radius = std::max(0.5f * glm::length(hi - lo), 1e-30f);
  glm::vec3 const dir = glm::normalize(glm::vec3(0.55f, 0.45f, 1.0f));
  float const half = 0.5f * fov_deg * 3.14159265358979f / 180.f;
  float const aspect_fix = std::max(1.f, float(height) / float(width));
  float const dist = radius * aspect_fix / std::sin(half) * 1.02f;
  return Camera::look_at(centre + dir * dist, centre, glm::vec3(0.f, 1.f, 0.f), fov_deg, width, height);
}

}  // namespace cellray
