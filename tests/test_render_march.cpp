// Cell-segment DVR marching through face neighbours (dvr_integrators_impl.hpp,
// integrate_march) renders what the tree-only path renders: the same
// segments, pieces and compositing, so the images agree to rounding, and
// both stay within the reference renderer's tolerance. Meshes that make a
// march leave and re-find its way: holes, NaN cells, a value window with
// long transparent stretches, early termination, shading; a real mesh.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>

#include "support/render_fixtures.hpp"
#include "support/sheared_lattice.hpp"
#include "support/test_data.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_march {

using namespace cellray;

using test::busy_tf;
using test::camera_for;
using test::diagonal;
using test::report;

namespace {

/// The image with face neighbours (march) and without (tree), compared;
/// and the march against the reference. Tets, or hexahedra (wedges and
/// pyramids as collapsed ones).
template <int N>
void check_march(CellMesh<N> const& mesh, DvrParams const& p, int size, std::string const& what, double max_ref_rmse) {
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  FaceNeighbours<N> const nb = [&] {
    if constexpr (N == 4) return build_tet_neighbours(mesh);
    else return build_hex_neighbours(mesh);
  }();
  Scene const tree(mesh, bvh), march(mesh, bvh, nullptr, &nb);
  Camera const cam = camera_for(tree, size, size);
  RenderOptions const o = test::isa_options();
  Image const a = render_dvr(march, cam, p, o), b = render_dvr(tree, cam, p, o);
  ImageDiff const d = compare_images(a, b, 0.5);
  report(what + ": march vs tree", d);
  CHECK(d.nonfinite == 0);
  CHECK(d.rmse < 0.01);
  CHECK(d.max < 0.5);
  if (max_ref_rmse > 0) {
    ImageDiff const r = compare_images(a, render_dvr_reference(tree, cam, p), 2.0);
    report(what + ": march vs reference", r);
    CHECK(r.rmse < max_ref_rmse);
  }
}

DvrParams segments(TransferFunction tf, float step) {
  DvrParams p;
  p.tf = std::move(tf);
  p.mode = DvrMode::segments;
  p.step = step;
  return p;
}

}  // namespace

TEST_CASE("DVR march: jittered tets, shading, early termination, every traversal", "[render][dvr][isa]") {
  auto const g = generate_tets(6 * 10 * 10 * 10, 3);
  TetMesh const mesh = g.mesh();
  float const diag = std::sqrt(12.f);
  DvrParams p = segments(busy_tf(0.1f, 0.9f, diag / 8.f), diag / 500.f);
  check_march(mesh, p, 48, "jittered 6000 tets", 0.3);
  p.shading.enabled = true;
  check_march(mesh, p, 40, "jittered, shaded", 0.3);
  p.shading.enabled = false;
  p.tf.unit_distance = diag / 200.f;  // dense: most rays terminate inside
  check_march(mesh, p, 40, "jittered, dense (early termination)", 0.3);
}

TEST_CASE("DVR march: holes, NaN cells and transparent stretches send rays back to the tree", "[render][dvr][isa]") {
  auto g = generate_tets(6 * 10 * 10 * 10, 8);
  for (size_t v = 0; v < g.field.size(); v += 53) g.field[v] = std::numeric_limits<float>::quiet_NaN();
  // Remove a shell: rays leave the mesh and enter it again.
  std::vector<uint32_t> cells;
  for (size_t c = 0; c + 4 <= g.cells.size(); c += 4) {
    glm::vec3 m(0.f);
    for (int i = 0; i < 4; ++i) m += glm::vec3(g.xyz[3 * g.cells[c + i]], g.xyz[3 * g.cells[c + i] + 1], g.xyz[3 * g.cells[c + i] + 2]);
    float const r = glm::length(0.25f * m);
    if (r < 0.45f || r > 0.7f) cells.insert(cells.end(), g.cells.begin() + long(c), g.cells.begin() + long(c) + 4);
  }
  TetMesh const mesh{view(g.xyz), view(cells), view(g.field)};
  float const diag = std::sqrt(12.f);
  // Opacity only in a narrow band of values: long invisible stretches.
  TransferFunction tf;
  tf.values = {0.f, 0.55f, 0.6f, 0.65f, 1.f};
  tf.rgba = {{0.1f, 0.2f, 0.9f, 0.f}, {0.1f, 0.2f, 0.9f, 0.f}, {0.9f, 0.6f, 0.1f, 0.8f}, {0.9f, 0.1f, 0.1f, 0.f},
             {0.9f, 0.1f, 0.1f, 0.f}};
  tf.unit_distance = diag / 20.f;
  check_march(mesh, segments(tf, diag / 500.f), 48, "shell removed, NaN cells, narrow band", 0.3);
}

