// Two crossings of one isovalue inside one hex, with the search window
// starting between them: what a shadow or AO ray leaving a hex surface, or a
// ray continuing behind a transparent surface, asks. The second crossing
// must be found (it was lost: the cell's first root, before the window, hid
// it). Oracle: the field 4 (x - 1/2)(y - 1/2) on the unit cube is the
// trilinear interpolant of its corner values, so along a ray it is a
// quadratic whose roots are solved in double here; the double reference
// renderer for the composited image.

#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/render/reference.hpp>
#include <cellray/traverse/occlusion_query.hpp>

#include "support/render_fixtures.hpp"
#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_traverse_hex_window {

using namespace cellray;

namespace {

constexpr float iso = -0.2f;

struct UnitCube {
  std::vector<float> xyz{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
  std::vector<uint32_t> cells{0, 1, 2, 3, 4, 5, 6, 7};
  std::vector<float> values;
  UnitCube() {
    for (size_t v = 0; v < 8; ++v) values.push_back(4.f * (xyz[3 * v] - 0.5f) * (xyz[3 * v + 1] - 0.5f));
  }
  HexMesh mesh() const { return HexMesh(view(xyz), view(cells), view(values)); }
};

/// Roots in t of 4 (x(t) - 1/2)(y(t) - 1/2) = iso along a ray, ascending
/// (none: empty).
std::vector<double> field_roots(Ray const& r) {
  double const ax = r.dir.x, bx = double(r.org.x) - 0.5, ay = r.dir.y, by = double(r.org.y) - 0.5;
  double const a = 4 * ax * ay, b = 4 * (ax * by + bx * ay), c = 4 * bx * by - double(iso);
  double const disc = b * b - 4 * a * c;
  if (a == 0 || disc <= 0) return {};
  double const s = std::sqrt(disc);
  double const q = -0.5 * (b + (b >= 0 ? s : -s));
  double r1 = q / a, r2 = c / q;
  if (r1 > r2) std::swap(r1, r2);
  return {r1, r2};
}

/// Rays through the cube in the direction (1, -1, dz) at several offsets,
/// each crossing the surface twice inside the cell; tmin halfway between the
/// crossings, tmax past the cell.
std::vector<Ray> rays_between_crossings(std::vector<double>& second) {
  std::vector<Ray> rays;
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 5; ++j) {
      float const off = -0.12f + 0.03f * float(i), z = 0.2f + 0.15f * float(j);
      Ray r{{-0.5f + off, 1.5f + off, z}, 0.f, {1.f, -1.f, 0.05f * float(j - 2)}, 10.f};
      std::vector<double> const roots = field_roots(r);
      REQUIRE(roots.size() == 2);
      // Both crossings inside the cube (x in [0, 1] there).
      REQUIRE(r.org.x + roots[0] * r.dir.x > 0.01);
      REQUIRE(r.org.x + roots[1] * r.dir.x < 0.99);
      REQUIRE(roots[1] - roots[0] > 0.05);
      r.tmin = float(0.5 * (roots[0] + roots[1]));
      rays.push_back(r);
      second.push_back(roots[1]);
    }
  return rays;
}

}  // namespace

TEST_CASE("hex iso: a window starting between two crossings in one cell finds the second", "[traverse][isa]") {
  UnitCube const cube;
  HexMesh const mesh = cube.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  TreeView const tree(bvh);
  std::vector<double> second;
  std::vector<Ray> const rays = rays_between_crossings(second);
  IsoQuery q;
  q.isos.count = 1;
  q.isos.values[0] = iso;
  for (Traversal tv : {Traversal::packet, Traversal::spmd, Traversal::hybrid}) {
    q.traversal = tv;
    INFO(traversal_name(tv) << " on " << isa_name(test::isa()));
    std::vector<SurfaceHit> const hits = first_hits(tree, mesh, rays, q, test::isa());
    for (size_t i = 0; i < rays.size(); ++i) {
      INFO("ray " << i);
      REQUIRE(hits[i].hit());
      // Float positions and roots on a unit cell: errors ~1e-6.
      CHECK(std::abs(double(hits[i].t) - second[i]) < 1e-5);
    }
    for (bool grouped : {false, true}) {
      if (grouped && tv != Traversal::packet) continue;
      std::vector<uint8_t> const occ = occluded_rays(tree, mesh, rays, q, grouped, test::isa());
      for (size_t i = 0; i < rays.size(); ++i) CHECK(occ[i] == 1);
    }
  }
  // Windows ending before the second crossing: nothing (the first one lies
  // before tmin).
  std::vector<Ray> short_rays = rays;
  for (size_t i = 0; i < rays.size(); ++i) short_rays[i].tmax = float(0.5 * (double(rays[i].tmin) + second[i]));
  for (SurfaceHit const& h : first_hits(tree, mesh, short_rays, q, test::isa())) CHECK(!h.hit());
}

TEST_CASE("hex iso: a transparent surface crossed twice in one cell composites both layers like the reference",
          "[render][isa]") {
  UnitCube const cube;
  auto const loaded = test::load(cube.mesh());
  Scene const scene = loaded->scene();
  Camera const cam = Camera::look_at({-1.2f, 2.2f, 0.9f}, {0.5f, 0.5f, 0.5f}, {0.f, 0.f, 1.f}, 40.f, 48, 48);
  IsoParams ip;
  ip.surfaces.push_back({iso, {0.9f, 0.7f, 0.4f}, 0.5f});
  ImageDiff const d = compare_images(render_iso(scene, cam, ip, test::isa_options()), render_iso_reference(scene, cam, ip), 2.0);
  test::report("unit cube, one transparent surface crossed twice", d);
  CHECK(d.nonfinite == 0);
  CHECK(d.frac_over <= 0.005);
}

}  // namespace test_traverse_hex_window
