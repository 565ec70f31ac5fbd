// Clip planes and boxes (render/clip.hpp, issue #25): isosurfaces (with and
// without caps, shadows and AO) and DVR (samples, segments through the tree
// and marching) of clipped tet and hex meshes against the double reference
// with the same clip, on every ISA; a clip that keeps everything changes
// nothing; one that keeps nothing leaves the background.

#include <catch2/catch.hpp>

#include <cmath>
#include <string>
#include <vector>

#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>

#include "support/render_fixtures.hpp"
#include "support/sanitized.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_clip {

using namespace cellray;

using test::busy_tf;
using test::camera_for;
using test::diagonal;
using test::report;

namespace {

constexpr int frame = test::full_or_sanitized(64, 40);

/// A plane through the scene's centre facing the camera a little sideways,
/// and a box over the lower-left-front part: both cut through the isosurfaces.
Clip cut(Scene const& scene, bool box, bool caps) {
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  glm::vec3 const c = 0.5f * (lo + hi);
  Clip clip;
  if (box) clip.planes = clip_box(lo - 0.1f * (hi - lo), c + 0.15f * (hi - lo));
  else clip.planes = {{c, glm::vec3(0.55f, 0.45f, 1.0f)}};  // the default camera's side is cut away
  clip.caps = caps;
  if (caps) clip.cap_colors = transfer_function_preset("viridis", 0.f, 1.f);
  return clip;
}

double fraction_differing(Image const& a, Image const& b) {
  size_t n = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4)
    for (int k = 0; k < 4; ++k)
      if (std::fabs(a.rgba[i + size_t(k)] - b.rgba[i + size_t(k)]) > 2.f / 255.f) {
        ++n;
        break;
      }
  return double(n) / double(a.rgba.size() / 4);
}

template <int N> void check_clipped(CellMesh<N> const& mesh, std::string const& what) {
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  TetNeighbours nb;
  Scene scene(mesh, bvh);
  if constexpr (N == 4) {
    nb = build_tet_neighbours(mesh);
    scene = Scene(mesh, bvh, nullptr, &nb);
  }
  Camera const cam = camera_for(scene, frame, frame);
  RenderOptions const ro = test::isa_options();

  IsoParams ip;
  ip.surfaces = {{0.35f, {0.9f, 0.7f, 0.4f}, 0.5f}, {0.55f, {0.4f, 0.6f, 0.9f}, 1.f}};
  Image const whole = render_iso(scene, cam, ip, ro);
  for (bool box : {false, true})
    for (bool caps : {false, true}) {
      std::string const name = what + (box ? ", clip box" : ", clip plane") + (caps ? " + caps" : "");
      ip.clip = cut(scene, box, caps);
      ip.shadows = !caps, ip.ao_samples = caps ? 0 : 2;
      ip.light_dir = ip.shadows ? glm::vec3(0.3f, 1.f, 0.5f) : glm::vec3(0.f);
      Image const fast = render_iso(scene, cam, ip, ro);
      ImageDiff const d = compare_images(fast, render_iso_reference(scene, cam, ip), 2.0);
      report(name + ": iso vs reference", d);
      CHECK(d.nonfinite == 0);
      CHECK(d.frac_over <= 0.005);
      CHECK(fraction_differing(fast, whole) > 0.05);  // the clip shows
    }

  DvrParams dp;
  dp.tf = busy_tf(0.1f, 0.9f, diagonal(scene) / 8.f);
  dp.step = diagonal(scene) / 1000.f;
  for (bool box : {false, true}) {
    dp.clip = cut(scene, box, false);
    dp.mode = DvrMode::segments;
    Image const ref = render_dvr_reference(scene, cam, dp);
    for (DvrMode m : {DvrMode::samples, DvrMode::segments}) {
      dp.mode = m;
      std::string const name = what + (box ? ", clip box" : ", clip plane") +
                               (m == DvrMode::samples ? ": DVR samples" : ": DVR segments");
      ImageDiff const d = compare_images(render_dvr(scene, cam, dp, ro), ref, 2.0);
      report(name + " vs reference", d);
      CHECK(d.nonfinite == 0);
      CHECK(d.frac_over <= 0.005);
    }
    if constexpr (N == 4) {  // the same through the tree alone
      dp.mode = DvrMode::segments;
      ImageDiff const d = compare_images(render_dvr(Scene(mesh, bvh), cam, dp, ro), ref, 2.0);
      report(what + (box ? ", clip box" : ", clip plane") + ": DVR segments, tree only, vs reference", d);
      CHECK(d.frac_over <= 0.005);
    }
  }
}

}  // namespace

TEST_CASE("clip planes and boxes: iso (caps, shadows, AO) and DVR against the reference", "[render][clip][isa]") {
  auto const t = generate_tets(6 * 9 * 9 * 9, 2);
  check_clipped(t.mesh(), "tets");
  auto const h = generate_hexes(9 * 9 * 9, 2, 0.15f);
  check_clipped(h.mesh(), "hexes");
}