TEST_CASE("DVR march: component8 84k, the benchmark's transfer function", "[render][dvr][isa][data]") {
  auto const g = read_mesh(test::real_file("openfoam/component8_heat_84k.vtk"));
  TetMesh const mesh = g.tet_mesh().with_array("T");
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (uint64_t v = 0; v < mesh.vertex_count(); ++v) lo = glm::min(lo, mesh.position(v)), hi = glm::max(hi, mesh.position(v));
  DvrParams p = segments(transfer_function_preset("cool-warm", 273.f, 573.f), glm::length(hi - lo) / 250.f);
  p.tf.unit_distance = glm::length(hi - lo) / 10.f;
  check_march(mesh, p, 96, "component8 84k", 0);
}

TEST_CASE("DVR march: neighbours of another mesh are refused, several parts use the tree", "[render][dvr]") {
  auto const g = generate_tets(6 * 4 * 4 * 4, 1), h = generate_tets(6 * 5 * 5 * 5, 1);
  TetMesh const a = g.mesh(), b = h.mesh();
  MinMaxBvh const bvh_a = build_minmax_bvh(a), bvh_b = build_minmax_bvh(b);
  TetNeighbours const nb_b = build_tet_neighbours(b);
  DvrParams const p = segments(busy_tf(0.1f, 0.9f, 1.f), 0.01f);
  Scene const wrong(a, bvh_a, nullptr, &nb_b);
  Camera const cam = camera_for(wrong, 8, 8);
  CHECK_THROWS_WITH(render_dvr(wrong, cam, p), Catch::Contains("face neighbours") && Catch::Contains("part 0"));
  // Same cell and vertex counts, other connectivity (cells in another order).
  std::vector<uint32_t> shuffled(g.cells.size());
  size_t const nc = g.cells.size() / 4;
  for (size_t c = 0; c < nc; ++c)
    std::copy_n(g.cells.begin() + long(4 * ((c * 7 + 3) % nc)), 4, shuffled.begin() + long(4 * c));
  TetMesh const a2{view(g.xyz), view(shuffled), view(g.field)};
  TetNeighbours const nb_a2 = build_tet_neighbours(a2);
  CHECK_THROWS_WITH(render_dvr(Scene(a, bvh_a, nullptr, &nb_a2), cam, p), Catch::Contains("another mesh"));
  Scene two(a, bvh_a, nullptr, nullptr);
  two.tets.push_back({b, &bvh_b, nullptr, &nb_b});
  Scene two_tree(a, bvh_a);
  two_tree.tets.push_back({b, &bvh_b, nullptr, nullptr});
  ImageDiff const d = compare_images(render_dvr(two, cam, p), render_dvr(two_tree, cam, p), 0.5);
  CHECK(d.max == 0.0);
}

