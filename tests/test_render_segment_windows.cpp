// Cell-segment DVR when a window holds more cells than a ray's segment list
// (traverse/segments.hpp, max_segments): the window is cut at the first cell
// that did not fit and the next one starts there. Before this test, a wrong
// cut could send the next window backwards and a render never finished
// (component8_heat_608k); now it must finish and match the reference.

#include <catch2/catch.hpp>

#include <cstdio>

#include <glm/glm.hpp>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/reference.hpp>

#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_segment_windows {

using namespace cellray;

TEST_CASE("DVR segments with more cells per window than a segment list holds match the reference",
          "[render][dvr][isa]") {
  auto const gen = generate_tets(60000);  // ~40 cubes per axis: ~100 cells along a diagonal ray
  TetMesh const mesh = gen.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  Scene const scene(mesh, bvh);
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  float const diag = glm::length(hi - lo);
  // Looking along the diagonal, so rays cross many cells.
  Camera const cam = Camera::look_at(hi + 0.9f * (hi - lo), 0.5f * (lo + hi), glm::vec3(0, 1, 0), 30.f, 40, 40);
  DvrParams p;
  p.tf = transfer_function_preset("viridis", 0.f, 1.f);
  for (auto& c : p.tf.rgba) c.a = 0.02f;  // faint everywhere: no ray terminates early
  p.tf.unit_distance = diag / 10.f;
  p.mode = DvrMode::segments;
  p.group_size = 32;
  p.step = diag / 4.f;  // the first window (32 steps) spans the whole mesh
  RenderOptions o;
  o.isa = test::isa();
  Image const fast = render_dvr(scene, cam, p, o);
  Image const ref = render_dvr_reference(scene, cam, p);
  ImageDiff const d = compare_images(fast, ref);
  std::printf("  segments, whole mesh in one window: rmse %.4f max %.2f (8-bit)\n", d.rmse, d.max);
  // The step only sets the midpoint-rule pieces; at diag/4 most cells are
  // one piece, an error of a few 1/255 at most (docs/accuracy.md, d125).
  CHECK(d.rmse < 1.0);
  CHECK(d.max < 4.0);
}

}  // namespace test_render_segment_windows
