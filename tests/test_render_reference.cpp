// The reference renderer (render/reference.hpp) checked against analytic
// answers, its own tolerance checked by refinement, and the fast renderer
// checked against it on generated and real meshes, on every ISA. The
// failure-mode guards at the end hold the numbers docs/failure_modes.md
// reports (see scripts/failure-report.sh); cell-level watertightness is
// guarded in test_cells_watertight.cpp and not repeated here.

#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>

#include "support/render_fixtures.hpp"
#include "support/sanitized.hpp"
#include "support/test_data.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_reference {

using namespace cellray;

using test::busy_tf;
using test::camera_for;
using test::diagonal;
using test::load;
using test::report;

namespace {

/// The generated field replaced by a linear one, s = x: its isosurfaces are
/// exact planes in tets and (trilinear maps reproduce x) in hexes too.
template <int N> std::vector<float> linear_field(GeneratedMesh<N> const& g) {
  std::vector<float> f(g.xyz.size() / 3);
  for (size_t v = 0; v < f.size(); ++v) f[v] = g.xyz[3 * v];
  return f;
}

template <int N> void check_plane_roots(GeneratedMesh<N> const& g) {
  std::vector<float> const f = linear_field(g);
  CellMesh<N> const m = g.mesh().with_values(view(f));
  auto const l = load(m);
  Scene const scene = l->scene();
  Camera const cam = camera_for(scene, 24, 24);
  IsoParams p;
  p.surfaces = {{0.137f}};
  auto const s = ref_render::prepare(scene);
  std::vector<ref_render::Crossing> xs;
  int hits = 0;
  double worst = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      ref::Ray const r = ref_render::camera_ray(cam, x, y);
      ref_render::iso_crossings(s, r, 0.0, std::numeric_limits<double>::infinity(), p, {}, xs);
      double const t = (double(0.137f) - r.o.x) / r.d.x;
      glm::dvec3 const q = r.o + t * r.d;
      bool const inside = std::abs(q.y) < 0.999 && std::abs(q.z) < 0.999;  // clear of the jittered-free boundary
      if (!inside) continue;
      REQUIRE(!xs.empty());
      ++hits;
      // Every crossing found lies on the plane; at a shared face both cells
      // may report it (same t), never a different one.
      for (auto const& c : xs) worst = std::max(worst, std::abs(c.t - t) / t);
    }
  CHECK(hits > 50);
  CHECK(worst < 1e-9);
}

}  // namespace

TEST_CASE("reference iso: a linear field's planar isosurface is hit at the analytic t", "[render][reference]") {
  SECTION("tets") { check_plane_roots(generate_tets(6000)); }
  SECTION("hexes") { check_plane_roots(generate_hexes(1000)); }
}

TEST_CASE("reference DVR: constant transfer function gives the analytic Beer-Lambert image", "[render][reference]") {
  // The generated meshes fill [-1,1]^3 exactly: the path length is the slab
  // interval, the answer c (1 - (1 - a)^(L / unit)) + background x rest.
  auto const g = generate_tets(3000);
  auto const l = load(g.mesh());
  Scene const scene = l->scene();
  Camera const cam = camera_for(scene, 20, 20);
  DvrParams p;
  p.tf.values = {0.f, 1.f};
  p.tf.rgba = {{0.3f, 0.6f, 0.9f, 0.4f}, {0.3f, 0.6f, 0.9f, 0.4f}};
  p.tf.unit_distance = 0.7f;
  p.termination = 1.f;
  p.background = {1.f, 1.f, 1.f, 1.f};
  Image const img = render_dvr_reference(scene, cam, p);
  double worst = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      ref::Ray const r = ref_render::camera_ray(cam, x, y);
      double t0 = 0, t1 = 1e30;
      for (int k = 0; k < 3; ++k) {
        double a = (-1 - r.o[k]) / r.d[k], b = (1 - r.o[k]) / r.d[k];
        if (a > b) std::swap(a, b);
        t0 = std::max(t0, a), t1 = std::min(t1, b);
      }
      double const L = std::max(0.0, t1 - t0);
      double const T = std::pow(1.0 - double(0.4f), L / double(0.7f));
      double const want[3] = {0.3f * (1 - T) + T, 0.6f * (1 - T) + T, 0.9f * (1 - T) + T};
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(double(img.pixel(x, y)[c]) - want[c]));
    }
  CHECK(worst < 1e-6);  // float output rounding (6e-8) plus the face-chain rounding of the clip
}

