#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/bvh/refit.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/mesh/vtk_cells.hpp>
#include <cellray/render/render.hpp>

#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_basic {

using namespace cellray;

namespace {

/// Fraction of pixels whose 8-bit colour differs by more than `tol` levels.
double fraction_off(Image const& a, Image const& b, int tol) {
  auto pa = a.to_rgba8(), pb = b.to_rgba8();
  REQUIRE(pa.size() == pb.size());
  size_t off = 0;
  for (size_t i = 0; i < pa.size(); i += 4) {
    bool bad = false;
    for (int c = 0; c < 3; ++c) bad |= std::abs(int(pa[i + c]) - int(pb[i + c])) > tol;
    off += bad;
  }
  return double(off) / double(pa.size() / 4);
}

double rmse8(Image const& a, Image const& b) {
  double s = 0;
  for (size_t i = 0; i < a.rgba.size(); ++i) {
    double const d = 255.0 * (double(a.rgba[i]) - double(b.rgba[i]));
    s += d * d;
  }
  return std::sqrt(s / double(a.rgba.size()));
}

bool has_structure(Image const& img) {
  auto px = img.to_rgba8();
  int distinct = 0;
  for (size_t i = 4; i < px.size(); i += 4) distinct += px[i] != px[0] || px[i + 1] != px[1] || px[i + 2] != px[2];
  return distinct > int(px.size() / 4 / 20);  // at least 5% of pixels differ from the corner
}

/// The host's depth for the grouped-traversal tests: infinite on the
/// image's left third, elsewhere a ramp down the image that ends some rays
/// inside the mesh.
std::vector<float> depth_ramp(Camera const& cam, glm::vec3 lo, glm::vec3 hi) {
  std::vector<float> d(size_t(cam.width) * size_t(cam.height));
  float const dist = glm::length(cam.eye - 0.5f * (lo + hi));
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      d[size_t(y) * size_t(cam.width) + size_t(x)] = x < cam.width / 3
                                                         ? std::numeric_limits<float>::infinity()
                                                         : dist * (0.8f + 0.4f * float(y) / float(cam.height));
  return d;
}

/// Packet traversal (eight pixel blocks together: group_x x group_y), or
/// hybrid with a threshold of 1 (packet traversal, one block at a time).
/// Tiles of 20 pixels hold whole groups (8x4, 8x8 or 16x8 pixels) and cut
/// others.
RenderOptions grouped_or_alone(Traversal t) {
  RenderOptions o;
  o.isa = test::isa();
  o.traversal = t;
  o.hybrid_threshold = 1;
  o.tile_size = 20;
  return o;
}

IsoParams three_surfaces() {
  IsoParams p;
  p.surfaces = {{0.25f, {0.3f, 0.5f, 0.9f}, 0.4f}, {0.45f, {0.9f, 0.7f, 0.2f}, 0.6f}, {0.6f, {0.9f, 0.2f, 0.2f}, 1.f}};
  return p;
}

}  // namespace

TEST_CASE("iso and DVR: packet, SPMD and hybrid render the same image on every ISA", "[render][isa]") {
  auto tets = generate_tets(20000, 2);
  auto hexes = generate_hexes(4000, 2);
  TetMesh const tm = tets.mesh();
  HexMesh const hm = hexes.mesh();
  MinMaxBvh const tb = build_minmax_bvh(tm), hb = build_minmax_bvh(hm);
  for (int which = 0; which < 2; ++which) {
    Scene const scene = which == 0 ? Scene(tm, tb) : Scene(hm, hb);
    glm::vec3 lo, hi;
    scene.bounds(lo, hi);
    Camera const cam = fit_camera(lo, hi, 96, 80);
    IsoParams iso = three_surfaces();
    iso.shadows = true;
    iso.ao_samples = 2;
    DvrParams dvr;
    dvr.tf = transfer_function_preset("viridis", 0.f, 0.75f);
    dvr.tf.unit_distance = 0.2f;
    RenderOptions o;
    o.isa = isa_available(Isa::sse4_2) ? Isa::sse4_2 : test::isa();  // a sanitizer build has one ISA
    Image const iso_ref = render_iso(scene, cam, iso, o);
    Image const dvr_ref = render_dvr(scene, cam, dvr, o);
    CHECK(has_structure(iso_ref));
    CHECK(has_structure(dvr_ref));
    o.isa = test::isa();
    for (Traversal t : {Traversal::packet, Traversal::spmd, Traversal::hybrid}) {
      o.traversal = o.secondary_traversal = t;
      INFO((which == 0 ? "tets " : "hexes ") << traversal_name(t) << " on " << isa_name(test::isa()));
      // Different ISAs round differently (FMA, lane order of gathers);
      // a pixel may flip at a silhouette or shadow edge, nothing more.
      CHECK(fraction_off(render_iso(scene, cam, iso, o), iso_ref, 2) < 0.003);
      CHECK(fraction_off(render_dvr(scene, cam, dvr, o), dvr_ref, 2) < 0.003);
    }
  }
}

