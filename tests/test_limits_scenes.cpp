#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/render.hpp>

#include "support/brute_force.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_limits_scenes {

// Renders at the edges of their documented input space: isovalues outside
// the data, zero-size and 1x1 images, extreme fields of view, the eye inside
// the mesh, meshes around 1e7 and around 1e-7. Where a hit or a miss is
// decided, the oracle is the brute-force double-precision first hit over
// every tet (tests/support/brute_force.hpp) on the very float mesh rendered.

using namespace cellray;

namespace {

constexpr glm::vec4 clear{0.f, 0.f, 0.f, 0.f};  // alpha 0: a pixel's alpha says hit (1) or miss (0)

/// One opaque isosurface on a transparent background.
IsoParams opaque(float value) {
  IsoParams p;
  p.surfaces = {{value, {0.6f, 0.6f, 0.6f}, 1.f}};
  p.background = clear;
  return p;
}

/// A generated tet mesh, scaled by `scale` and moved by `offset` (each
/// coordinate rounded to float once).
struct Placed {
  GeneratedMesh<4> g;
  Placed(uint64_t cells, double scale, glm::dvec3 offset) : g(generate_tets(cells, 11)) {
    for (size_t i = 0; i < g.xyz.size(); ++i) g.xyz[i] = float(double(g.xyz[i]) * scale + offset[int(i % 3)]);
  }
  TetMesh mesh() const { return g.mesh(); }
};

/// Pixels whose hit/miss differs from the brute-force oracle, and how many
/// pixels the oracle says hit.
struct MaskCompare {
  int wrong = 0, hits = 0, pixels = 0;
};

/// The oracle's hit (1) or miss (0) per pixel: brute force over every tet.
std::vector<char> oracle_mask(TetMesh const& mesh, Camera const& cam, float iso) {
  std::vector<char> hit;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      Ray r;
      r.org = cam.eye;
      r.dir = cam.direction(float(x), float(y));
      hit.push_back(std::isfinite(test::brute_force_first_hit(mesh, r, {iso}).t));
    }
  return hit;
}

MaskCompare compare_mask(Image const& img, std::vector<char> const& oracle) {
  MaskCompare m;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      bool const hit = oracle[size_t(y) * size_t(img.width) + size_t(x)];
      bool const drawn = img.pixel(x, y)[3] > 0.5f;
      m.wrong += hit != drawn;
      m.hits += hit;
      ++m.pixels;
    }
  return m;
}

MaskCompare compare_mask(Image const& img, TetMesh const& mesh, Camera const& cam, float iso) {
  return compare_mask(img, oracle_mask(mesh, cam, iso));
}

bool all_pixels(Image const& img, glm::vec4 c) {
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int k = 0; k < 4; ++k)
        if (img.pixel(x, y)[k] != c[k]) return false;
  return true;
}

bool finite_in_unit(Image const& img) {
  for (float v : img.rgba)
    if (!(v >= 0.f && v <= 1.f)) return false;
  return true;
}

}  // namespace

