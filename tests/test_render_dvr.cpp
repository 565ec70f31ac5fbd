// DVR accuracy against the double-precision reference renderer
// (render/reference.hpp): hex cell segments follow the true field, point
// samples converge at second order now that the steps at the mesh boundary
// are clipped, and gradient shading matches the reference in both modes.
// Small meshes and images: these run on every ISA in CI.

#include <catch2/catch.hpp>

#include <cstdio>
#include <string>
#include <vector>

#include <cellray/mesh/generate.hpp>

#include "support/render_fixtures.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_dvr {

using namespace cellray;

using test::busy_tf;
using test::camera_for;
using test::diagonal;
using test::load;
using test::report;

namespace {

RenderOptions options() { return test::isa_options(); }

}  // namespace

TEST_CASE("DVR segments in hexes integrate the true field, not the chord", "[render][dvr][isa]") {
  // A coarse lattice (8^3 hexes) of the blob field: the field along a ray
  // bends strongly inside each cell. Unjittered, every hex is a box, so the
  // field along a ray is exactly the cubic segments.hpp fits: what remains is
  // the midpoint rule. Jittered, the cubic is an approximation of a smooth
  // non-polynomial field. Measured (48x48, step diag/500, AVX-512): boxes
  // RMSE 0.0005/255, jittered 0.0010/255, no pixel off by more than 2/255;
  // the former chord between entry and exit values: 0.32/255 and 0.33/255,
  // 0.8% and 1.1% of pixels off by more than 2/255. Bounds: RMSE 0.02/255,
  // 0.2% of pixels.
  for (float jitter : {0.f, 0.3f}) {
    auto const g = generate_hexes(512, 1, jitter);
    auto const l = load(g.mesh());
    Scene const scene = l->scene();
    Camera const cam = camera_for(scene, 48, 48);
    DvrParams p;
    p.tf = busy_tf(0.1f, 0.9f, diagonal(scene) / 8.f);
    p.mode = DvrMode::segments;
    p.step = diagonal(scene) / 500.f;
    Image const ref = render_dvr_reference(scene, cam, p);
    ImageDiff const d = compare_images(render_dvr(scene, cam, p, options()), ref, 2.0);
    report("hexes 8^3, jitter " + std::to_string(jitter) + ", segments diag/500", d);
    CHECK(d.nonfinite == 0);
    CHECK(d.frac_over <= 0.002);
    CHECK(d.rmse < 0.02);
  }
}

TEST_CASE("DVR samples converge at second order in the step", "[render][dvr][isa]") {
  // Error against the reference at steps diag/200, /400, /800: first order
  // (a boundary step counted in full or not at all, or the step that crosses
  // the termination opacity counted in full) divides it by 4 over the two
  // halvings, second order by 16. Measured (40x40, AVX-512): tets 0.0446 ->
  // 0.0143 -> 0.0037 (12x), hexes 0.0317 -> 0.0102 -> 0.0027 (12x); before
  // the boundary clip the sweep showed 2.0x per halving. Bound: > 8x.
  auto check = [](std::string const& name, Scene const& scene) {
    Camera const cam = camera_for(scene, 40, 40);
    DvrParams p;
    p.tf = busy_tf(0.1f, 0.9f, diagonal(scene) / 8.f);
    p.mode = DvrMode::samples;
    Image const ref = render_dvr_reference(scene, cam, p);
    double first = 0, last = 0;
    for (int div : {200, 400, 800}) {
      p.step = diagonal(scene) / float(div);
      ImageDiff const d = compare_images(render_dvr(scene, cam, p, options()), ref, 2.0);
      report(name + ", samples diag/" + std::to_string(div), d);
      CHECK(d.nonfinite == 0);
      if (first == 0) first = d.rmse;
      last = d.rmse;
    }
    std::printf("    error ratio diag/200 : diag/800 = %.1f\n", first / last);
    CHECK(first / last > 8.0);
  };
  auto const t = generate_tets(6000);
  auto const lt = load(t.mesh());
  check("generated tets 6k", lt->scene());
  auto const h = generate_hexes(1000);
  auto const lh = load(h.mesh());
  check("generated hexes 1k", lh->scene());
}