TEST_CASE("DVR march: hexes, wedges and pyramids, shading, early termination, NaN cells", "[render][dvr][isa]") {
  float const diag = std::sqrt(12.f);
  auto const hexes = generate_hexes(8 * 8 * 8, 3);  // jittered: bilinear faces
  DvrParams p = segments(busy_tf(0.1f, 0.9f, diag / 8.f), diag / 250.f);
  check_march(hexes.mesh(), p, 40, "jittered 512 hexes", 0.3);
  auto g = generate_hex_family(7 * 7 * 7, 4);
  check_march(g.mesh(), p, 40, "hexes, wedges, pyramids", 0.3);
  p.shading.enabled = true;
  check_march(g.mesh(), p, 32, "hex family, shaded", 0.3);
  p.shading.enabled = false;
  p.tf.unit_distance = diag / 200.f;  // dense: most rays terminate inside
  check_march(g.mesh(), p, 32, "hex family, dense (early termination)", 0.3);
  for (size_t v = 0; v < g.field.size(); v += 41) g.field[v] = std::numeric_limits<float>::quiet_NaN();
  p.tf.unit_distance = diag / 8.f;
  check_march(g.mesh(), p, 32, "hex family, NaN cells", 0);
  // Neighbours of another hex mesh are refused.
  auto const other = generate_hexes(6 * 6 * 6, 3);
  HexNeighbours const wrong = build_hex_neighbours(other.mesh());
  MinMaxBvh const bvh = build_minmax_bvh(hexes.mesh());
  Scene const s(hexes.mesh(), bvh, nullptr, &wrong);
  CHECK_THROWS_WITH(render_dvr(s, camera_for(s, 8, 8), p), Catch::Contains("face neighbours") && Catch::Contains("hexahedral part 0"));
}

TEST_CASE("DVR march: parallelepipeds take the parametric segment as the ray, beside distorted hexes",
          "[render][dvr][isa]") {
  // A parallelepiped's field on the ray is its parametric segment's (no
  // inversions: CellOps<A, 8>::field_on_ray); the lattice's distorted half
  // and the shared faces still invert.
  for (double jitter : {0.0, 0.25}) {
    test::OwnedMesh<8> const lattice = test::sheared_lattice(10, jitter, 5);
    auto const [vmin, vmax] = std::minmax_element(lattice.values.begin(), lattice.values.end());
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (size_t v = 0; v < lattice.values.size(); ++v) {
      glm::vec3 const x(lattice.xyz[3 * v], lattice.xyz[3 * v + 1], lattice.xyz[3 * v + 2]);
      lo = glm::min(lo, x), hi = glm::max(hi, x);
    }
    float const diag = glm::length(hi - lo);
    DvrParams p = segments(busy_tf(*vmin, *vmax, diag / 6.f), diag / 250.f);
    std::string const what = jitter == 0.0 ? "sheared lattice" : "sheared lattice, half distorted";
    // Measured 0.0027-0.0028 (rmse, 8-bit units); with the segment's
    // lambda off by 10% in the fast path, 0.13-0.16.
    check_march(lattice.mesh(), p, 40, what, 0.03);
    p.shading.enabled = true;
    check_march(lattice.mesh(), p, 32, what + ", shaded", 0.03);
  }
}

