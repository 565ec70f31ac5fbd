// Smooth isosurface normals from per-vertex gradients (cells/vertex_gradients.hpp)
// and isosurfaces coloured by another array (issue #25): exact on linear
// fields, closer to a sphere's true normals than the faceted per-cell ones,
// the same as the reference renderer on every ISA, and refused without the
// data they need.

#include <catch2/catch.hpp>

#include <tbb/task_arena.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <cellray/cells/vertex_gradients.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/vtk_cells.hpp>

#include "support/render_fixtures.hpp"
#include "support/sanitized.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_smooth {

using namespace cellray;

using test::camera_for;
using test::report;

namespace {

template <int N, class F> std::vector<float> field_of(GeneratedMesh<N> const& g, F const& f) {
  std::vector<float> out(g.xyz.size() / 3);
  for (size_t v = 0; v < out.size(); ++v) out[v] = f(glm::vec3(g.xyz[3 * v], g.xyz[3 * v + 1], g.xyz[3 * v + 2]));
  return out;
}

/// RMSE (8-bit units) between an image and the picture of the exact sphere
/// |p| = radius shaded like the renderer (headlight, two-sided, opaque
/// white), over the pixels both show as sphere, away from the silhouette
/// (there the mesh's surface, not its normals, decides the shade).
double sphere_error(Image const& img, Camera const& cam, IsoParams const& p, float radius) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      glm::dvec3 const o(cam.eye), d = glm::normalize(glm::dvec3(cam.direction(float(x), float(y))));
      double const b = glm::dot(o, d), c = glm::dot(o, o) - double(radius) * radius, disc = b * b - c;
      float const* q = img.pixel(x, y);
      if (disc <= 0 || q[0] == p.background.r) continue;
      glm::dvec3 const hit = o + (-b - std::sqrt(disc)) * d;
      double const ndl = std::abs(glm::dot(glm::normalize(hit), -d));  // two-sided
      if (ndl < 0.3) continue;
      double const spec = double(p.specular) * std::pow(ndl, double(p.shininess));  // headlight: h = l
      double const shade = std::min(1.0, double(p.ambient) + double(p.diffuse) * ndl + spec);
      double const e = 255.0 * (double(q[0]) - shade);
      sum += e * e, ++n;
    }
  REQUIRE(n > 100);
  return std::sqrt(sum / n);
}

template <int N> void check_smooth(GeneratedMesh<N> const& g, std::string const& what, double max_smooth_rmse) {
  std::vector<float> const f = field_of(g, [](glm::vec3 p) { return glm::dot(p, p); });
  std::vector<float> const colour = field_of(g, [](glm::vec3 p) { return p.x + 0.5f * p.y; });
  CellMesh<N> mesh = g.mesh().with_values(view(f));
  mesh.add_array("colour", view(colour));
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  VertexGradients const vg = build_vertex_gradients(mesh);
  CHECK(vg.memory_bytes() == 12 * mesh.vertex_count());
  Scene scene(mesh, bvh);
  if constexpr (N == 4) scene.tets[0].gradients = &vg;
  else scene.hexes[0].gradients = &vg;
  Camera const cam = Camera::look_at({0.f, 0.3f, 3.2f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 30.f, test::full_or_sanitized(96, 48),
                                     test::full_or_sanitized(96, 48));
  RenderOptions const ro = test::isa_options();
  IsoParams ip;
  ip.surfaces = {{0.36f, {1.f, 1.f, 1.f}, 1.f}};
  ip.normals = GradientMethod::analytic;
  double const flat = sphere_error(render_iso(scene, cam, ip, ro), cam, ip, 0.6f);
  ip.normals = GradientMethod::smooth;
  Image const smooth_img = render_iso(scene, cam, ip, ro);
  double const smooth = sphere_error(smooth_img, cam, ip, 0.6f);
  std::printf("  %s sphere: shading RMSE against the exact sphere, flat %.2f, smooth %.2f (8-bit)\n", what.c_str(),
              flat, smooth);
  CHECK(smooth < 0.6 * flat);
  CHECK(smooth < max_smooth_rmse);
  ImageDiff const d = compare_images(smooth_img, render_iso_reference(scene, cam, ip), 2.0);
  report(what + ": smooth normals vs reference", d);
  CHECK(d.frac_over <= 0.005);

  // Coloured by another array, with transparency and shadows.
  ip.color_by.array = "colour";
  ip.color_by.colors = transfer_function_preset("viridis", -1.f, 1.f);
  ip.surfaces = {{0.2f, {1.f, 1.f, 1.f}, 0.5f}, {0.5f, {1.f, 1.f, 1.f}, 1.f}};
  ip.shadows = true, ip.light_dir = {0.3f, 1.f, 0.5f};
  Image const coloured = render_iso(scene, cam, ip, ro);
  ImageDiff const dc = compare_images(coloured, render_iso_reference(scene, cam, ip), 2.0);
  report(what + ": coloured by another array vs reference", dc);
  CHECK(dc.frac_over <= 0.005);
  // Left (low x) and right (high x) of the sphere take the map's two ends.
  float const* left = coloured.pixel(cam.width / 2 - cam.width / 6, cam.height / 2);
  float const* right = coloured.pixel(cam.width / 2 + cam.width / 6, cam.height / 2);
  CHECK(left[2] > left[1]);    // viridis at the low end: purple-blue
  CHECK(right[1] > right[2]);  // at the high end: green-yellow
}

}  // namespace