TEST_CASE("DVR samples: the image does not depend on the sample group size", "[render][dvr][isa]") {
  // Each further group of a ray doubles (up to 32) and packet leaves may
  // drop cells between samples (SampleCull): neither may move, skip or
  // repeat a sample. Group sizes 1 to 32 must render the 32-sample image up
  // to the rounding of the sample positions (t0 accumulates other steps).
  // A mesh finer than the step (about 3 cells per step: cells dropped) and
  // one coarser (several samples per cell).
  auto check = [](std::string const& name, Scene const& scene, float step_div) {
    Camera const cam = camera_for(scene, 40, 40);
    DvrParams p;
    p.tf = busy_tf(0.1f, 0.9f, diagonal(scene) / 8.f);
    p.mode = DvrMode::samples;
    p.step = diagonal(scene) / step_div;
    p.group_size = 32;
    Image const all = render_dvr(scene, cam, p, options());
    for (int g : {1, 3, 8, 16}) {
      p.group_size = g;
      ImageDiff const d = compare_images(render_dvr(scene, cam, p, options()), all, 1.0);
      report(name + ", first group " + std::to_string(g) + " vs 32", d);
      CHECK(d.nonfinite == 0);
      CHECK(d.frac_over == 0);
      CHECK(d.max < 0.01);
    }
  };
  auto const fine = generate_tets(6 * 24 * 24 * 24);  // cells a third of the step
  auto const lf = load(fine.mesh());
  check("generated tets 83k, step diag/25", lf->scene(), 25.f);
  auto const coarse = generate_hexes(1000);
  auto const lc = load(coarse.mesh());
  check("generated hexes 1k, step diag/300", lc->scene(), 300.f);
}

TEST_CASE("DVR gradient shading matches the reference in both modes", "[render][dvr][isa]") {
  auto run = [](std::string const& name, Scene const& scene, float vmin, float vmax) {
    Camera const cam = camera_for(scene, 48, 48);
    DvrParams p;
    p.tf = busy_tf(vmin, vmax, diagonal(scene) / 8.f);
    p.step = diagonal(scene) / 1000.f;
    Image const plain = render_dvr_reference(scene, cam, p);
    p.shading.enabled = true;
    Image const ref = render_dvr_reference(scene, cam, p);
    // Shading must change the picture, or the comparisons below prove nothing.
    ImageDiff const effect = compare_images(plain, ref, 2.0);
    report(name + ": shaded vs unshaded reference", effect);
    CHECK(effect.frac_over > 0.3);
    for (DvrMode m : {DvrMode::samples, DvrMode::segments}) {
      p.mode = m;
      ImageDiff const d = compare_images(render_dvr(scene, cam, p, options()), ref, 2.0);
      report(name + (m == DvrMode::samples ? ": shaded samples diag/1000" : ": shaded segments diag/1000"), d);
      CHECK(d.nonfinite == 0);
      CHECK(d.frac_over <= 0.01);
    }
  };
  auto const t = generate_tets(6000);
  auto const lt = load(t.mesh());
  run("generated tets 6k", lt->scene(), 0.1f, 0.9f);
  auto const h = generate_hexes(1000);
  auto const lh = load(h.mesh());
  run("generated hexes 1k", lh->scene(), 0.1f, 0.9f);
}

TEST_CASE("DVR gradient shading leaves a flat field unshaded", "[render][dvr][isa]") {
  // The rule: shading blends in with |grad| / gradient_full, so a constant
  // field (zero gradient) renders exactly as without shading.
  auto const g = generate_tets(3000);
  std::vector<float> const flat(g.xyz.size() / 3, 0.5f);
  auto const l = load(g.mesh().with_values(view(flat)));
  Scene const scene = l->scene();
  Camera const cam = camera_for(scene, 24, 24);
  DvrParams p;
  p.tf = busy_tf(0.f, 1.f, 0.5f);
  for (DvrMode m : {DvrMode::samples, DvrMode::segments}) {
    p.mode = m;
    p.shading.enabled = false;
    Image const a = render_dvr(scene, cam, p, options());
    p.shading.enabled = true;
    Image const b = render_dvr(scene, cam, p, options());
    // Not bit-exact: the analytic gradient of a constant field is zero up to
    // rounding (~1e-8), which shades by a blend of that order.
    CHECK(compare_images(a, b).max < 0.01);
  }
  p.shading.ambient = -1.f;
  CHECK_THROWS_AS(render_dvr(scene, cam, p, options()), InvalidArgument);
}

}  // namespace test_render_dvr
