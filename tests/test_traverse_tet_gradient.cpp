// The gradient the first-hit query keeps at tet hits (FirstHitQuery with
// want_gradient: the renderer's analytic shading normals, computed in the
// leaf from the corners it already loaded) against the double-precision
// gradient of the hit cell (cells/reference.hpp), on a field with a large
// offset as real data has (a temperature near 400 varying by a few units).
// Runs the scalar arch here; the SIMD widths run the same code in
// test_render_tet_normals.cpp through render_iso.

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
namespace test_traverse_tet_gradient {

using namespace cellray;

TEST_CASE("first hit: the tet gradient kept at each hit matches the double reference", "[traverse]") {
  auto const g = generate_tets(6 * 12 * 12 * 12, 3);
  std::vector<float> offset(g.field.size());
  for (size_t v = 0; v < offset.size(); ++v) offset[v] = 400.f + 4.f * g.field[v];
  TetMesh const mesh = g.mesh().with_values(view(offset));
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  TreeView const tree(bvh);
  Camera const cam = Camera::look_at({2.2f, 1.4f, 3.1f}, glm::vec3(0.f), {0, 1, 0}, 50.f, 48, 36);
  double worst = 0;
  int const hits = test::for_each_first_hit(
      tree, mesh, test::iso_set({401.7f, 402.3f}), CellIsoOptions{}, cam,
      [](FirstHitQuery<scalar, 4>& q) { q.want_gradient = true; },
      [&](FirstHitQuery<scalar, 4> const& q, Ray const&) {
        glm::dvec3 const want = ref::gradient(ref::load(mesh, tree.item(uint64_t(q.hit.item))));
        glm::dvec3 const got(q.grad.x, q.grad.y, q.grad.z);
        REQUIRE(glm::length(want) > 0);
        // Float corner positions and values are the reference's exact inputs;
        // the value differences are exact in float (Sterbenz), so what is left
        // is the rounding of edges, three cross products and one division on
        // well-shaped cells: a few 1e-7 relative (measured worst 3.6e-7).
        // 1e-5 leaves room for thinner cells.
        double const err = glm::length(got - want) / glm::length(want);
        worst = std::max(worst, err);
        CHECK(err < 1e-5);
      });
  INFO("worst relative gradient error " << worst);
  CHECK(hits > 100);  // 143 of the 1728 rays hit
}

}  // namespace test_traverse_tet_gradient
