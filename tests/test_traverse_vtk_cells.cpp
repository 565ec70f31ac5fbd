// VTK's wedges and pyramids as collapsed hexahedra (mesh/vtk_cells.hpp,
// issue #21): the hex kernels' point samples inside distorted wedges and
// pyramids equal VTK's own interpolation (vtkWedge / vtkPyramid shape
// functions, evaluated here in double from the cell's VTK-ordered corners)
// at points placed by those same functions, on every ISA and traversal,
// including points near the collapsed edge and the apex; points outside
// come back NaN. Polyhedra: decompose_polyhedron's cells fill the
// polyhedron exactly (volumes add up, all positively oriented), and
// check_polyhedron names what is wrong with faces that do not close.

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/mesh/vtk_cells.hpp>
#include <cellray/traverse/queries.hpp>

#include "support/test_isa.hpp"

namespace test_traverse_vtk_cells {

using namespace cellray;

namespace {

// VTK's shape functions (vtkWedge.cxx, vtkPyramid.cxx, VTK 9).
std::array<double, 6> wedge_weights(double r, double s, double t) {
  return {(1 - r - s) * (1 - t), r * (1 - t), s * (1 - t), (1 - r - s) * t, r * t, s * t};
}
std::array<double, 5> pyramid_weights(double r, double s, double t) {
  return {(1 - r) * (1 - s) * (1 - t), r * (1 - s) * (1 - t), r * s * (1 - t), (1 - r) * s * (1 - t), t};
}

struct Case {
  std::vector<float> xyz, values;
  std::vector<uint32_t> hex;  // the cell as a collapsed hexahedron
  std::vector<glm::dvec3> points;
  std::vector<double> expected;
};

// One distorted cell with `n` VTK corners, random values, and points placed
// by VTK's own map at parametric coordinates drawn inside the cell.
template <size_t N, class Weights>
Case make_case(std::array<glm::dvec3, N> const& corners, std::array<int, 8> const& as_hex, Weights weights,
               bool wedge, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.12, 0.12), val(-1.0, 2.0), u(0.0, 1.0);
  Case c;
  for (size_t k = 0; k < N; ++k) {
    glm::dvec3 const p = corners[k] + glm::dvec3(jitter(rng), jitter(rng), jitter(rng));
    for (int a = 0; a < 3; ++a) c.xyz.push_back(float(p[a]));
    c.values.push_back(float(val(rng)));
  }
  for (int k : as_hex) c.hex.push_back(uint32_t(k));
  auto corner = [&](size_t k) { return glm::dvec3(c.xyz[3 * k], c.xyz[3 * k + 1], c.xyz[3 * k + 2]); };
  for (int i = 0; i < 400; ++i) {
    double r = u(rng), s = u(rng), t = u(rng);
    if (wedge && r + s > 1) r = 1 - r, s = 1 - s;
    // Margins keep points off the faces (the containment tolerance there is
    // tested elsewhere); a quarter of them crowd the apex / collapsed edge.
    r = 0.02 + 0.96 * r, s = 0.02 + 0.96 * s, t = 0.02 + 0.96 * t;
    if (wedge) r *= 0.96, s *= 0.96;
    if (i % 4 == 0) {
      if (wedge) s = 0.9 * (1 - r) + 0.08 * s * (1 - r);  // near the collapsed edge (r + s = 1 face's far side)
      else t = 0.9 + 0.08 * t;                          // near the apex
    }
    auto const w = weights(r, s, t);
    glm::dvec3 p(0.0);
    double v = 0;
    for (size_t k = 0; k < N; ++k) p += w[k] * corner(k), v += w[k] * double(c.values[k]);
    c.points.push_back(p);
    c.expected.push_back(v);
  }
  return c;
}

void check(Case const& c, char const* what) {
  HexMesh const mesh(view(c.xyz), view(c.hex), view(c.values));
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  std::vector<Ray> rays;
  for (auto const& p : c.points) rays.push_back({glm::vec3(p), 0.f, {1.f, 0.f, 0.f}, 0.f});
  double range = 0;
  for (float a : c.values)
    for (float b : c.values) range = std::max(range, double(a) - b);
  for (Traversal how : {Traversal::packet, Traversal::spmd}) {
    std::vector<float> const got = sample_rays(TreeView(bvh), mesh, rays, 0.f, 1, 1, how, test::isa());
    int missed = 0;
    double worst = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      if (std::isnan(got[i])) {
        ++missed;
        continue;
      }
      worst = std::max(worst, std::abs(double(got[i]) - c.expected[i]) / range);
    }
    INFO(what << ", " << traversal_name(how) << ": missed " << missed << " of " << rays.size()
              << ", worst error / range " << worst);
    CHECK(missed == 0);
    CHECK(worst < 2e-5);
  }
  // Outside: beyond the cell's box on each axis.
  std::vector<Ray> out;
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (size_t k = 0; k < c.xyz.size(); k += 3)
    lo = glm::min(lo, glm::vec3(c.xyz[k], c.xyz[k + 1], c.xyz[k + 2])),
    hi = glm::max(hi, glm::vec3(c.xyz[k], c.xyz[k + 1], c.xyz[k + 2]));
  for (int a = 0; a < 3; ++a) {
    glm::vec3 p = 0.5f * (lo + hi);
    p[a] = hi[a] + 0.1f;
    out.push_back({p, 0.f, {1.f, 0.f, 0.f}, 0.f});
    p[a] = lo[a] - 0.1f;
    out.push_back({p, 0.f, {1.f, 0.f, 0.f}, 0.f});
  }
  for (float v : sample_rays(TreeView(bvh), mesh, out, 0.f, 1, 1, Traversal::packet, test::isa())) CHECK(std::isnan(v));
}

}  // namespace