TEST_CASE("reference DVR: tightening the tolerance 1000x changes no pixel by more than the stated 1e-6",
          "[render][reference]") {
  auto run = [](Scene const& scene) {
    Camera const cam = camera_for(scene, 32, 32);
    DvrParams p;
    p.tf = busy_tf(0.1f, 0.9f, diagonal(scene) / 10.f);
    ReferenceOptions o, fine;
    fine.dvr_tolerance = o.dvr_tolerance / 1000;
    Image const a = render_dvr_reference(scene, cam, p, o), b = render_dvr_reference(scene, cam, p, fine);
    double worst = 0;
    for (size_t i = 0; i < a.rgba.size(); ++i) worst = std::max(worst, std::abs(double(a.rgba[i]) - double(b.rgba[i])));
    return worst;
  };
  auto const t = generate_tets(6000);
  auto const lt = load(t.mesh());
  double const et = run(lt->scene());
  auto const h = generate_hexes(1000);
  auto const lh = load(h.mesh());
  double const eh = run(lh->scene());
  std::printf("  DVR reference refinement: tets %.2e, hexes %.2e\n", et, eh);
  CHECK(et < 1e-6);
  CHECK(eh < 1e-6);
}

namespace {

struct Case {
  std::string name;
  Scene scene;
  float vmin, vmax;
  std::vector<float> isos;
};

/// Bounds on the fraction of pixels off by more than 2/255. Measured (all
/// ISAs, 96x96): iso <= 0.011% (disk_out_ref, transparent + shadows: float
/// shadow-ray offsets), DVR samples at step diag/2000 0%, DVR segments 0% on
/// tets and hexes (0.23% on disk_out_ref while hex segments took the chord
/// between entry and exit values). Bounds: 0.5% (one pixel is 0.043% of the
/// 48x48 frames of the sanitizer build).
struct Bounds {
  double iso, dvr_samples, dvr_segments;
};

void fast_vs_reference(Case const& c, Bounds const& b, int size) {
  Camera const cam = camera_for(c.scene, size, size);
  RenderOptions const ro = test::isa_options();
  IsoParams ip;
  for (float v : c.isos) ip.surfaces.push_back({v, {0.9f, 0.7f, 0.4f}, 1.f});
  Image const iso_ref = render_iso_reference(c.scene, cam, ip);
  Image const iso_fast = render_iso(c.scene, cam, ip, ro);
  ImageDiff const di = compare_images(iso_fast, iso_ref, 2.0);
  report(c.name + " iso (exact, analytic)", di);
  CHECK(di.nonfinite == 0);
  CHECK(di.frac_over <= b.iso);
  // Transparent nested surfaces with shadows: layers and shadow rays.
  ip.surfaces.front().opacity = 0.5f;
  ip.surfaces.push_back({c.vmin + 0.7f * (c.vmax - c.vmin), {0.3f, 0.5f, 0.9f}, 1.f});
  ip.shadows = true;
  ip.light_dir = {0.3f, 1.f, 0.5f};
  ImageDiff const dt = compare_images(render_iso(c.scene, cam, ip, ro), render_iso_reference(c.scene, cam, ip), 2.0);
  report(c.name + " iso, 2 surfaces, transparent, shadows", dt);
  CHECK(dt.nonfinite == 0);
  CHECK(dt.frac_over <= b.iso);

  DvrParams dp;
  float const diag = diagonal(c.scene);
  dp.tf = busy_tf(c.vmin, c.vmax, diag / 8.f);
  Image const dvr_ref = render_dvr_reference(c.scene, cam, dp);
  dp.step = diag / 2000.f;
  dp.mode = DvrMode::samples;
  ImageDiff const ds = compare_images(render_dvr(c.scene, cam, dp, ro), dvr_ref, 2.0);
  report(c.name + " DVR samples, step diag/2000", ds);
  CHECK(ds.nonfinite == 0);
  CHECK(ds.frac_over <= b.dvr_samples);
  dp.mode = DvrMode::segments;
  ImageDiff const dg = compare_images(render_dvr(c.scene, cam, dp, ro), dvr_ref, 2.0);
  report(c.name + " DVR segments, step diag/2000", dg);
  CHECK(dg.nonfinite == 0);
  CHECK(dg.frac_over <= b.dvr_segments);
}

/// Frame side: 96 in the Release build (every ISA), 48 under the sanitizers,
/// where every code path still runs (support/sanitized.hpp).
constexpr int frame = test::full_or_sanitized(96, 48);

}  // namespace