TEST_CASE("a clip keeping everything changes nothing -- one keeping nothing leaves the background",
          "[render][clip][isa]") {
  auto const g = generate_tets(6 * 6 * 6 * 6, 3);
  TetMesh const mesh = g.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  Scene const scene(mesh, bvh);
  Camera const cam = camera_for(scene, 32, 24);
  RenderOptions const ro = test::isa_options();
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  IsoParams ip;
  ip.surfaces = {{0.4f}};
  DvrParams dp;
  dp.tf = busy_tf(0.1f, 0.9f, diagonal(scene) / 8.f);
  Image const iso = render_iso(scene, cam, ip, ro), dvr = render_dvr(scene, cam, dp, ro);
  ip.clip.planes = dp.clip.planes = clip_box(lo - (hi - lo), hi + (hi - lo));
  ip.clip.caps = true;
  CHECK(render_iso(scene, cam, ip, ro).rgba == iso.rgba);
  CHECK(render_dvr(scene, cam, dp, ro).rgba == dvr.rgba);
  // The kept side of a plane beyond the mesh holds nothing of it.
  ip.clip.planes = dp.clip.planes = {{hi + (hi - lo), glm::vec3(-1.f, 0.f, 0.f)}};
  Image const empty_iso = render_iso(scene, cam, ip, ro), empty_dvr = render_dvr(scene, cam, dp, ro);
  for (size_t i = 0; i < empty_iso.rgba.size(); i += 4) {
    CHECK(empty_iso.rgba[i] == ip.background.r);
    CHECK(empty_dvr.rgba[i + 3] == dp.background.a);
  }
}

TEST_CASE("caps are coloured by the field where the cut face lies inside the mesh", "[render][clip][isa]") {
  // A linear field s = x: a cap on the plane z = 0 shows the colour map along x.
  auto const g = generate_tets(6 * 8 * 8 * 8, 1);
  std::vector<float> f(g.xyz.size() / 3);
  for (size_t v = 0; v < f.size(); ++v) f[v] = g.xyz[3 * v];
  TetMesh const mesh = g.mesh().with_values(view(f));
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  Scene const scene(mesh, bvh);
  Camera const cam = Camera::look_at({0.f, 0.f, 4.f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 20.f, 48, 48);
  IsoParams ip;
  ip.surfaces = {{5.f}};  // outside the data: only the cap shows
  ip.ambient = 1.f, ip.diffuse = 0.f, ip.specular = 0.f;
  ip.clip.planes = {{{0.f, 0.f, 0.f}, {0.f, 0.f, 1.f}}};
  ip.clip.caps = true;
  ip.clip.cap_colors.values = {-1.f, 1.f};
  ip.clip.cap_colors.rgba = {{1.f, 0.f, 0.f, 1.f}, {0.f, 0.f, 1.f, 1.f}};
  Image const img = render_iso(scene, cam, ip, test::isa_options());
  // Pixel centres map to x on the plane z = 0 (the camera looks down -z).
  float const* left = img.pixel(12, 24);
  float const* right = img.pixel(36, 24);
  CHECK(left[0] > 0.55f);  // x < 0: more red than blue
  CHECK(left[2] < 0.45f);
  CHECK(right[0] < 0.45f);
  CHECK(right[2] > 0.55f);
  CHECK(left[3] == 1.f);
  ImageDiff const d = compare_images(img, render_iso_reference(scene, cam, ip), 2.0);
  report("cap colours along a linear field vs reference", d);
  CHECK(d.frac_over <= 0.005);
}

TEST_CASE("bad clip parameters are refused", "[render][clip]") {
  auto const g = generate_tets(6 * 3 * 3 * 3, 1);
  TetMesh const mesh = g.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  Scene const scene(mesh, bvh);
  Camera const cam = camera_for(scene, 8, 8);
  IsoParams ip;
  ip.surfaces = {{0.4f}};
  ip.clip.planes = {{{0.f, 0.f, 0.f}, {0.f, 0.f, 0.f}}};
  CHECK_THROWS_WITH(render_iso(scene, cam, ip), Catch::Contains("clip plane 0"));
  ip.clip.planes.assign(17, ClipPlane{});
  CHECK_THROWS_WITH(render_iso(scene, cam, ip), Catch::Contains("at most 16 clip planes"));
  DvrParams dp;
  dp.tf = busy_tf(0.1f, 0.9f, 1.f);
  dp.clip.planes = {{{std::nanf(""), 0.f, 0.f}, {1.f, 0.f, 0.f}}};
  CHECK_THROWS_AS(render_dvr(scene, cam, dp), InvalidArgument);
}

}  // namespace test_render_clip
