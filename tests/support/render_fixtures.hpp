#pragma once
// Scene set-up and image-comparison helpers shared by the render tests that
// compare the fast renderer with the double-precision reference
// (test_render_dvr.cpp, test_render_reference.cpp).

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <cellray/bvh/build.hpp>
#include <cellray/render/reference.hpp>

#include "support/test_isa.hpp"

namespace cellray::test {

/// A mesh with its tree, kept alive together with the scene that views them
/// (heap-allocated so the scene's pointers stay valid when the holder moves).
template <int N> struct Loaded {
  CellMesh<N> mesh;
  MinMaxBvh bvh;
  Scene scene() const { return Scene(mesh, bvh); }
};

/// Builds the default BVH over `m` (a view: its arrays must outlive the result).
template <int N> std::unique_ptr<Loaded<N>> load(CellMesh<N> const& m) {
  auto l = std::make_unique<Loaded<N>>(Loaded<N>{m, {}});
  l->bvh = build_minmax_bvh(l->mesh);
  return l;
}

/// sin(3x) + y^2 + z/2 at each vertex of `xyz` (3 floats a vertex): a
/// curved field with isosurfaces across the gmsh test meshes (tests/data/gmsh).
inline std::vector<float> curved_field(std::vector<float> const& xyz) {
  std::vector<float> field(xyz.size() / 3);
  for (size_t v = 0; v < field.size(); ++v) {
    float const* q = &xyz[3 * v];
    field[v] = std::sin(3.f * q[0]) + q[1] * q[1] + 0.5f * q[2];
  }
  return field;
}

/// A `w` x `h` camera that frames the whole scene.
inline Camera camera_for(Scene const& s, int w, int h) {
  glm::vec3 lo, hi;
  s.bounds(lo, hi);
  return fit_camera(lo, hi, w, h);
}

/// Length of the scene's bounding-box diagonal (world units).
inline float diagonal(Scene const& s) {
  glm::vec3 lo, hi;
  s.bounds(lo, hi);
  return glm::length(hi - lo);
}

/// Opacity over the whole range [vmin, vmax] with kinks, colour changing
/// everywhere, so every part of the DVR model is exercised (the accuracy
/// sweep's transfer function, bench/bench_accuracy.cpp). `unit` is the
/// transfer function's unit distance.
inline TransferFunction busy_tf(float vmin, float vmax, float unit) {
  TransferFunction tf;
  float const k[6] = {0.f, 0.2f, 0.4f, 0.6f, 0.8f, 1.f};
  float const a[6] = {0.05f, 0.3f, 0.1f, 0.6f, 0.2f, 0.9f};
  for (int i = 0; i < 6; ++i) {
    tf.values.push_back(vmin + k[i] * (vmax - vmin));
    tf.rgba.emplace_back(0.2f + 0.7f * k[i], 0.9f - 0.6f * k[i], 0.5f + 0.4f * std::sin(6.f * k[i]), a[i]);
  }
  tf.unit_distance = unit;
  return tf;
}

/// Prints one line of an image comparison (8-bit units) to the test log.
inline void report(std::string const& what, ImageDiff const& d) {
  std::printf("  %-58s rmse %.4f  max %.2f  >%.0f/255: %.3f%%\n", what.c_str(), d.rmse, d.max, d.threshold,
              100.0 * d.frac_over);
}

/// Render options for the ISA under test (`--isa=`), everything else default.
inline RenderOptions isa_options() {
  RenderOptions o;
  o.isa = isa();
  return o;
}

}  // namespace cellray::test