TEST_CASE("fast vs reference: generated tets and hexes", "[render][reference][isa]") {
  auto const t = generate_tets(20000);
  auto const lt = load(t.mesh());
  fast_vs_reference({"generated tets 20k", lt->scene(), 0.1f, 0.9f, {0.45f}}, {0.005, 0.005, 0.005}, frame);
  auto const h = generate_hexes(4000);
  auto const lh = load(h.mesh());
  fast_vs_reference({"generated hexes 4k", lh->scene(), 0.1f, 0.9f, {0.45f}}, {0.005, 0.005, 0.005}, frame);
}

TEST_CASE("fast vs reference: post.vtk (tets) and disk_out_ref.vtu (hexes)", "[render][reference][isa][data]") {
  auto const post = read_mesh(test::real_file("vtk-data/post.vtk"));
  auto const lp = load(post.tet_mesh());
  fast_vs_reference({"post.vtk Pressure", lp->scene(), 0.355f, 1.641f, {0.9f}}, {0.005, 0.005, 0.005}, frame);
  auto const disk = read_mesh(test::real_file("vtk-data/disk_out_ref.vtu"));
  auto const ld = load(disk.hex_mesh().with_array("Temp"));
  fast_vs_reference({"disk_out_ref.vtu Temp", ld->scene(), 293.f, 913.f, {600.f}}, {0.005, 0.005, 0.005}, frame);
}

TEST_CASE("fast vs reference: flange_heat.vtk (hexes and 372 wedges as collapsed hexes)",
          "[render][reference][isa][vtk-cells]") {
  auto const flange = read_mesh(test::real_file("openfoam/flange_heat.vtk"));
  auto const lf = load(flange.hex_mesh().with_array("T"));
  fast_vs_reference({"flange_heat.vtk T", lf->scene(), 273.f, 573.f, {300.f}}, {0.005, 0.005, 0.005}, frame);
}

// ------------------------------------------------------------ failure modes
// The numbers docs/failure_modes.md reports (scripts/failure-report.sh, at
// 192x192), guarded here at 64x64 with bounds a few times above what was
// measured so that a regression fails and rounding noise does not.

namespace {

/// Regular lattice (no jitter), s = x, two transparent isosurfaces exactly on
/// lattice planes: every hit lies on shared faces, edges or vertices.
template <int N> ImageDiff lattice_plane_diff(CellIsoOptions roots) {
  GeneratedMesh<N> g;
  if constexpr (N == 4) g = generate_tets(6000, 1, 0.f);
  else g = generate_hexes(2000, 1, 0.f);
  std::vector<float> const f = linear_field(g);
  auto const l = load(g.mesh().with_values(view(f)));
  Scene const scene = l->scene();
  Camera const cam = camera_for(scene, 64, 64);
  IsoParams p;
  float const h = 2.f / float(g.lattice);
  p.surfaces = {{-1.f + h * float(g.lattice / 2), {0.9f, 0.6f, 0.3f}, 0.5f},
                {-1.f + h * float(g.lattice / 2 + 1), {0.3f, 0.6f, 0.9f}, 0.5f}};
  Image const ref = render_iso_reference(scene, cam, p);
  p.roots = roots;
  RenderOptions const ro = test::isa_options();
  return compare_images(render_iso(scene, cam, p, ro), ref, 2.0);
}

}  // namespace

TEST_CASE("failure modes: no cracks or double layers where isosurfaces lie on shared faces",
          "[render][reference][failure][isa]") {
  for (auto const& roots : {CellIsoOptions{CellIsoMethod::exact, 2, 2}, CellIsoOptions{CellIsoMethod::neubauer, 2, 2}}) {
    ImageDiff const t = lattice_plane_diff<4>(roots), h = lattice_plane_diff<8>(roots);
    report("lattice planes, tets", t);
    report("lattice planes, hexes", h);
    CHECK(t.frac_over <= 0.005);
    CHECK(h.frac_over <= 0.005);
  }
}