TEST_CASE("a mixed mesh with its tets folded into the hexahedra renders as its two parts do, and marches",
          "[render][dvr][isa]") {
  // gmsh's hex block glued to a tet block (pyramids between them), with a
  // curved field; the tets as collapsed hexahedra (fold_tets_into_hexes).
  UnstructuredGrid g = read_mesh(std::string(CELLRAY_TEST_DATA) + "/gmsh/mixed22.msh");
  REQUIRE(g.tet_count() > 0);
  REQUIRE(g.hex_count() > 0);
  std::vector<float> const field = test::curved_field(g.xyz);
  UnstructuredGrid f = g;
  uint64_t const tets = f.fold_tets_into_hexes();
  CHECK(tets == g.tet_count());
  TetMesh const tm = g.tet_mesh().with_values(view(field));
  HexMesh const hm = g.hex_mesh().with_values(view(field));
  HexMesh const fm = f.hex_mesh().with_values(view(field));
  MinMaxBvh const tb = build_minmax_bvh(tm), hb = build_minmax_bvh(hm), fb = build_minmax_bvh(fm);
  HexNeighbours const nb = build_hex_neighbours(fm);
  Scene two;
  two.tets.push_back({tm, &tb});
  two.hexes.push_back({hm, &hb});
  Scene const one(fm, fb), one_march(fm, fb, nullptr, &nb);
  Camera const cam = camera_for(two, 64, 64);
  RenderOptions const o = test::isa_options();
  float const lo = *std::min_element(field.begin(), field.end()), hi = *std::max_element(field.begin(), field.end());
  // Iso: the same crossings (a tet's faces are triangles in both kernels)
  // and the same linear field inside: the same image but for the roots'
  // last bits.
  IsoParams ip;
  for (float k : {0.3f, 0.6f}) ip.surfaces.push_back({lo + k * (hi - lo), glm::vec3(0.8f), 1.f});
  ImageDiff const iso = compare_images(render_iso(one, cam, ip, o), render_iso(two, cam, ip, o), 1.0);
  report("mixed22 iso: folded vs two parts", iso);
  CHECK(iso.nonfinite == 0);
  CHECK(iso.frac_over < 0.001);
  CHECK(iso.rmse < 0.05);
  // DVR: one part marches from tet to pyramid to hex and back.
  DvrParams const p = segments(busy_tf(lo, hi, diagonal(two) / 6.f), diagonal(two) / 250.f);
  Image const d_two = render_dvr(two, cam, p, o);
  for (Scene const* s : {&one, &one_march}) {
    ImageDiff const d = compare_images(render_dvr(*s, cam, p, o), d_two, 0.5);
    report(s == &one ? "mixed22 DVR: folded vs two parts" : "mixed22 DVR: folded, marching vs two parts", d);
    CHECK(d.nonfinite == 0);
    CHECK(d.rmse < 0.01);
    CHECK(d.max < 0.5);
  }
  // Probes: the folded tets give the tets' values.
  std::vector<float> pts;
  glm::vec3 blo, bhi;
  two.bounds(blo, bhi);
  for (int i = 0; i < 4000; ++i)
    for (int a = 0; a < 3; ++a) pts.push_back(blo[a] + (bhi[a] - blo[a]) * float((i * 7919 + a * 104729) % 1000) / 1000.f);
  std::vector<float> const a = sample_points(two, pts, o), b = sample_points(one, pts, o);
  uint64_t inside = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    CHECK(std::isnan(a[i]) == std::isnan(b[i]));
    if (std::isnan(a[i])) continue;
    ++inside;
    CHECK(b[i] == Approx(a[i]).margin(1e-5f * (hi - lo)));
  }
  CHECK(inside > 1000);
}

TEST_CASE("DVR march: a mixed mesh kept as two parts marches across both when their neighbours are linked",
          "[render][dvr][isa]") {
  // mixed22: tets, pyramids, hexahedra; sphere_bl_small: a boundary layer
  // of hexahedra and prisms under tets, pyramids between, a hole.
  for (char const* file : {"mixed22.msh", "sphere_bl_small.msh"}) {
    UnstructuredGrid g = read_mesh(std::string(CELLRAY_TEST_DATA) + "/gmsh/" + file);
    std::vector<float> field = test::curved_field(g.xyz);
    TetMesh const tm = g.tet_mesh().with_values(view(field));
    HexMesh const hm = g.hex_mesh().with_values(view(field));
    MinMaxBvh tb = build_minmax_bvh(tm), hb = build_minmax_bvh(hm);
    TetNeighbours tn = build_tet_neighbours(tm);
    HexNeighbours hn = build_hex_neighbours(hm);
    Scene tree;
    tree.tets.push_back({tm, &tb});
    tree.hexes.push_back({hm, &hb});
    Scene march;
    march.tets.push_back({tm, &tb, nullptr, &tn});
    march.hexes.push_back({hm, &hb, nullptr, nullptr, &hn});
    // Unlinked neighbours: the two trees (the march cannot cross).
    CHECK_FALSE(render_detail::prepare(march).mixed_march);
    link_face_neighbours(tm, tn, hm, hn);
    CHECK(render_detail::prepare(march).mixed_march);
    Camera const cam = camera_for(tree, 56, 56);
    RenderOptions const o = test::isa_options();
    float const lo = *std::min_element(field.begin(), field.end()), hi = *std::max_element(field.begin(), field.end());
    DvrParams p = segments(busy_tf(lo, hi, diagonal(tree) / 6.f), diagonal(tree) / 250.f);
    auto check = [&](std::string const& what, double max_ref_rmse) {
      Image const a = render_dvr(march, cam, p, o), b = render_dvr(tree, cam, p, o);
      ImageDiff const d = compare_images(a, b, 0.5);
      report(std::string(file) + " " + what + ": mixed march vs two trees", d);
      CHECK(d.nonfinite == 0);
      CHECK(d.rmse < 0.01);
      CHECK(d.max < 0.5);
      if (max_ref_rmse > 0) {
        ImageDiff const r = compare_images(a, render_dvr_reference(tree, cam, p), 2.0);
        report(std::string(file) + " " + what + ": mixed march vs reference", r);
        CHECK(r.rmse < max_ref_rmse);
      }
    };
    check("", 0.3);
    p.shading.enabled = true;
    check("shaded", 0.3);
    p.shading.enabled = false;
    p.tf.unit_distance = diagonal(tree) / 100.f;  // dense: most rays terminate inside
    check("dense", 0);
    for (size_t v = 0; v < field.size(); v += 29) field[v] = std::numeric_limits<float>::quiet_NaN();
    tb = build_minmax_bvh(tm), hb = build_minmax_bvh(hm);  // the scenes point at these
    p.tf.unit_distance = diagonal(tree) / 6.f;
    check("NaN cells", 0);
  }
}

