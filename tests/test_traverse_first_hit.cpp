#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/vtk_cells.hpp>
#include <cellray/render/camera.hpp>
#include <cellray/traverse/occlusion_query.hpp>
#include <cellray/traverse/queries.hpp>

#include "support/brute_force.hpp"
#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_traverse_first_hit {

using namespace cellray;

namespace {

std::vector<Ray> camera_rays(int w, int h, glm::vec3 eye) {
  Camera cam = Camera::look_at(eye, glm::vec3(0.f), glm::vec3(0, 1, 0), 50.f, w, h);
  std::vector<Ray> rays;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) rays.push_back({cam.eye, 0.f, cam.direction(float(x), float(y)), 1e30f});
  return rays;
}

std::vector<Ray> random_rays(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.2f, 1.2f);
  std::vector<Ray> rays;
  for (int i = 0; i < n; ++i) {
    glm::vec3 o(u(rng), u(rng), u(rng)), d(u(rng), u(rng), u(rng));
    rays.push_back({o, 0.f, d, 1e30f});
  }
  return rays;
}

}  // namespace

TEST_CASE("first hit: packet, SPMD, hybrid and single-ray agree with a brute-force double oracle", "[traverse][isa]") {
  auto g = generate_tets(6 * 9 * 9 * 9, 7);
  TetMesh const mesh = g.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  TreeView const tree(bvh);
  std::vector<float> const isos = {0.3f, 0.5f};
  IsoQuery q;
  q.isos.count = 2;
  q.isos.values[0] = isos[0];
  q.isos.values[1] = isos[1];

  auto rays = camera_rays(24, 18, {2.2f, 1.4f, 3.1f});
  auto incoherent = random_rays(300, 5);
  rays.insert(rays.end(), incoherent.begin(), incoherent.end());

  std::vector<test::RefHit> ref;
  for (auto const& r : rays) ref.push_back(test::brute_force_first_hit(mesh, r, isos));
  int ref_hits = 0;
  for (auto const& h : ref) ref_hits += std::isfinite(h.t);
  REQUIRE(ref_hits > 100);

  for (Traversal tv : {Traversal::packet, Traversal::spmd, Traversal::hybrid}) {
    q.traversal = tv;
    INFO("traversal " << traversal_name(tv) << " on " << isa_name(test::isa()));
    auto hits = first_hits(tree, mesh, rays, q, test::isa());
    int missed = 0, spurious = 0, far = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      bool const rh = std::isfinite(ref[i].t);
      if (rh && !hits[i].hit()) ++missed;
      if (!rh && hits[i].hit()) ++spurious;
      if (rh && hits[i].hit()) {
        // 1e-5 relative of the ray length to the hit, as the issue states.
        if (std::abs(hits[i].t - ref[i].t) > 1e-5 * std::max(1.0, ref[i].t)) ++far;
        else CHECK(hits[i].iso == ref[i].iso);
        float const dn = glm::dot(hits[i].normal, rays[i].dir);
        CHECK(dn <= 0.f);  // shading normal faces the viewer
      }
    }
    CHECK(missed == 0);
    CHECK(spurious == 0);
    CHECK(far == 0);
  }
}

TEST_CASE("first hit: an empty tree finds nothing, and a [tmin, tmax] window is honoured", "[traverse][isa]") {
  auto g = generate_tets(6 * 5 * 5 * 5, 2);
  TetMesh const mesh = g.mesh();
  IsoQuery q;
  q.isos.count = 1;
  q.isos.values[0] = 0.5f;
  auto rays = camera_rays(8, 8, {0.3f, 0.2f, 3.f});
  MinMaxBvh const empty;
  for (auto const& h : first_hits(TreeView(empty), mesh, rays, q, test::isa())) CHECK_FALSE(h.hit());

  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  auto full = first_hits(TreeView(bvh), mesh, rays, q, test::isa());
  // Continuing behind each hit finds the next crossing, never the same one.
  std::vector<Ray> behind = rays;
  for (size_t i = 0; i < rays.size(); ++i)
    if (full[i].hit()) behind[i].tmin = full[i].t * (1.f + 1e-5f);
  auto next = first_hits(TreeView(bvh), mesh, behind, q, test::isa());
  int continued = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (!full[i].hit()) continue;
    auto ref = test::brute_force_first_hit(mesh, behind[i], {0.5f});
    CHECK(next[i].hit() == std::isfinite(ref.t));
    if (next[i].hit()) {
      ++continued;
      CHECK(next[i].t > full[i].t);
      CHECK(next[i].t == Approx(ref.t).epsilon(1e-5));
    }
  }
  CHECK(continued > 0);
}

