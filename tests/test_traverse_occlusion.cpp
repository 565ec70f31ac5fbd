// The occlusion (any-hit) query (traverse/occlusion_query.hpp) against the
// double-precision reference renderer's crossings (an oracle without a
// float kernel or the fast tree) and against first_hits (the meaning it
// promises: occluded exactly when the nearest-hit query finds a hit), on
// jittered and regular lattices, with AO-like rays leaving surface points,
// grazing rays in lattice faces and rays along shared edges.

#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/camera.hpp>
#include <cellray/render/reference.hpp>
#include <cellray/traverse/occlusion_query.hpp>

#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_traverse_occlusion {

using namespace cellray;

namespace {

/// Rays of every kind a shadow or AO query meets, for a mesh in [-1, 1]^3
/// whose first hits `hits` of `camera` rays are known: the camera rays
/// themselves (long), random short segments, AO-like rays from just above
/// each hit (random hemisphere directions, length 0.3), and segments ending
/// just before and just after each first hit (the window's ends).
std::vector<Ray> mixed_rays(std::vector<Ray> const& camera, std::vector<SurfaceHit> const& hits, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.2f, 1.2f), u01(0.f, 1.f);
  std::vector<Ray> rays = camera;
  for (int i = 0; i < 200; ++i)
    rays.push_back({{u(rng), u(rng), u(rng)}, 0.f, {u(rng), u(rng), u(rng)}, 0.05f + 0.5f * u01(rng)});
  for (size_t i = 0; i < camera.size(); ++i) {
    if (!hits[i].hit()) continue;
    glm::vec3 const p = camera[i].org + hits[i].t * camera[i].dir, n = hits[i].normal;
    for (int k = 0; k < 3; ++k) {
      glm::vec3 d(u(rng), u(rng), u(rng));
      if (glm::dot(d, n) < 0.f) d = -d;
      rays.push_back({p + 1e-4f * n, 1e-4f, d, 0.3f});
    }
    Ray before = camera[i], after = camera[i];
    before.tmax = 0.99f * hits[i].t;  // nothing nearer than the nearest hit
    after.tmax = 1.01f * hits[i].t;
    rays.push_back(before);
    rays.push_back(after);
  }
  return rays;
}

/// Rays in the planes and along the lines of a regular lattice of `n` cells
/// per side over [-1, 1]^3: along shared edges (through every vertex on the
/// line) and grazing faces, in both directions.
std::vector<Ray> lattice_rays(int n) {
  std::vector<Ray> rays;
  float const h = 2.f / float(n);
  for (int i = 1; i < n; i += 2)
    for (int j = 1; j < n; j += 2) {
      float const a = -1.f + float(i) * h, b = -1.f + float(j) * h;
      rays.push_back({{-1.5f, a, b}, 0.f, {1.f, 0.f, 0.f}, 3.f});                 // along an edge
      rays.push_back({{a, 1.5f, b}, 0.f, {0.f, -1.f, 0.f}, 3.f});                 // along an edge
      rays.push_back({{-1.5f, a, b + 0.5f * h}, 0.f, {1.f, 0.f, 0.f}, 3.f});      // in a face plane
      rays.push_back({{-1.5f, -1.5f, b}, 0.f, {1.f, 1.f, 0.f}, 3.f});             // face diagonals
      rays.push_back({{a, b, -1.5f}, 0.f, {0.f, 0.f, 1.f}, 3.f});                 // along an edge
    }
  return rays;
}

/// The reference renderer's answer: a crossing at t in [tmin, tmax]. A ray
/// whose only crossings near the segment lie within 2e-5 world units of an
/// end is `ambiguous`: float positions and roots (errors ~1e-6 here) may put
/// such a crossing on either side, so the caller skips it. The AO-like
/// rays start 1e-4 above their surface, well clear of that margin.
bool reference_occluded(ref_render::Setup const& s, Ray const& r, IsoParams const& p, bool& ambiguous) {
  std::vector<ref_render::Crossing> xs;
  ref::Ray const rr{glm::dvec3(r.org), glm::dvec3(r.dir)};
  double const margin = 2e-5 / glm::length(glm::dvec3(r.dir));
  ref_render::iso_crossings(s, rr, double(r.tmin) - margin, double(r.tmax) + margin, p, {}, xs);
  ambiguous = false;
  bool inside = false;
  for (auto const& x : xs) {
    bool const near_end = std::abs(x.t - double(r.tmin)) <= margin || std::abs(x.t - double(r.tmax)) <= margin;
    ambiguous = ambiguous || near_end;
    inside = inside || (!near_end && x.t >= double(r.tmin) && x.t <= double(r.tmax));
  }
  ambiguous = ambiguous && !inside;
  return inside;
}