TEST_CASE("iso: eight pixel blocks traced together find the hits each finds alone", "[render][isa]") {
  // Packet traversal finds the first hits of eight pixel blocks in one
  // traversal (traverse_packets), and their hits behind a translucent
  // surface, layer by layer; hybrid traversal with a threshold of 1
  // is packet traversal one block at a time. The first hit's t is the
  // nearest crossing over every cell, whatever the order nodes and cells
  // are visited in: the depth is the same bits. Colours may differ where a
  // ray meets a shared face exactly (either cell's gradient shades it).
  auto tets = generate_tets(6000, 3);
  auto family = generate_hex_family(3000, 2);  // hexahedra, wedges, pyramids
  TetMesh const tm = tets.mesh();
  HexMesh const hm = family.mesh();
  // The tets as collapsed hexahedra (fold_tets_into_hexes' 0 1 2 2 3 3 3 3),
  // which packet leaves clip with the tet kernels.
  GeneratedMesh<8> folded{tets.xyz, {}, tets.field, tets.field_t1, tets.lattice};
  for (size_t c = 0; c < tets.cells.size(); c += 4)
    for (int k : tet_as_hex) folded.cells.push_back(tets.cells[c + size_t(k)]);
  HexMesh const fm = folded.mesh();
  // A regular grid: every face a parallelogram, which grouped packets clip
  // from one setup per cell (hex_window_setup).
  auto grid = generate_hexes(2000, 1, 0.f);
  HexMesh const gm = grid.mesh();
  MinMaxBvh const tb = build_minmax_bvh(tm), hb = build_minmax_bvh(hm), fb = build_minmax_bvh(fm),
                  gb = build_minmax_bvh(gm);
  Scene both(tm, tb);
  both.hexes.push_back({hm, &hb, nullptr, nullptr, nullptr});
  Scene const scenes[] = {Scene(tm, tb), Scene(hm, hb), both, Scene(fm, fb), Scene(gm, gb)};
  char const* const names[] = {"tets", "hex family", "tets and hex family", "tets folded into hexahedra",
                               "regular hexahedra"};
  for (int run = 0; run < 6; ++run) {
    int const which = run % 5;
    bool const clipped = run == 5;  // each packet's span cut by a plane, with caps, before the first hits
    Scene const& scene = scenes[which];
    glm::vec3 lo, hi;
    scene.bounds(lo, hi);
    Camera const cam = fit_camera(lo, hi, 45, 37);  // blocks and groups cut by the tiles' and image's edges
    IsoParams iso;
    iso.surfaces = {{0.3f, {0.9f, 0.7f, 0.4f}, 0.5f}, {0.55f, {0.4f, 0.6f, 0.9f}, 1.f}};
    if (clipped) {
      iso.clip.planes = {{0.5f * (lo + hi), glm::vec3(0.55f, 0.45f, 1.0f)}};
      iso.clip.caps = true;
      iso.clip.cap_colors = transfer_function_preset("viridis", 0.f, 1.f);
    }
    std::vector<float> const depth_in = depth_ramp(cam, lo, hi);
    auto render_with = [&](Traversal t, std::vector<float>& depth) {
      RenderOptions const o = grouped_or_alone(t);
      Image img(cam.width, cam.height);
      FrameBuffer fb = FrameBuffer::of(img);
      fb.depth_in = depth_in.data();
      fb.depth_out = depth.data();
      fb.depth_opacity = 0.4f;  // the first surface's hit (opacity 0.5)
      render(scene, cam, iso, fb, o);
      return img;
    };
    std::vector<float> grouped(depth_in.size()), alone(depth_in.size());
    Image const a = render_with(Traversal::packet, grouped);
    Image const b = render_with(Traversal::hybrid, alone);
    INFO(names[which] << (clipped ? ", clipped" : "") << " on " << isa_name(test::isa()));
    int hits = 0, same = 0;
    for (size_t i = 0; i < grouped.size(); ++i) {
      hits += std::isfinite(alone[i]);
      same += std::memcmp(&grouped[i], &alone[i], sizeof(float)) == 0;
    }
    CHECK(hits > int(grouped.size()) / 10);
    CHECK(same == int(grouped.size()));
    CHECK(fraction_off(a, b, 1) < 0.003);
  }
}