TEST_CASE("first hit: tets stored as hexahedra (folded) hit as the tets do, through the tet kernels",
          "[traverse][isa]") {
  // Every tet as the hexahedron 0 1 2 2 3 3 3 3 (fold_tets_into_hexes):
  // the same boxes give the same tree, so packets meet the same cells in the
  // same order; a packet leaf hands a folded tet to the tet kernels
  // (CellOps<A, 8>::is_folded_tet), so the hits are the tets' bit for bit:
  // t, cell, isovalue and the (constant) gradient's normal. The trilinear
  // root search on the same cell agrees only to its tolerance.
  auto g = generate_tets(6 * 9 * 9 * 9, 7);
  TetMesh const tets = g.mesh();
  std::vector<uint32_t> folded;
  for (size_t c = 0; c + 4 <= g.cells.size(); c += 4)
    for (int k : tet_as_hex) folded.push_back(g.cells[c + size_t(k)]);
  HexMesh const hexes{view(g.xyz), view(folded), view(g.field)};
  MinMaxBvh const tb = build_minmax_bvh(tets), hb = build_minmax_bvh(hexes);
  REQUIRE(tb.node_count() == hb.node_count());
  IsoQuery q;
  q.isos.count = 2;
  q.isos.values[0] = 0.3f, q.isos.values[1] = 0.5f;
  auto rays = camera_rays(24, 18, {2.2f, 1.4f, 3.1f});
  auto incoherent = random_rays(300, 5);
  rays.insert(rays.end(), incoherent.begin(), incoherent.end());
  INFO("on " << isa_name(test::isa()));
  std::vector<SurfaceHit> const a = first_hits(TreeView(tb), tets, rays, q, test::isa());
  std::vector<SurfaceHit> const b = first_hits(TreeView(hb), hexes, rays, q, test::isa());
  int hits = 0, differ = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    hits += a[i].hit();
    differ += a[i].t != b[i].t || a[i].cell != b[i].cell || a[i].iso != b[i].iso || a[i].normal != b[i].normal;
  }
  CHECK(hits > 100);
  CHECK(differ == 0);
  // Shadow rays (the packet occlusion query) from points on the surface.
  std::vector<Ray> shadow;
  for (size_t i = 0; i < rays.size(); ++i)
    if (a[i].hit()) shadow.push_back({rays[i].org + a[i].t * rays[i].dir, 1e-4f, glm::vec3(0.3f, 0.8f, 0.5f), 1e30f});
  std::vector<uint8_t> const sa = occluded_rays(TreeView(tb), tets, shadow, q, false, test::isa());
  std::vector<uint8_t> const sb = occluded_rays(TreeView(hb), hexes, shadow, q, false, test::isa());
  CHECK(sa == sb);
  int occluded = 0;
  for (uint8_t x : sa) occluded += x;
  CHECK(occluded > int(shadow.size()) / 10);
  // SPMD leaves clip a folded tet with the tet kernel too (HexClip::linear)
  // and search the root with the hexahedron's (trilinear) method: the same
  // hits to its tolerance.
  q.traversal = Traversal::spmd;
  std::vector<SurfaceHit> const c = first_hits(TreeView(hb), hexes, rays, q, test::isa());
  int far = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    CHECK(a[i].hit() == c[i].hit());
    if (a[i].hit() && c[i].hit()) far += std::abs(a[i].t - c[i].t) > 1e-6f * std::max(1.f, a[i].t);
  }
  CHECK(far == 0);
}

}  // namespace test_traverse_first_hit