/// The field's range over a generated mesh.
template <int N> std::pair<float, float> field_range(GeneratedMesh<N> const& g) {
  auto const mm = std::minmax_element(g.field.begin(), g.field.end());
  return {*mm.first, *mm.second};
}

TEST_CASE("DVR segments: a narrow opacity peak is integrated, not stepped over", "[render][dvr][isa]") {
  // Opacity 1 on a peak 1% of the value range wide, zero elsewhere: a piece
  // of a cell segment spans far more value than that, so a midpoint rule
  // sees the peak only where a midpoint falls on it (component8 at the
  // default step: RMSE 7.8/255, 15% of pixels off by more than 1/255, and
  // 3.4/255 still at a tenth of it). Cell segments integrate each piece
  // over the transfer function between its end values (the optical depth
  // of the log-shaped extinction near opacity 1 exactly). Measured (64x64,
  // AVX-512) against the reference: tets at the default step RMSE
  // 0.0038/255, hexahedra 0.017/255; sampling each piece at one end instead
  // (both at diag/250) 1.5/255 and 1.8/255.
  auto peak = [](float lo, float hi, float unit) {
    TransferFunction tf;
    float const m = lo + 0.55f * (hi - lo), w = 0.005f * (hi - lo);
    tf.values = {lo, m - w, m, m + w, hi};
    tf.rgba = {{0.1f, 0.2f, 0.9f, 0.f}, {0.3f, 0.8f, 0.4f, 0.f}, {0.9f, 0.7f, 0.1f, 1.f}, {0.8f, 0.2f, 0.1f, 0.f},
               {0.9f, 0.1f, 0.1f, 0.f}};
    tf.unit_distance = unit;
    return tf;
  };
  auto const t = generate_tets(6000);
  auto const [tlo, thi] = field_range(t);
  float const tdiag = diagonal(Scene(t.mesh(), build_minmax_bvh(t.mesh())));
  check_march(t.mesh(), segments(peak(tlo, thi, tdiag / 8.f), 0.f), 64, "tets 6k, a narrow peak", 0.3);
  auto const h = generate_hexes(1000);
  auto const [hlo, hhi] = field_range(h);
  float const hdiag = diagonal(Scene(h.mesh(), build_minmax_bvh(h.mesh())));
  // Hexahedra at diag/250: with ten cells across, at the default step the
  // field bends within a piece, and the march's and the tree's cubics
  // (fitted apart) crossing the peak's steep sides differed by up to
  // 0.48/255, at the edge of check_march's 0.5.
  check_march(h.mesh(), segments(peak(hlo, hhi, hdiag / 8.f), hdiag / 250.f), 64, "hexes 1k, a narrow peak", 0.3);
}