TEST_CASE("DVR: eight pixel blocks locating their first cells together march as each would alone", "[render][isa]") {
  // Marching cell segments: packet traversal locates the first visible
  // cell of eight pixel blocks in one traversal, then each block marches
  // (and locates again after leaving the mesh or a transparent stretch);
  // hybrid traversal with a threshold of 1 locates one block at a time.
  // Each ray starts in the same cell (ties aside: a ray entering through
  // an edge may start in either cell, and integrate the same field).
  auto tets = generate_tets(6000, 3);
  auto family = generate_hex_family(3000, 2);  // hexahedra, wedges, pyramids
  TetMesh const tm = tets.mesh();
  HexMesh const hm = family.mesh();
  // A shell removed from a tet block: rays leave the mesh and enter it
  // again, and cross it where a narrow band of values sees nothing.
  auto block = generate_tets(6 * 12 * 12 * 12, 9);
  std::vector<uint32_t> kept;
  for (size_t c = 0; c + 4 <= block.cells.size(); c += 4) {
    glm::vec3 m(0.f);
    for (int i = 0; i < 4; ++i) {
      uint32_t const v = block.cells[c + size_t(i)];
      m += glm::vec3(block.xyz[3 * v], block.xyz[3 * v + 1], block.xyz[3 * v + 2]);
    }
    float const r = glm::length(0.25f * m);
    if (r < 0.45f || r > 0.7f) kept.insert(kept.end(), block.cells.begin() + long(c), block.cells.begin() + long(c) + 4);
  }
  TetMesh const shell{view(block.xyz), view(kept), view(block.field)};
  MinMaxBvh const tb = build_minmax_bvh(tm), hb = build_minmax_bvh(hm), sb = build_minmax_bvh(shell);
  TetNeighbours const tn = build_tet_neighbours(tm), sn = build_tet_neighbours(shell);
  HexNeighbours const hn = build_hex_neighbours(hm);
  Scene const scenes[] = {Scene(tm, tb, nullptr, &tn), Scene(hm, hb, nullptr, &hn), Scene(shell, sb, nullptr, &sn)};
  char const* const names[] = {"tets", "hex family", "tets, a shell removed, a narrow band of values"};
  for (int which = 0; which < 3; ++which) {
    Scene const& scene = scenes[which];
    glm::vec3 lo, hi;
    scene.bounds(lo, hi);
    Camera const cam = fit_camera(lo, hi, 45, 37);  // blocks and groups cut by the tiles' and image's edges
    DvrParams dvr;
    dvr.tf = transfer_function_preset("viridis", 0.f, 0.75f);
    dvr.tf.unit_distance = 0.2f;
    if (which == 2) {
      dvr.tf.values = {0.f, 0.4f, 0.5f, 0.6f, 1.f};
      dvr.tf.rgba = {{0.1f, 0.2f, 0.9f, 0.f}, {0.1f, 0.2f, 0.9f, 0.f}, {0.9f, 0.6f, 0.1f, 0.8f}, {0.9f, 0.1f, 0.1f, 0.f},
                     {0.9f, 0.1f, 0.1f, 0.f}};
      dvr.tf.unit_distance = 0.1f;
    }
    std::vector<float> const depth_in = depth_ramp(cam, lo, hi);
    auto render_with = [&](Traversal t) {
      RenderOptions const o = grouped_or_alone(t);
      Image img(cam.width, cam.height);
      FrameBuffer fb = FrameBuffer::of(img);
      fb.depth_in = depth_in.data();
      render(scene, cam, dvr, fb, o);
      return img;
    };
    Image const a = render_with(Traversal::packet);
    Image const b = render_with(Traversal::hybrid);
    INFO(names[which] << " on " << isa_name(test::isa()));
    CHECK(has_structure(a));
    CHECK(fraction_off(a, b, 1) < 0.003);
  }
}