TEST_CASE("vertex gradients of a linear field are exact at every vertex", "[render][smooth]") {
  auto check = [](auto const& g) {
    std::vector<float> const f = field_of(g, [](glm::vec3 p) { return 2.f * p.x - 3.f * p.y + 0.5f * p.z; });
    auto const mesh = g.mesh().with_values(view(f));
    VertexGradients const vg = build_vertex_gradients(mesh);
    REQUIRE(vg.vertex_count() == mesh.vertex_count());
    double worst = 0;
    for (uint64_t v = 0; v < vg.vertex_count(); ++v)
      worst = std::max({worst, std::abs(vg.data()[3 * v] - 2.0), std::abs(vg.data()[3 * v + 1] + 3.0),
                        std::abs(vg.data()[3 * v + 2] - 0.5)});
    CHECK(worst < 1e-3);
  };
  check(generate_tets(6 * 6 * 6 * 6, 2));
  check(generate_hexes(6 * 6 * 6, 2));
}

TEST_CASE("vertex gradients match a double-precision sum over the cells, whatever the thread count",
          "[render][smooth]") {
  // A curved field: what one double-precision pass over the cells gives
  // (float sums, so to ~1e-5 relative), the same bits on 1 and on all
  // threads (whether one pass or several ranges in parallel), and a NaN
  // vertex's cells left out of every sum.
  auto check = [](auto const& g) {
    constexpr int N = decltype(g.mesh())::corners;
    std::vector<float> f = field_of(g, [](glm::vec3 p) { return std::sin(3.f * p.x) * p.y + p.z * p.z; });
    f[f.size() / 2] = std::nanf("");
    auto const mesh = g.mesh().with_values(view(f));
    VertexGradients const all = build_vertex_gradients(mesh);
    VertexGradients one;
    tbb::task_arena(1).execute([&] { one = build_vertex_gradients(mesh); });
    REQUIRE(one.vertex_count() == all.vertex_count());
    CHECK(std::memcmp(one.data(), all.data(), all.memory_bytes()) == 0);

    uint64_t const nv = mesh.vertex_count();
    std::vector<double> sum(3 * nv, 0.0), weight(nv, 0.0);
    float const* xyz = mesh.positions();
    auto p = [&](uint64_t v) { return glm::dvec3(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]); };
    auto add = [&](uint64_t o, uint64_t a, uint64_t b, uint64_t c, uint64_t const* to, int n) {
      glm::dvec3 const e1 = p(a) - p(o), e2 = p(b) - p(o), e3 = p(c) - p(o);
      glm::dvec3 const c23 = glm::cross(e2, e3), c31 = glm::cross(e3, e1), c12 = glm::cross(e1, e2);
      double const det = glm::dot(e1, c23);
      if (det == 0) return;
      glm::dvec3 const grad =
          ((double(f[a]) - f[o]) * c23 + (double(f[b]) - f[o]) * c31 + (double(f[c]) - f[o]) * c12) / det;
      for (int k = 0; k < n; ++k) {
        for (int i = 0; i < 3; ++i) sum[3 * to[k] + uint64_t(i)] += std::abs(det) * grad[i];
        weight[to[k]] += std::abs(det);
      }
    };
    for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
      uint64_t v[N];
      bool finite = true;
      for (int k = 0; k < N; ++k) v[k] = mesh.vertex(c, k), finite = finite && std::isfinite(f[v[k]]);
      if (!finite) continue;
      if constexpr (N == 4) {
        add(v[0], v[1], v[2], v[3], v, 4);
      } else {
        static constexpr int nb[8][3] = {{1, 3, 4}, {2, 0, 5}, {3, 1, 6}, {0, 2, 7},
                                         {7, 5, 0}, {4, 6, 1}, {5, 7, 2}, {6, 4, 3}};
        for (int k = 0; k < 8; ++k) add(v[k], v[nb[k][0]], v[nb[k][1]], v[nb[k][2]], v + k, 1);
      }
    }
    double scale = 0;
    for (uint64_t v = 0; v < nv; ++v)
      for (int i = 0; i < 3 && weight[v] > 0; ++i) scale = std::max(scale, std::abs(sum[3 * v + uint64_t(i)] / weight[v]));
    uint64_t nan_both = 0, off = 0;
    for (uint64_t v = 0; v < nv; ++v) {
      if (!(weight[v] > 0)) {
        nan_both += std::isnan(all.data()[3 * v]) ? 1 : 0;
        continue;
      }
      for (int i = 0; i < 3; ++i) {
        double const want = sum[3 * v + uint64_t(i)] / weight[v];
        off += !(std::abs(double(all.data()[3 * v + uint64_t(i)]) - want) <= 2e-5 * scale);  // NaN counts
      }
    }
    CHECK(nan_both >= 1);  // the NaN vertex itself: all its cells dropped
    CHECK(off == 0);
  };
  check(generate_tets(6 * 12 * 12 * 12, 3));
  check(generate_hexes(16 * 16 * 16, 3));
  // Large enough to be cut into ranges accumulated in parallel.
  auto const many_tets = generate_tets(6 * 30 * 30 * 30, 3);
  auto const many_hexes = generate_hexes(48 * 48 * 48, 3);
  REQUIRE(many_tets.mesh().cell_count() >= 2 * detail::gradient_part_cells);
  REQUIRE(many_hexes.mesh().cell_count() >= 2 * detail::gradient_part_cells);
  check(many_tets);
  check(many_hexes);
}

