// Shadow and ambient-occlusion rays (RenderOptions::secondary_query): every
// query renders the image of the nearest-hit query bit for bit (opaque
// surfaces, semi-transparent ones of one opacity, and of several opacities,
// where shadows keep the nearest hit's opacity), on tets, hexes and a
// two-part scene, tets and hexes with face neighbours (AO rays march) with
// and without holes, and a mixed mesh's two parts with linked neighbours
// (AO rays march across both); and the default matches the
// double-precision reference renderer with shadows and AO.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>

#include "support/cell_subsets.hpp"
#include "support/render_fixtures.hpp"
#include "support/sanitized.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_occlusion {

using namespace cellray;

namespace {

/// Largest channel difference between two images of one size.
float max_difference(Image const& a, Image const& b) {
  REQUIRE(a.rgba.size() == b.rgba.size());
  float m = 0.f;
  for (size_t i = 0; i < a.rgba.size(); ++i) m = std::max(m, std::abs(a.rgba[i] - b.rgba[i]));
  return m;
}

/// Lit parameter sets: opaque; two surfaces of one opacity 0.5 (any-hit
/// shadows still exact); three of different opacities (shadows fall back to
/// the nearest hit). AO sample counts not multiples of 4 leave a partial
/// chunk of regrouped rays.
std::vector<std::pair<std::string, IsoParams>> lit_params() {
  std::vector<std::pair<std::string, IsoParams>> out;
  IsoParams p;
  p.shadows = true;
  p.light_dir = {0.3f, 1.f, 0.5f};
  p.surfaces = {{0.45f, {0.9f, 0.7f, 0.2f}, 1.f}};
  p.ao_samples = 5;
  out.push_back({"opaque, shadows, AO 5", p});
  p.surfaces = {{0.3f, {0.3f, 0.5f, 0.9f}, 0.5f}, {0.55f, {0.9f, 0.2f, 0.2f}, 0.5f}};
  p.ao_samples = 4;
  out.push_back({"two surfaces of opacity 0.5, shadows, AO 4", p});
  p.surfaces = {{0.25f, {0.3f, 0.5f, 0.9f}, 0.4f}, {0.45f, {0.9f, 0.7f, 0.2f}, 0.6f}, {0.6f, {0.9f, 0.2f, 0.2f}, 1.f}};
  p.ao_samples = 3;
  p.light_dir = {0.f, 0.f, 0.f};  // the headlight
  out.push_back({"three opacities, headlight shadows, AO 3", p});
  return out;
}

void check_queries_agree(std::string const& name, Scene const& scene, int size) {
  Camera const cam = test::camera_for(scene, size, size);
  for (auto const& [what, p] : lit_params()) {
    for (Traversal tv : {Traversal::packet, Traversal::spmd, Traversal::hybrid}) {
      RenderOptions o = test::isa_options();
      o.secondary_traversal = tv;
      o.secondary_query = SecondaryQuery::nearest;
      Image const nearest = render_iso(scene, cam, p, o);
      for (SecondaryQuery q : {SecondaryQuery::occlusion, SecondaryQuery::sorted, SecondaryQuery::grouped,
                               SecondaryQuery::march}) {
        o.secondary_query = q;
        INFO(name << ", " << what << ", " << secondary_query_name(q) << ", " << traversal_name(tv) << " on "
                  << isa_name(test::isa()));
        CHECK(max_difference(render_iso(scene, cam, p, o), nearest) == 0.f);
      }
    }
  }
}

constexpr int frame = test::full_or_sanitized(64, 32);

/// The generated mesh's cells less two slabs (their centroids' |x| <= 0.15
/// or |y - 0.3| <= 0.1): AO rays leave the mesh through the holes' faces.
template <int N> std::vector<uint32_t> with_holes(GeneratedMesh<N> const& g) {
  return test::cells_without(g, [](glm::vec3 m) { return !(std::abs(m.x) > 0.15f && std::abs(m.y - 0.3f) > 0.1f); });
}


}  // namespace