TEST_CASE("DVR segments: faint material valued above a near-opaque band keeps its opacity", "[render][dvr][isa]") {
  // The integrals over value are sums from the transfer function's lowest
  // value: here a near-opaque band below the field's range makes them large
  // where the field is, and a faint piece's optical depth is a small
  // difference of two large sums. Kept in two floats (hi + lo) they stay
  // exact. Measured (64x64, tets, AVX-512) against the reference: RMSE
  // 0.0003/255; with the sums in one float 0.014/255.
  auto const g = generate_tets(6000);
  auto const [lo, hi] = field_range(g);
  float const r = hi - lo;
  TransferFunction tf;
  tf.values = {lo - r, lo - 0.02f * r, lo - 0.01f * r, lo, hi};
  tf.rgba = {{0.1f, 0.1f, 0.1f, 1.f}, {0.1f, 0.1f, 0.1f, 1.f}, {0.2f, 0.3f, 0.9f, 0.05f}, {0.2f, 0.3f, 0.9f, 0.05f},
             {0.9f, 0.3f, 0.1f, 0.05f}};
  tf.unit_distance = diagonal(Scene(g.mesh(), build_minmax_bvh(g.mesh()))) / 40.f;
  check_march(g.mesh(), segments(tf, 0.f), 64, "tets 6k, faint above opaque", 0.002);
}

TEST_CASE("DVR segments: each table cell holds the transfer function's mean extinction and colour over it", "[render][dvr]") {
  // tf_integrals computes the table cells in parallel tasks, each finding
  // its first control value itself; 300 control values, so most tasks start
  // between two of them. Checked against a 256-point midpoint rule over
  // each cell's values (the function itself, evaluated here): a task that
  // started from the wrong control value integrates the wrong pieces.
  TransferFunction tf;
  for (int k = 0; k < 300; ++k) {
    float const x = float(k) / 299.f;
    tf.values.push_back(-2.f + 5.f * x * x);
    tf.rgba.push_back({x, 1.f - x, 0.5f, 0.45f + 0.45f * std::sin(37.f * x)});
  }
  tf.unit_distance = 0.1f;
  int const size = 4096;
  float const lo = tf.values.front(), scale = float(size - 1) / (tf.values.back() - lo);
  std::vector<float> const t = render_detail::tf_integrals(tf, lo, scale, size);
  int bad = 0;
  double worst = 0.0;
  for (int c = 1; c < size; ++c) {
    double const v0 = double(lo) + double(c - 1) / scale, v1 = double(lo) + double(c) / scale;
    double mean[4] = {0.0, 0.0, 0.0, 0.0};
    for (int q = 0; q < 256; ++q) {
      glm::vec4 const e = tf(float(v0 + (q + 0.5) * (v1 - v0) / 256.0));
      double const sigma = -std::log(1.0 - std::min(double(e.a), 0.999999)) / tf.unit_distance / 256.0;
      mean[0] += sigma, mean[1] += e.r * sigma, mean[2] += e.g * sigma, mean[3] += e.b * sigma;
    }
    float const* cell = t.data() + size_t(c) * PreparedTf::integral_stride + 8;
    for (int ch = 0; ch < 4; ++ch) {
      double const err = std::fabs(double(cell[ch]) - mean[ch]) / (mean[0] + 1e-3);
      worst = std::max(worst, err);
      bad += err > 1e-3;
    }
  }
  INFO("worst relative error " << worst);
  CHECK(bad == 0);
}

TEST_CASE("DVR march: boxturb48 hexes, a narrow band of enstrophy", "[render][dvr][isa][data]") {
  auto const path = test::shared_data_file("openfoam/boxturb48_dns.vtk");
  if (!path) return;
  auto const g = read_mesh(*path);
  HexMesh const mesh = g.hex_mesh().with_array("enstrophy");
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (uint64_t v = 0; v < mesh.vertex_count(); ++v) lo = glm::min(lo, mesh.position(v)), hi = glm::max(hi, mesh.position(v));
  float const diag = glm::length(hi - lo);
  TransferFunction tf;  // issue #23's representative shape: opacity where the data is
  tf.values = {0.f, 0.1f, 0.16f, 0.28f, 0.34f, 10.f};
  tf.rgba = {{0.2f, 0.3f, 0.8f, 0.f}, {0.2f, 0.3f, 0.8f, 0.f}, {0.5f, 0.6f, 0.9f, 0.3f}, {0.9f, 0.5f, 0.4f, 0.3f},
             {0.8f, 0.1f, 0.1f, 0.f}, {0.8f, 0.1f, 0.1f, 0.f}};
  tf.unit_distance = diag / 35.f;
  check_march(mesh, segments(tf, diag / 250.f), 64, "boxturb48", 0);
}

}  // namespace test_render_march