TEST_CASE("wedges and pyramids give every vertex a gradient, the collapsed side's and the apex's too",
          "[render][smooth]") {
  // One cell each, as the readers store them: a vertex only a collapsed
  // corner touches has no other cell to take a gradient from. A linear
  // field: every vertex's gradient is the field's.
  auto check = [](std::vector<float> const& xyz, std::vector<uint32_t> const& cell) {
    std::vector<float> f;
    for (size_t v = 0; v < xyz.size(); v += 3) f.push_back(2.f * xyz[v] - 3.f * xyz[v + 1] + 0.5f * xyz[v + 2]);
    VertexGradients const vg = build_vertex_gradients(HexMesh{view(xyz), view(cell), view(f), "f"});
    for (uint64_t v = 0; v < vg.vertex_count(); ++v) {
      INFO("vertex " << v);
      CHECK(std::abs(vg.data()[3 * v] - 2.f) < 1e-4f);  // false for NaN
      CHECK(std::abs(vg.data()[3 * v + 1] + 3.f) < 1e-4f);
      CHECK(std::abs(vg.data()[3 * v + 2] - 0.5f) < 1e-4f);
    }
  };
  std::vector<float> const wedge = {0, 0, 0, 1.2f, 0.1f, 0, 0.2f, 0.9f, 0.1f, 0.1f, 0, 1, 1.1f, 0.2f, 1.1f, 0.3f, 1, 0.9f};
  std::vector<uint32_t> as_hex;
  for (int k : wedge_as_hex) as_hex.push_back(uint32_t(k));
  check(wedge, as_hex);
  std::vector<float> const pyramid = {0, 0, 0, 1, 0.1f, 0, 1.1f, 1, 0.1f, 0, 0.9f, 0, 0.4f, 0.6f, 0.8f};
  as_hex.clear();
  for (int k : pyramid_as_hex) as_hex.push_back(uint32_t(k));
  check(pyramid, as_hex);
}

TEST_CASE("a tet folded into a hexahedron has the tet's vertex gradients", "[render][smooth]") {
  // 0 1 2 2 3 3 3 3, as a mixed mesh folded into one part stores it. A field
  // that is not linear, so a vertex's average depends on every cell around it.
  auto const g = generate_tets(6 * 4 * 4 * 4, 3);
  std::vector<float> const f = field_of(g, [](glm::vec3 p) { return glm::dot(p, p) + p.x * p.y; });
  std::vector<uint32_t> folded;
  for (size_t c = 0; c < g.cells.size() / 4; ++c)
    for (int k : tet_as_hex) folded.push_back(g.cells[4 * c + size_t(k)]);
  VertexGradients const as_tets = build_vertex_gradients(TetMesh{view(g.xyz), view(g.cells), view(f), "f"});
  VertexGradients const as_hexes = build_vertex_gradients(HexMesh{view(g.xyz), view(folded), view(f), "f"});
  REQUIRE(as_hexes.vertex_count() == as_tets.vertex_count());
  // The same sums in the same order: equal bit for bit.
  for (uint64_t i = 0; i < 3 * as_tets.vertex_count(); ++i) REQUIRE(as_hexes.data()[i] == as_tets.data()[i]);
}