TEST_CASE("shadow and AO queries: occlusion, sorted, grouped and march render the nearest-hit image bit for bit",
          "[render][isa]") {
  auto t = generate_tets(20000, 2);
  auto h = generate_hexes(4000, 2);
  auto const lt = test::load(t.mesh());
  auto const lh = test::load(h.mesh());
  check_queries_agree("tets", lt->scene(), frame);
  // With face neighbours AO rays march (without, `march` is `grouped`);
  // a mesh with holes makes AO rays leave it and finish in the tree.
  TetNeighbours const nb = build_tet_neighbours(lt->mesh);
  check_queries_agree("tets with face neighbours", Scene(lt->mesh, lt->bvh, nullptr, &nb), frame);
  std::vector<uint32_t> const holed = with_holes(t);
  auto const lholed = test::load(TetMesh{view(t.xyz), view(holed), view(t.field)});
  TetNeighbours const nb_holed = build_tet_neighbours(lholed->mesh);
  check_queries_agree("tets with holes and face neighbours", Scene(lholed->mesh, lholed->bvh, nullptr, &nb_holed),
                      frame);
  check_queries_agree("hexes", lh->scene(), frame);
  HexNeighbours const hnb = build_hex_neighbours(lh->mesh);
  check_queries_agree("hexes with face neighbours", Scene(lh->mesh, lh->bvh, nullptr, &hnb), frame);
  std::vector<uint32_t> const hex_holed = with_holes(h);
  auto const lhex_holed = test::load(HexMesh{view(h.xyz), view(hex_holed), view(h.field)});
  HexNeighbours const hnb_holed = build_hex_neighbours(lhex_holed->mesh);
  check_queries_agree("hexes with holes and face neighbours",
                      Scene(lhex_holed->mesh, lhex_holed->bvh, nullptr, &hnb_holed), frame);
  Scene both = lt->scene();  // two overlapping parts: a ray occluded by the first skips the second
  both.hexes.push_back({lh->mesh, &lh->bvh, nullptr});
  check_queries_agree("tets + hexes", both, frame);
}

TEST_CASE("shadow and AO queries on a mixed mesh's two linked parts: AO rays march across both, the same image",
          "[render][isa]") {
  // gmsh's hex block glued to a tet block, pyramids between
  // (tests/data/gmsh/mixed22.msh), a curved field.
  UnstructuredGrid g = read_mesh(std::string(CELLRAY_TEST_DATA) + "/gmsh/mixed22.msh");
  REQUIRE(g.tet_count() > 0);
  REQUIRE(g.hex_count() > 0);
  std::vector<float> field = test::curved_field(g.xyz);
  // lit_params' isovalues lie in [0.25, 0.6]: map the field onto [0, 1].
  float const lo = *std::min_element(field.begin(), field.end()), hi = *std::max_element(field.begin(), field.end());
  for (float& f : field) f = (f - lo) / (hi - lo);
  TetMesh const tm = g.tet_mesh().with_values(view(field));
  HexMesh const hm = g.hex_mesh().with_values(view(field));
  MinMaxBvh const tb = build_minmax_bvh(tm), hb = build_minmax_bvh(hm);
  TetNeighbours tn = build_tet_neighbours(tm);
  HexNeighbours hn = build_hex_neighbours(hm);
  link_face_neighbours(tm, tn, hm, hn);
  Scene linked;
  linked.tets.push_back({tm, &tb, nullptr, &tn});
  linked.hexes.push_back({hm, &hb, nullptr, nullptr, &hn});
  check_queries_agree("mixed22, two linked parts", linked, frame);
}

TEST_CASE("fast vs reference: shadows and ambient occlusion with the default secondary query", "[render][reference][isa]") {
  auto t = generate_tets(20000, 4);
  auto h = generate_hexes(4000, 4);
  auto const lt = test::load(t.mesh());
  auto const lh = test::load(h.mesh());
  TetNeighbours const nb = build_tet_neighbours(lt->mesh);
  HexNeighbours const hnb = build_hex_neighbours(lh->mesh);
  for (int which = 0; which < 2; ++which) {
    Scene const scene = which == 0 ? Scene(lt->mesh, lt->bvh, nullptr, &nb) : Scene(lh->mesh, lh->bvh, nullptr, &hnb);
    Camera const cam = test::camera_for(scene, 2 * frame, 2 * frame);
    RenderOptions const o = test::isa_options();
    REQUIRE(o.secondary_query == SecondaryQuery::march);
    for (auto const& [what, p] : lit_params()) {
      std::string const name = std::string(which == 0 ? "tets" : "hexes") + ", " + what;
      ImageDiff const d = compare_images(render_iso(scene, cam, p, o), render_iso_reference(scene, cam, p), 2.0);
      test::report(name, d);
      INFO(name << " on " << isa_name(test::isa()));
      CHECK(d.nonfinite == 0);
      // An AO or shadow ray that grazes a surface may flip between the float
      // and double answers (one AO ray moves a pixel by ambient / samples,
      // up to 0.2 / 3 = 17/255), and a layer hit at a silhouette more:
      // measured at most 0.12% of pixels over 2/255 (128x128); bound 1%.
      CHECK(d.frac_over <= 0.01);
    }
  }
}

}  // namespace test_render_occlusion