TEST_CASE("failure modes: iso hits missed or spurious against exact roots", "[render][reference][failure][isa]") {
  auto const g = generate_hexes(4000);
  auto const l = load(g.mesh());
  Scene const scene = l->scene();
  Camera const cam = camera_for(scene, 64, 64);
  IsoParams p;
  p.surfaces = {{0.3f}};
  p.background = {0.f, 0.f, 0.f, 0.f};  // alpha is the hit mask
  Image const ref = render_iso_reference(scene, cam, p);
  auto rates = [&](CellIsoOptions o) {
    IsoParams q = p;
    q.roots = o;
    RenderOptions const ro = test::isa_options();
    Image const img = render_iso(scene, cam, q, ro);
    int missed = 0, spurious = 0, hits = 0;
    for (size_t i = 3; i < img.rgba.size(); i += 4) {
      bool const f = img.rgba[i] > 0.5f, r = ref.rgba[i] > 0.5f;
      hits += r, missed += r && !f, spurious += f && !r;
    }
    std::printf("  hexes iso 0.3, %s N=%d: %d hits, %d missed, %d spurious\n",
                o.method == CellIsoMethod::exact ? "exact" : "Neubauer", o.neubauer_steps, hits, missed, spurious);
    return std::array<double, 2>{double(missed) / hits, double(spurious) / hits};
  };
  auto const exact = rates({CellIsoMethod::exact, 2, 2});
  CHECK(exact[0] <= 0.002);
  CHECK(exact[1] <= 0.002);
  auto const n2 = rates({CellIsoMethod::neubauer, 2, 2});
  CHECK(n2[0] <= 0.01);
  CHECK(n2[1] <= 0.01);
}

TEST_CASE("failure modes: NaN scalars and zero-volume cells render as the reference does",
          "[render][reference][failure][isa]") {
  auto const g = generate_tets(6000);
  std::vector<float> f = g.field;
  for (size_t v = 0; v < f.size(); ++v)
    if (g.xyz[3 * v] > 0.2f && g.xyz[3 * v + 1] > -0.3f) f[v] = std::numeric_limits<float>::quiet_NaN();
  std::vector<uint32_t> cells = g.cells;
  uint64_t const orig = cells.size() / 4;
  for (uint64_t c = 0; c < orig; c += 50)  // zero-volume duplicates: last corner = first
    cells.insert(cells.end(), {g.cells[4 * c], g.cells[4 * c + 1], g.cells[4 * c + 2], g.cells[4 * c]});
  auto const l = load(TetMesh(view(g.xyz), view(cells), view(f), "field"));
  Scene const scene = l->scene();
  Camera const cam = camera_for(scene, 64, 64);
  RenderOptions const ro = test::isa_options();
  IsoParams ip;
  ip.surfaces = {{0.3f, {0.9f, 0.7f, 0.4f}, 0.6f}, {0.5f, {0.4f, 0.6f, 0.9f}, 1.f}};
  ImageDiff const di = compare_images(render_iso(scene, cam, ip, ro), render_iso_reference(scene, cam, ip), 2.0);
  report("NaN + degenerate, iso", di);
  CHECK(di.nonfinite == 0);
  CHECK(di.frac_over <= 0.005);
  DvrParams dp;
  dp.tf = busy_tf(0.1f, 0.9f, 0.35f);
  Image const dref = render_dvr_reference(scene, cam, dp);
  dp.step = diagonal(scene) / 2000.f;
  for (DvrMode m : {DvrMode::samples, DvrMode::segments}) {
    dp.mode = m;
    ImageDiff const d = compare_images(render_dvr(scene, cam, dp, ro), dref, 2.0);
    report(m == DvrMode::samples ? "NaN + degenerate, DVR samples" : "NaN + degenerate, DVR segments", d);
    CHECK(d.nonfinite == 0);
    CHECK(d.frac_over <= 0.005);
  }
}

}  // namespace test_render_reference