TEST_CASE("smooth normals follow a sphere more closely than flat ones -- colour by another array",
          "[render][smooth][isa]") {
  check_smooth(generate_tets(6 * 10 * 10 * 10, 2), "tets", 12.0);
  check_smooth(generate_hexes(10 * 10 * 10, 2, 0.15f), "hexes", 12.0);
}

TEST_CASE("tets folded into hexahedra shade as the tets: smooth normals and colour by at the hit's coordinates",
          "[render][smooth][isa]") {
  // A packet hands a folded tet (0 1 2 2 3 3 3 3) to the tet kernels, which
  // keep no cell coordinates: the hit's trilinear ones come from its
  // barycentric ones (CellOps<A, 8>::folded_tet_param), and the smooth
  // normal and the colour interpolate with the trilinear weights there,
  // which must be the barycentric weights again. Same vertex gradients and
  // arrays in both scenes; a wrong mapping shows as other shades and colours.
  auto const g = generate_tets(6 * 10 * 10 * 10, 2);
  std::vector<float> const f = field_of(g, [](glm::vec3 p) { return glm::dot(p, p); });
  std::vector<float> const colour = field_of(g, [](glm::vec3 p) { return p.x + 0.5f * p.y; });
  std::vector<uint32_t> folded;
  for (size_t c = 0; c < g.cells.size() / 4; ++c)
    for (int k : tet_as_hex) folded.push_back(g.cells[4 * c + size_t(k)]);
  TetMesh tets{view(g.xyz), view(g.cells), view(f), "f"};
  HexMesh hexes{view(g.xyz), view(folded), view(f), "f"};
  tets.add_array("colour", view(colour));
  hexes.add_array("colour", view(colour));
  MinMaxBvh const tb = build_minmax_bvh(tets), hb = build_minmax_bvh(hexes);
  VertexGradients const vg = build_vertex_gradients(tets);
  Scene as_tets(tets, tb), as_hexes(hexes, hb);
  as_tets.tets[0].gradients = &vg;
  as_hexes.hexes[0].gradients = &vg;
  int const size = test::full_or_sanitized(96, 48);
  Camera const cam = Camera::look_at({0.f, 0.3f, 3.2f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 30.f, size, size);
  IsoParams ip;
  ip.surfaces = {{0.2f, {1.f, 1.f, 1.f}, 0.5f}, {0.5f, {1.f, 1.f, 1.f}, 1.f}};
  ip.normals = GradientMethod::smooth;
  ip.color_by.array = "colour";
  ip.color_by.colors = transfer_function_preset("viridis", -1.f, 1.f);
  RenderOptions const ro = test::isa_options();
  ImageDiff const d = compare_images(render_iso(as_hexes, cam, ip, ro), render_iso(as_tets, cam, ip, ro), 1.0);
  report("folded tets vs tets, smooth normals and colour by", d);
  INFO("on " << isa_name(test::isa()));
  CHECK(d.nonfinite == 0);
  CHECK(d.frac_over == 0.0);  // weights equal to rounding: no channel off by more than 1/255
}

TEST_CASE("smooth normals need vertex gradients -- colouring needs the array", "[render][smooth]") {
  auto const g = generate_tets(6 * 3 * 3 * 3, 1);
  TetMesh const mesh = g.mesh();
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  Scene scene(mesh, bvh);
  Camera const cam = camera_for(scene, 8, 8);
  IsoParams ip;
  ip.surfaces = {{0.4f}};
  ip.normals = GradientMethod::smooth;
  CHECK_THROWS_WITH(render_iso(scene, cam, ip), Catch::Contains("vertex gradients") && Catch::Contains("part 0"));
  auto const other = generate_tets(6 * 4 * 4 * 4, 1);
  VertexGradients const wrong = build_vertex_gradients(other.mesh());
  scene.tets[0].gradients = &wrong;
  CHECK_THROWS_WITH(render_iso(scene, cam, ip), Catch::Contains("another mesh"));
  ip.normals = GradientMethod::analytic;
  ip.color_by.array = "no_such";
  CHECK_THROWS_WITH(render_iso(scene, cam, ip), Catch::Contains("no point array 'no_such'"));
}

}  // namespace test_render_smooth