TEST_CASE("isovalues outside the data range draw nothing -- DVR over an empty range is the background",
          "[limits][render]") {
  Placed const p(6000, 1.0, {0, 0, 0});
  TetMesh const m = p.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(m);
  Camera const cam = Camera::look_at({0.3f, 0.4f, 3.f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 45.f, 33, 21);
  for (float v : {-1e30f, -5.f, 5.f, 1e30f, 0.f, 2.f}) {  // the field lies in about [0.1, 0.9]
    INFO("isovalue " << v);
    CHECK(all_pixels(render_iso(Scene(m, bvh), cam, opaque(v)), clear));
  }
  DvrParams d;
  d.tf.values = {10.f, 11.f};  // opaque only far above the data
  d.tf.rgba = {{1, 0, 0, 0}, {1, 0, 0, 1}};
  d.background = clear;
  for (DvrMode mode : {DvrMode::samples, DvrMode::segments}) {
    d.mode = mode;
    CHECK(all_pixels(render_dvr(Scene(m, bvh), cam, d), clear));
  }
}

TEST_CASE("zero-size images and tiles are rejected or do nothing, as documented", "[limits][render]") {
  Placed const p(600, 1.0, {0, 0, 0});
  TetMesh const m = p.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(m);
  CHECK_THROWS_AS(Camera::look_at({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 45.f, 0, 10), InvalidArgument);
  CHECK_THROWS_AS(Camera::look_at({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 45.f, 10, 0), InvalidArgument);
  Camera zero;
  zero.width = 0;
  CHECK_THROWS_AS(render_iso(Scene(m, bvh), zero, opaque(0.4f)), InvalidArgument);
  DvrParams d;
  d.tf = transfer_function_preset("grayscale", 0.f, 1.f);
  CHECK_THROWS_AS(render_dvr(Scene(m, bvh), zero, d), InvalidArgument);
  // An empty tile writes nothing.
  Camera const cam = Camera::look_at({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 45.f, 8, 8);
  Image img(8, 8);
  std::fill(img.rgba.begin(), img.rgba.end(), 0.25f);
  render_tile(Scene(m, bvh), cam, opaque(0.4f), Tile{3, 3, 0, 0}, img);
  render_tile(Scene(m, bvh), cam, d, Tile{8, 8, 0, 0}, img);
  CHECK(all_pixels(img, glm::vec4(0.25f)));
  CHECK_THROWS_AS(render_tile(Scene(m, bvh), cam, d, Tile{4, 4, 5, 1}, img), InvalidArgument);
}

TEST_CASE("a 1x1 image is the centre ray: same hit as the oracle and as a 3x3 image's centre", "[limits][render]") {
  Placed const p(6000, 1.0, {0, 0, 0});
  TetMesh const m = p.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(m);
  for (float iso : {0.3f, 0.5f})
    for (glm::vec3 eye : {glm::vec3(0.2f, 0.1f, 3.f), glm::vec3(-2.f, 1.f, 1.5f)}) {
      Camera const one = Camera::look_at(eye, {0.1f, 0.f, 0.f}, {0, 1, 0}, 30.f, 1, 1);
      Camera const three = Camera::look_at(eye, {0.1f, 0.f, 0.f}, {0, 1, 0}, 30.f, 3, 3);
      Image const a = render_iso(Scene(m, bvh), one, opaque(iso));
      Image const b = render_iso(Scene(m, bvh), three, opaque(iso));
      REQUIRE(a.rgba.size() == 4);
      CHECK(compare_mask(a, m, one, iso).wrong == 0);
      // Same ray (direction(1, 1) of 3x3 = direction(0, 0) of 1x1 = forward):
      // same hit and shading, to float rounding of the pixel position.
      for (int k = 0; k < 4; ++k) CHECK(a.pixel(0, 0)[k] == Approx(b.pixel(1, 1)[k]).margin(1e-4));
      DvrParams d;
      d.tf = transfer_function_preset("cool-warm", 0.f, 1.f);
      Image const dv = render_dvr(Scene(m, bvh), one, d);
      CHECK(finite_in_unit(dv));
    }
}

TEST_CASE("extreme fields of view render finite images -- out-of-range ones are rejected", "[limits][render]") {
  Placed const p(6000, 1.0, {0, 0, 0});
  TetMesh const m = p.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(m);
  glm::vec3 const eye(0.3f, 0.2f, 3.f);
  for (float fov : {0.f, -1.f, 180.f, 200.f, NAN})
    CHECK_THROWS_AS(Camera::look_at(eye, {0, 0, 0}, {0, 1, 0}, fov, 8, 8), InvalidArgument);
  for (float fov : {1e-3f, 0.1f, 170.f, 179.9f}) {
    INFO("fov " << fov);
    Camera const cam = Camera::look_at(eye, {0, 0, 0}, {0, 1, 0}, fov, 20, 14);
    Image const img = render_iso(Scene(m, bvh), cam, opaque(0.35f));
    REQUIRE(finite_in_unit(img));
    MaskCompare const c = compare_mask(img, m, cam, 0.35f);
    // Pixels whose ray grazes the isosurface may go either way in float.
    CHECK(c.wrong <= c.pixels / 50);
    DvrParams d;
    d.tf = transfer_function_preset("viridis", 0.f, 1.f);
    CHECK(finite_in_unit(render_dvr(Scene(m, bvh), cam, d)));
  }
}

TEST_CASE("a camera inside the mesh sees the first isosurface crossing in front of it", "[limits][render]") {
  Placed const p(6000, 1.0, {0, 0, 0});
  TetMesh const m = p.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(m);
  for (glm::vec3 eye : {glm::vec3(0.f, 0.f, 0.f), glm::vec3(0.9f, -0.7f, 0.2f), glm::vec3(0.05f, 0.45f, 0.5f)})
    for (float iso : {0.3f, 0.6f}) {
      INFO("eye " << eye.x << " " << eye.y << " " << eye.z << ", iso " << iso);
      Camera const cam = Camera::look_at(eye, eye + glm::vec3(0.3f, -0.2f, -1.f), {0, 1, 0}, 90.f, 24, 18);
      std::vector<char> const oracle = oracle_mask(m, cam, iso);
      for (Traversal t : {Traversal::packet, Traversal::spmd, Traversal::hybrid}) {
        RenderOptions o;
        o.traversal = t;
        Image const img = render_iso(Scene(m, bvh), cam, opaque(iso), o);
        MaskCompare const c = compare_mask(img, oracle);
        CHECK(c.wrong <= c.pixels / 100);
      }
      DvrParams d;
      d.tf = transfer_function_preset("inferno", 0.f, 1.f);
      for (DvrMode mode : {DvrMode::samples, DvrMode::segments}) {
        d.mode = mode;
        Image const img = render_dvr(Scene(m, bvh), cam, d);
        CHECK(finite_in_unit(img));
      }
    }
}

TEST_CASE("meshes far from the origin (1e7) and tiny ones (1e-7) render like unit ones", "[limits][render]") {
  // Scale 1e4 at offset 1e7: float spacing there is 1, 1e-4 of the mesh size.
  struct Case {
    double scale;
    glm::dvec3 offset;
    char const* name;
  };
  Image unit_samples, unit_segments;  // the unit mesh's DVR images
  {
    Placed const p(3000, 1.0, {0, 0, 0});
    TetMesh const m = p.mesh();
    MinMaxBvh const bvh = build_minmax_bvh(m);
    Camera const cam = Camera::look_at({0.4f, 0.5f, 3.f}, {0.f, 0.f, 0.f}, {0, 1, 0}, 45.f, 32, 24);
    DvrParams d;
    d.tf = transfer_function_preset("viridis", 0.1f, 0.8f);
    d.tf.unit_distance = 0.3f;
    unit_samples = render_dvr(Scene(m, bvh), cam, d);
    d.mode = DvrMode::segments;
    unit_segments = render_dvr(Scene(m, bvh), cam, d);
  }
  for (Case const& k : {Case{1e4, {1e7, -1e7, 1e7}, "1e4 at 1e7"}, Case{1e-7, {0, 0, 0}, "1e-7 at the origin"},
                        Case{1e-7, {3e-6, 1e-6, -2e-6}, "1e-7 at 3e-6"}, Case{1.0, {0, 0, 0}, "unit"}}) {
    INFO(k.name);
    Placed const p(3000, k.scale, k.offset);
    TetMesh const m = p.mesh();
    MinMaxBvh const bvh = build_minmax_bvh(m);
    auto place = [&](glm::dvec3 q) { return glm::vec3(q * k.scale + k.offset); };
    Camera const cam =
        Camera::look_at(place({0.4, 0.5, 3.0}), place({0.0, 0.0, 0.0}), {0, 1, 0}, 45.f, 32, 24);
    for (float iso : {0.3f, 0.55f}) {
      IsoParams ip = opaque(iso);
      ip.shadows = true;
      ip.ao_samples = 2;
      Image const img = render_iso(Scene(m, bvh), cam, ip);
      REQUIRE(finite_in_unit(img));
      MaskCompare const c = compare_mask(img, m, cam, iso);
      CHECK(c.hits > c.pixels / 10);
      CHECK(c.wrong <= c.pixels / 100);
    }
    // DVR is scale invariant when the opacity unit scales with the mesh (the
    // default step is the diagonal / 500): the image must match the unit
    // mesh's up to float rounding of positions and sample points.
    DvrParams d;
    d.tf = transfer_function_preset("viridis", 0.1f, 0.8f);
    d.tf.unit_distance = float(0.3 * k.scale);
    for (DvrMode mode : {DvrMode::samples, DvrMode::segments}) {
      d.mode = mode;
      Image const img = render_dvr(Scene(m, bvh), cam, d);
      REQUIRE(finite_in_unit(img));
      Image const& ref = mode == DvrMode::samples ? unit_samples : unit_segments;
      double err = 0;
      for (size_t i = 0; i < img.rgba.size(); ++i) err += std::fabs(double(img.rgba[i]) - double(ref.rgba[i]));
      CHECK(err / double(img.rgba.size()) < 0.01);  // mean channel error under 1% (2.5 of 255 levels)
    }
  }
}

}  // namespace test_limits_scenes
