// first_hits (the host ray query) with analytic normals takes them from the
// gradient the first-hit query keeps at each hit (as the renderer does),
// not from a second corner load and point location per ray. Checked on
// every ISA against the double reference's gradient of the hit cell at the
// hit point (cells/reference.hpp), for tets on an offset field (a large
// value offset, as a temperature near 400 K) and for jittered hexes.

#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/reference.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/camera.hpp>
#include <cellray/traverse/queries.hpp>

#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_traverse_first_hit_normals {

using namespace cellray;

namespace {

std::vector<Ray> camera_rays(int w, int h) {
  Camera const cam = Camera::look_at({2.2f, 1.4f, 3.1f}, glm::vec3(0.f), {0, 1, 0}, 50.f, w, h);
  std::vector<Ray> rays;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) rays.push_back({cam.eye, 0.f, cam.direction(float(x), float(y)), 1e30f});
  return rays;
}

/// The reference shading normal: -g / |g| turned to face the ray.
glm::dvec3 reference_normal(glm::dvec3 const& g, glm::vec3 const& dir) {
  glm::dvec3 n = -g / glm::length(g);
  if (glm::dot(n, glm::dvec3(dir)) > 0) n = -n;
  return n;
}

template <int N>
void check_normals(CellMesh<N> const& mesh, std::vector<float> const& isovalues, double max_angle, Traversal how) {
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  TreeView const tree(bvh);
  IsoQuery q;
  q.isos.count = int(isovalues.size());
  for (size_t k = 0; k < isovalues.size(); ++k) q.isos.values[k] = isovalues[k];
  q.traversal = how;
  std::vector<Ray> const rays = camera_rays(64, 48);
  std::vector<SurfaceHit> const hits = first_hits(tree, mesh, rays, q, test::isa());
  int count = 0;
  double worst = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (!hits[i].hit()) continue;
    ref::Cell<N> const c = ref::load(mesh, hits[i].cell);
    glm::dvec3 g;
    if constexpr (N == 4) {
      g = ref::gradient(c);
    } else {
      glm::dvec3 const p = glm::dvec3(rays[i].org) + double(hits[i].t) * glm::dvec3(rays[i].dir);
      ref::Location const at = ref::locate(c, p);
      REQUIRE(at.converged);
      g = ref::gradient(c, at.param);
    }
    if (!(glm::length(g) > 0)) continue;
    ++count;
    glm::dvec3 const want = reference_normal(g, rays[i].dir);
    glm::dvec3 const got(hits[i].normal);
    CHECK(std::abs(glm::length(got) - 1.0) < 1e-5);
    double const angle = std::acos(std::min(1.0, glm::dot(got, want) / glm::length(got)));
    worst = std::max(worst, angle);
    CHECK(angle < max_angle);
  }
  INFO("worst normal angle " << worst << " rad over " << count << " hits");
  CHECK(count > 100);
}

}  // namespace

TEST_CASE("first_hits: analytic normals from the query's gradient match the double reference (tets)",
          "[traverse][isa]") {
  auto const g = generate_tets(6 * 12 * 12 * 12, 3);
  std::vector<float> offset(g.field.size());
  for (size_t v = 0; v < offset.size(); ++v) offset[v] = 400.f + 4.f * g.field[v];
  TetMesh const mesh = g.mesh().with_values(view(offset));
  // A tet's gradient is constant: float rounding of edges, cross products
  // and one division only (a few 1e-7 relative, test_traverse_tet_gradient):
  // 1e-5 rad leaves room for thin cells.
  for (Traversal how : {Traversal::packet, Traversal::spmd}) check_normals<4>(mesh, {401.7f, 402.3f}, 1e-5, how);
}

TEST_CASE("first_hits: analytic normals from the query's gradient match the double reference (hexes)",
          "[traverse][isa]") {
  auto const g = generate_hexes(12 * 12 * 12, 3);
  HexMesh const mesh = g.mesh();
  // The query evaluates the gradient at the float root's trilinear
  // coordinates, the reference at the double inversion of the float hit
  // point: both within float rounding of the same point of a curved
  // (jittered) cell, where the gradient turns slowly (measured worst 7.9e-6
  // rad over 373 hits, AVX2 and AVX-512); 1e-4 rad (0.006 degree, invisible
  // in shading) leaves room for other roundings (SSE without FMA, clang).
  for (Traversal how : {Traversal::packet, Traversal::spmd}) check_normals<8>(mesh, {0.3f, 0.5f}, 1e-4, how);
}

}  // namespace test_traverse_first_hit_normals