template <int N>
void check_occlusion(std::string const& name, CellMesh<N> const& mesh, std::vector<float> const& isos,
                     std::vector<Ray> const& extra, BuildOptions const& build = {}) {
  MinMaxBvh const bvh = build_minmax_bvh(mesh, build);
  TreeView const tree(bvh);
  IsoQuery q;
  IsoParams p;
  q.isos.count = int(isos.size());
  for (size_t k = 0; k < isos.size(); ++k) q.isos.values[k] = isos[k], p.surfaces.push_back({isos[k]});
  Camera const cam = Camera::look_at({2.2f, 1.4f, 3.1f}, glm::vec3(0.f), {0.f, 1.f, 0.f}, 50.f, 20, 16);
  std::vector<Ray> camera;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) camera.push_back({cam.eye, 0.f, cam.direction(float(x), float(y)), 1e30f});
  std::vector<Ray> rays = mixed_rays(camera, first_hits(tree, mesh, camera, q, test::isa()), 11);
  rays.insert(rays.end(), extra.begin(), extra.end());

  Scene const scene(mesh, bvh);
  ref_render::Setup const s = ref_render::prepare(scene);
  std::vector<int> ref(rays.size());
  int occluded = 0, ambiguous = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    bool amb = false;
    ref[i] = reference_occluded(s, rays[i], p, amb) ? 1 : amb ? -1 : 0;
    occluded += ref[i] == 1;
    ambiguous += ref[i] == -1;
  }
  INFO(name << " on " << isa_name(test::isa()) << ": " << rays.size() << " rays, " << occluded << " occluded, "
            << ambiguous << " ambiguous");
  REQUIRE(occluded > 50);  // both answers well represented
  REQUIRE(occluded < int(rays.size()) - 50);
  CHECK(ambiguous < int(rays.size() / 50));

  std::vector<SurfaceHit> const nearest = first_hits(tree, mesh, rays, q, test::isa());
  for (Traversal tv : {Traversal::packet, Traversal::spmd, Traversal::hybrid})
    for (bool grouped : {false, true}) {
      if (grouped && tv != Traversal::packet) continue;  // grouped packets always traverse as one packet
      q.traversal = tv;
      INFO(traversal_name(tv) << (grouped ? ", grouped" : ""));
      std::vector<uint8_t> const occ = occluded_rays(tree, mesh, rays, q, grouped, test::isa());
      int wrong = 0, unlike_nearest = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        if (ref[i] >= 0 && occ[i] != ref[i]) ++wrong;
        if (occ[i] != uint8_t(nearest[i].hit())) ++unlike_nearest;
      }
      CHECK(wrong == 0);
      // The same cell code on the same data (grouped packets: one cell and
      // one ray per lane, TetPairs): the nearest-hit query's answers.
      CHECK(unlike_nearest == 0);
    }
}

}  // namespace

TEST_CASE("occlusion: packet, SPMD, hybrid and grouped packets match the reference and the nearest hit",
          "[traverse][isa]") {
  SECTION("jittered tets, two isovalues") {
    auto g = generate_tets(6 * 9 * 9 * 9, 7);
    check_occlusion("tets", g.mesh(), {0.3f, 0.5f}, {});
  }
  SECTION("jittered hexes") {
    auto g = generate_hexes(9 * 9 * 9, 3);
    check_occlusion("hexes", g.mesh(), {0.45f}, {});
  }
  SECTION("regular lattices: rays along shared edges and grazing faces") {
    auto t = generate_tets(6 * 8 * 8 * 8, 1, 0.f);
    check_occlusion("regular tets", t.mesh(), {0.4f}, lattice_rays(8));
    auto h = generate_hexes(8 * 8 * 8, 1, 0.f);
    check_occlusion("regular hexes", h.mesh(), {0.4f}, lattice_rays(8));
  }
  SECTION("leaves of up to 20 cells") {
    BuildOptions big;
    big.max_leaf_size = 20;
    big.builder = BvhBuilder::morton;  // a range of up to 20 cells is always one leaf
    auto g = generate_tets(6 * 9 * 9 * 9, 7);
    check_occlusion("tets, leaves of 20", g.mesh(), {0.3f, 0.5f}, {}, big);
    auto h = generate_hexes(9 * 9 * 9, 3);
    check_occlusion("hexes, leaves of 20", h.mesh(), {0.45f}, {}, big);
  }
}

TEST_CASE("occlusion: an empty tree, NaN values and empty segments occlude nothing", "[traverse][isa]") {
  auto g = generate_tets(6 * 5 * 5 * 5, 2);
  TetMesh const mesh = g.mesh();
  IsoQuery q;
  q.isos.count = 1;
  q.isos.values[0] = 0.5f;
  std::vector<Ray> rays;
  for (int i = 0; i < 40; ++i) rays.push_back({{-1.5f, -0.9f + 0.045f * float(i), 0.1f}, 0.f, {1.f, 0.05f, 0.02f}, 4.f});
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  std::vector<uint8_t> const all = occluded_rays(TreeView(bvh), mesh, rays, q, false, test::isa());
  int hits = 0;
  for (uint8_t o : all) hits += o;
  REQUIRE(hits > 10);  // the probe rays do cross the surface
  MinMaxBvh const empty;
  for (bool grouped : {false, true}) {
    for (uint8_t o : occluded_rays(TreeView(empty), mesh, rays, q, grouped, test::isa())) CHECK(o == 0);
    std::vector<float> const nan(mesh.vertex_count(), std::numeric_limits<float>::quiet_NaN());
    TetMesh const nan_mesh = mesh.with_values(view(nan));
    MinMaxBvh const nan_bvh = build_minmax_bvh(nan_mesh);
    for (uint8_t o : occluded_rays(TreeView(nan_bvh), nan_mesh, rays, q, grouped, test::isa())) CHECK(o == 0);
    std::vector<Ray> reversed = rays;  // tmin > tmax: an empty segment
    for (Ray& r : reversed) r.tmin = 5.f;
    for (uint8_t o : occluded_rays(TreeView(bvh), mesh, reversed, q, grouped, test::isa())) CHECK(o == 0);
  }
}

}  // namespace test_traverse_occlusion
