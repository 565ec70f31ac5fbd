#pragma once
// Plain ray and result types shared by baseline callers and the ISA units.

#include <cstdint>
#include <limits>

#include <glm/vec3.hpp>

namespace cellray {

/// A ray `org + t * dir` for t in [tmin, tmax]. `dir` need not be unit
/// length; every t is in units of `dir`. 32 bytes.
struct Ray {
  glm::vec3 org;
  float tmin = 0.f;
  glm::vec3 dir;
  float tmax = std::numeric_limits<float>::infinity();
};

/// How W rays go through the tree (Rathke 2015 §5.5; hybrid is its future work).
enum class Traversal {
  packet,  ///< W rays visit each node together, one shared stack
  spmd,    ///< every lane its own stack
  hybrid,  ///< packet until fewer than a threshold of lanes stay active, then one ray at a time
};

inline constexpr char const* traversal_name(Traversal t) {
  return t == Traversal::packet ? "packet" : t == Traversal::spmd ? "spmd" : "hybrid";
}

/// The nearest isosurface crossing of one ray.
struct SurfaceHit {
  float t = std::numeric_limits<float>::infinity();  ///< inf: no hit in [tmin, tmax]
  int32_t iso = -1;                                   ///< index into the isovalue list
  uint32_t piece = 0;                                 ///< mesh the cell belongs to
  uint64_t cell = ~uint64_t(0);                       ///< cell id within its mesh
  glm::vec3 normal{0.f};  ///< unit, faces the ray origin (shading normal)
  bool hit() const { return t < std::numeric_limits<float>::infinity(); }
};

/// One cell a ray crosses: the ray is inside `cell` for t in [t_in, t_out].
struct CellSegment {
  float t_in, t_out;
  float v_in, v_out;  ///< scalar at the entry and exit points
  uint32_t piece;
  uint64_t cell;
};

}  // namespace cellray
