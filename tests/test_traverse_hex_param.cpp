// The trilinear coordinates the first-hit query keeps at hexahedron hits
// (FirstHitQuery with want_param: what smooth normals and colour-by
// interpolate with, instead of inverting the hit cell again) against the
// hit itself in double: mapped through the hit cell (cells/reference.hpp)
// they give the hit point, and the double field there is the isovalue.
// Distorted hexes, so the root search inverts (affine cells take the
// parametric segment). Runs the scalar arch here; the SIMD widths run the
// same code in test_render_smooth.cpp through render_iso, against the
// reference renderer's own point location.

#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/reference.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/camera.hpp>
#include <cellray/traverse/first_hit.hpp>

#include "support/first_hits.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_traverse_hex_param {

using namespace cellray;

TEST_CASE("first hit: the hexahedron coordinates kept at each hit map to the hit point", "[traverse]") {
  auto const g = generate_hexes(10 * 10 * 10, 2, 0.3f);
  HexMesh const mesh = g.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  TreeView const tree(bvh);
  IsoSet const isos = test::iso_set({0.35f, 0.6f});
  Camera const cam = Camera::look_at({2.2f, 1.4f, 3.1f}, glm::vec3(0.f), {0, 1, 0}, 50.f, 40, 30);
  for (CellIsoMethod method : {CellIsoMethod::exact, CellIsoMethod::neubauer}) {
    CellIsoOptions roots;
    roots.method = method;
    double worst_position = 0, worst_value = 0;
    auto const keep_param = [](FirstHitQuery<scalar, 8>& q) {
      q.want_param = true;
      q.param = {-7.f, -7.f, -7.f};  // must be overwritten at a hit
    };
    int const hits = test::for_each_first_hit(tree, mesh, isos, roots, cam, keep_param,
                                              [&](FirstHitQuery<scalar, 8> const& q, Ray const& ray) {
      ref::Hex const h = ref::load(mesh, tree.item(uint64_t(q.hit.item)));
      glm::dvec3 const u(q.param.x, q.param.y, q.param.z);
      glm::dvec3 const hit = glm::dvec3(ray.org) + double(q.hit.t) * glm::dvec3(ray.dir);
      double edge = 0;  // the cell's size: its largest distance from corner 0
      for (int i = 1; i < 8; ++i) edge = std::max(edge, glm::length(h.p[i] - h.p[0]));
      INFO("u " << u.x << " " << u.y << " " << u.z);
      for (int a = 0; a < 3; ++a) {
        CHECK(u[a] >= -1e-3);
        CHECK(u[a] <= 1 + 1e-3);
      }
      // The exact method refines t after its last inversion, so the
      // coordinates lie one Newton step behind the hit; Neubauer inverts at
      // the root itself.
      double const dp = glm::length(ref::position(h, u) - hit) / edge;
      worst_position = std::max(worst_position, dp);
      CHECK(dp < 1e-3);
      double const dv = std::abs(ref::value(h, u) - double(isos.values[q.hit.iso]));
      worst_value = std::max(worst_value, dv);
      CHECK(dv < 1e-3);
    });
    INFO("worst position error " << worst_position << " of the cell size, value error " << worst_value);
    CHECK(hits > 100);
  }
}

}  // namespace test_traverse_hex_param