TEST_CASE("a time step is a refit: same image as a tree built on that step", "[render][isa]") {
  auto g = generate_tets(15000, 5);
  TetMesh const step0 = g.mesh();
  TetMesh const step1 = step0.with_array("field_t1");
  MinMaxBvh const bvh0 = build_minmax_bvh(step0);
  MinMaxBvh const bvh1 = build_minmax_bvh(step1);
  ValueRanges const refit = refit_ranges(bvh0, step1);
  glm::vec3 lo, hi;
  Scene(step0, bvh0).bounds(lo, hi);
  Camera const cam = fit_camera(lo, hi, 64, 64);
  IsoParams const iso = three_surfaces();
  RenderOptions o;
  o.isa = test::isa();
  Image const a = render_iso(Scene(step1, bvh0, &refit), cam, iso, o);
  Image const b = render_iso(Scene(step1, bvh1), cam, iso, o);
  Image const c = render_iso(Scene(step0, bvh0), cam, iso, o);
  CHECK(fraction_off(a, b, 1) < 0.002);  // another tree, another visiting order: ties only
  CHECK(fraction_off(a, c, 2) > 0.01);   // and the step really changed the picture
}

TEST_CASE("DVR: samples converge to cell segments, and empty-space skipping changes nothing", "[render][isa]") {
  auto g = generate_tets(20000, 3);
  TetMesh const m = g.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(m);
  Scene const scene(m, bvh);
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  Camera const cam = fit_camera(lo, hi, 64, 64);
  DvrParams p;
  p.tf = transfer_function_preset("cool-warm", 0.f, 0.75f);
  p.tf.unit_distance = 0.2f;
  p.step = 0.004f;
  RenderOptions o;
  o.isa = test::isa();
  Image const samples = render_dvr(scene, cam, p, o);
  p.empty_space_skipping = false;
  Image const no_skip = render_dvr(scene, cam, p, o);
  CHECK(rmse8(samples, no_skip) < 0.01);
  p.mode = DvrMode::segments;
  Image const segments = render_dvr(scene, cam, p, o);
  CHECK(rmse8(samples, segments) < 1.0);
  p.step = 0.06f;  // coarse sampling is visibly off, so the check above means something
  p.mode = DvrMode::samples;
  CHECK(rmse8(render_dvr(scene, cam, p, o), segments) > rmse8(samples, segments));
}

TEST_CASE("render entry points reject bad parameters with a message", "[render]") {
  auto g = generate_tets(600, 1);
  TetMesh const m = g.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(m);
  Scene const scene(m, bvh);
  Camera const cam = fit_camera({-1, -1, -1}, {1, 1, 1}, 8, 8);
  CHECK_THROWS_WITH(render_iso(scene, cam, IsoParams{}), Catch::Contains("1 to 8 isovalues"));
  DvrParams d;
  d.tf = transfer_function_preset("viridis", 0.f, 1.f);
  d.group_size = 40;
  CHECK_THROWS_WITH(render_dvr(scene, cam, d), Catch::Contains("group size 40"));
  MinMaxBvh const other = build_minmax_bvh(generate_tets(6000, 1).mesh());
  CHECK_THROWS_WITH(render_iso(Scene(m, other), cam, three_surfaces()), Catch::Contains("BVH built over"));
  TetMesh const bare{view(g.xyz), view(g.cells)};
  CHECK_THROWS_AS(render_iso(Scene(bare, bvh), cam, three_surfaces()), InvalidMesh);
  CHECK_THROWS_AS(Camera::look_at({0, 0, 0}, {0, 0, 0}, {0, 1, 0}, 45.f, 8, 8), InvalidArgument);
  CHECK_THROWS_AS(Camera::look_at({0, 0, 1}, {0, 0, 0}, {0, 1, 0}, 180.f, 8, 8), InvalidArgument);
}

}  // namespace test_render_basic