TEST_CASE("wedges and pyramids as collapsed hexahedra interpolate as VTK does", "[traverse][isa][vtk-cells]") {
  // VTK's orientation: the bottom triangle 0 1 2's normal points away from the top.
  std::array<glm::dvec3, 6> const wedge{glm::dvec3(0, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(1, 0, 0),
                                        glm::dvec3(0, 0, 1), glm::dvec3(0, 1, 1), glm::dvec3(1, 0, 1)};
  std::array<glm::dvec3, 5> const pyramid{glm::dvec3(0, 0, 0), glm::dvec3(1, 0, 0), glm::dvec3(1, 1, 0),
                                          glm::dvec3(0, 1, 0), glm::dvec3(0.5, 0.5, 0.8)};
  for (uint32_t seed : {1u, 2u, 3u, 4u}) {
    INFO("seed " << seed);
    Case const w = make_case(wedge, wedge_as_hex, wedge_weights, true, seed);
    // VTK's wedge orientation (bottom triangle's normal away from the top)
    // becomes a positively oriented hexahedron.
    HexMesh const wm(view(w.xyz), view(w.hex), view(w.values));
    ValidationReport const wr = validate(wm);
    CHECK(!wr.inverted);
    CHECK(!wr.zero_volume);
    check(w, "wedge");
    Case const p = make_case(pyramid, pyramid_as_hex, pyramid_weights, false, seed);
    HexMesh const pm(view(p.xyz), view(p.hex), view(p.values));
    ValidationReport const pr = validate(pm);
    CHECK(!pr.inverted);
    CHECK(!pr.zero_volume);
    check(p, "pyramid");
  }
}

TEST_CASE("polyhedra decompose into cells that fill them", "[traverse][vtk-cells]") {
  // A pentagonal prism: two pentagons and five quads, faces pointing out.
  std::vector<float> xyz;
  for (int z = 0; z < 2; ++z)
    for (int k = 0; k < 5; ++k) {
      double const a = 2 * M_PI * k / 5;
      xyz.insert(xyz.end(), {float(std::cos(a)), float(std::sin(a)), float(z) * 1.5f});
    }
  PolyhedronFaces f;
  auto face = [&](std::vector<uint64_t> ids) {
    if (f.offsets.empty()) f.offsets.push_back(0);
    f.ids.insert(f.ids.end(), ids.begin(), ids.end());
    f.offsets.push_back(f.ids.size());
  };
  face({4, 3, 2, 1, 0});  // bottom, seen from below: clockwise from above
  face({5, 6, 7, 8, 9});  // top
  for (uint64_t k = 0; k < 5; ++k) face({k, (k + 1) % 5, (k + 1) % 5 + 5, k + 5});
  REQUIRE(check_polyhedron(f, 10).empty());
  double const area = 5.0 / 2.0 * std::sin(2 * M_PI / 5);  // regular pentagon of circumradius 1
  for (bool flip : {false, true}) {
    PolyhedronFaces g = f;
    if (flip)  // every face pointing in: the same cells
      for (size_t i = 0; i < g.face_count(); ++i) std::reverse(g.ids.begin() + long(g.offsets[i]), g.ids.begin() + long(g.offsets[i + 1]));
    PolyhedronSplit const s = decompose_polyhedron(g, xyz.data(), 10);
    REQUIRE(s.hexes.size() == 5);  // the quads: pyramids
    REQUIRE(s.tets.size() == 6);   // two pentagons fanned into 3 triangles each
    CHECK(s.centre.x == Approx(0).margin(1e-6));  // float corners
    CHECK(s.centre.y == Approx(0).margin(1e-6));
    CHECK(s.centre.z == Approx(0.75));
    std::vector<float> all = xyz;
    all.insert(all.end(), {float(s.centre.x), float(s.centre.y), float(s.centre.z)});
    std::vector<uint32_t> tets, hexes;
    for (auto const& t : s.tets) tets.insert(tets.end(), t.begin(), t.end());
    for (auto const& h : s.hexes) hexes.insert(hexes.end(), h.begin(), h.end());
    ValidationReport const tr = validate(TetMesh(view(all), view(tets)));
    ValidationReport const hr = validate(HexMesh(view(all), view(hexes)));
    CHECK(!tr.inverted);
    CHECK(!hr.inverted);
    CHECK(!tr.zero_volume);
    CHECK(!hr.zero_volume);
    auto pos = [&](uint64_t v) { return glm::dvec3(all[3 * v], all[3 * v + 1], all[3 * v + 2]); };
    double volume = 0;
    for (auto const& t : s.tets)
      volume += glm::dot(pos(t[1]) - pos(t[0]), glm::cross(pos(t[2]) - pos(t[0]), pos(t[3]) - pos(t[0]))) / 6;
    for (auto const& h : s.hexes)  // a pyramid's volume: two tets on its base's diagonal
      volume += (glm::dot(pos(h[1]) - pos(h[0]), glm::cross(pos(h[2]) - pos(h[0]), pos(h[4]) - pos(h[0]))) +
                 glm::dot(pos(h[2]) - pos(h[0]), glm::cross(pos(h[3]) - pos(h[0]), pos(h[4]) - pos(h[0])))) / 6;
    CHECK(volume == Approx(area * 1.5).epsilon(1e-6));
  }

  {
    // Two prisms sharing a (non-planar) pentagon, each listing it in its own
    // rotation and direction: both fan it into the same triangles.
    std::vector<float> pts = xyz;
    pts[2] = 0.2f;  // lift one corner of the shared pentagon: not planar
    for (int k = 0; k < 5; ++k) {
      double const a = 2 * M_PI * k / 5;
      pts.insert(pts.end(), {float(std::cos(a)), float(std::sin(a)), -1.5f});
    }
    PolyhedronFaces below;
    auto face_b = [&](std::vector<uint64_t> ids) {
      if (below.offsets.empty()) below.offsets.push_back(0);
      below.ids.insert(below.ids.end(), ids.begin(), ids.end());
      below.offsets.push_back(below.ids.size());
    };
    face_b({2, 3, 4, 0, 1});  // the shared face, seen from below: rotated and reversed w.r.t. f's {4, 3, 2, 1, 0}
    face_b({14, 13, 12, 11, 10});
    for (uint64_t k = 0; k < 5; ++k) face_b({(k + 1) % 5, k, k + 10, (k + 1) % 5 + 10});
    REQUIRE(check_polyhedron(below, 15).empty());
    auto shared = [](PolyhedronSplit const& s) {
      std::vector<std::array<uint64_t, 3>> tri;
      for (auto const& t : s.tets) {
        std::array<uint64_t, 3> a{t[0], t[1], t[2]};
        if (a[0] < 5 && a[1] < 5 && a[2] < 5) {
          std::sort(a.begin(), a.end());
          tri.push_back(a);
        }
      }
      std::sort(tri.begin(), tri.end());
      return tri;
    };
    auto const a = shared(decompose_polyhedron(f, pts.data(), 15));
    auto const b = shared(decompose_polyhedron(below, pts.data(), 16));
    CHECK(a.size() == 3);
    CHECK(a == b);
  }

  PolyhedronFaces open = f;  // drop the top face
  open.ids.erase(open.ids.begin() + long(open.offsets[1]), open.ids.begin() + long(open.offsets[2]));
  open.offsets.erase(open.offsets.begin() + 2);
  for (size_t i = 2; i < open.offsets.size(); ++i) open.offsets[i] -= 5;
  CHECK_THAT(check_polyhedron(open, 10), Catch::Contains("does not close"));
  CHECK_THAT(check_polyhedron(f, 8), Catch::Contains("outside [0, 8)"));
  PolyhedronFaces twisted = f;  // one face turned the other way
  std::reverse(twisted.ids.begin(), twisted.ids.begin() + 5);
  CHECK_THAT(check_polyhedron(twisted, 10), Catch::Contains("not consistently oriented"));
}

}  // namespace test_traverse_vtk_cells
