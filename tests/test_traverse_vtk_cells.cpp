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
#include <iterator>
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
    // The quads: pyramids; each pentagon is cut into a triangle and a quad.
    REQUIRE(s.hexes.size() == 5 + 2);
    REQUIRE(s.tets.size() == 2);
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
    // rotation and direction: both cut it into the same triangle and quad.
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
    auto shared = [](PolyhedronSplit const& s) {  // the parts of the shared face, as sorted id lists
      std::vector<std::vector<uint64_t>> parts;
      auto add = [&](std::vector<uint64_t> a) {
        if (std::all_of(a.begin(), a.end(), [](uint64_t v) { return v < 5; })) {
          std::sort(a.begin(), a.end());
          parts.push_back(a);
        }
      };
      for (auto const& t : s.tets) add({t[0], t[1], t[2]});
      for (auto const& h : s.hexes) add({h[0], h[1], h[2], h[3]});
      std::sort(parts.begin(), parts.end());
      return parts;
    };
    auto const a = shared(decompose_polyhedron(f, pts.data(), 15));
    auto const b = shared(decompose_polyhedron(below, pts.data(), 16));
    CHECK(a.size() == 2);
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

namespace {

/// The parts of a face split, each as its sorted ids, sorted: what two
/// cells sharing the face must agree on.
std::vector<std::vector<uint64_t>> part_sets(std::vector<std::vector<uint64_t>> parts) {
  for (auto& q : parts) std::sort(q.begin(), q.end());
  std::sort(parts.begin(), parts.end());
  return parts;
}

/// Twice the signed area of a planar polygon in z = const, seen from +z.
double area2(std::vector<uint64_t> const& q, std::vector<float> const& xyz) {
  double a = 0;
  for (size_t i = 0; i < q.size(); ++i) {
    uint64_t const u = q[i], v = q[(i + 1) % q.size()];
    a += double(xyz[3 * u]) * xyz[3 * v + 1] - double(xyz[3 * v]) * xyz[3 * u + 1];
  }
  return a;
}

}  // namespace

TEST_CASE("faces of more than four corners split into triangles and quads as OpenFOAM splits them",
          "[traverse][vtk-cells]") {
  std::vector<float> xyz;
  auto point = [&](double x, double y, double z = 0) {
    xyz.insert(xyz.end(), {float(x), float(y), float(z)});
    return uint64_t(xyz.size() / 3 - 1);
  };
  // A regular hexagon: every corner 120 degrees; the cut from any corner
  // that halves its angle ends at the opposite corner: two quads.
  std::vector<uint64_t> hexagon;
  for (int k = 0; k < 6; ++k) hexagon.push_back(point(std::cos(M_PI * k / 3), std::sin(M_PI * k / 3)));
  auto const hq = part_sets(split_face(hexagon, xyz.data()));
  REQUIRE(hq.size() == 2);
  CHECK(hq[0].size() == 4);
  CHECK(hq[1].size() == 4);
  std::vector<uint64_t> cut;  // the corners both quads hold: opposite ones
  std::set_intersection(hq[0].begin(), hq[0].end(), hq[1].begin(), hq[1].end(), std::back_inserter(cut));
  REQUIRE(cut.size() == 2);
  CHECK(cut[1] - cut[0] == 3);
  // An L (a concave hexagon): the cut starts at the reflex corner (270
  // degrees) and runs to the corner opposite it, halving it: two quads, and
  // no part outside the face.
  std::vector<uint64_t> const ell = {point(0, 0), point(2, 0), point(2, 1), point(1, 1), point(1, 2), point(0, 2)};
  CHECK(part_sets(split_face(ell, xyz.data())) ==
        std::vector<std::vector<uint64_t>>{{6, 7, 8, 9}, {6, 9, 10, 11}});
  // A square with a hanging node on one side (snappyHexMesh's refinement):
  // the straight corner (180 degrees) is the widest; the cut from it that
  // best halves it ends at a far corner: a triangle and a quad.
  std::vector<uint64_t> const hanging = {point(0, 0), point(1, 0), point(2, 0), point(2, 2), point(0, 2)};
  auto const h = split_face(hanging, xyz.data());
  REQUIRE(h.size() == 2);
  CHECK(h[0].size() + h[1].size() == 7);
  CHECK(std::count(h[0].begin(), h[0].end(), hanging[1]) + std::count(h[1].begin(), h[1].end(), hanging[1]) == 2);
  // Every part keeps the face's rotation, and the parts tile it.
  for (std::vector<uint64_t> const* face : std::initializer_list<std::vector<uint64_t> const*>{&hexagon, &ell, &hanging}) {
    double sum = 0;
    for (auto const& q : split_face(*face, xyz.data())) {
      CHECK(area2(q, xyz) > 0);
      sum += area2(q, xyz);
    }
    CHECK(sum == Approx(area2(*face, xyz)));
  }

  // Random star-shaped, slightly non-planar polygons of 5 to 12 corners:
  // listed from any corner, in either rotation, the same parts.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 300; ++trial) {
    int const n = 5 + trial % 8;
    // Corner k (in angular order) gets id first + perm[k]: random ids.
    uint64_t const first = xyz.size() / 3;
    std::vector<uint64_t> perm(static_cast<size_t>(n)), ring(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) perm[size_t(k)] = uint64_t(k);
    std::shuffle(perm.begin(), perm.end(), rng);
    xyz.resize(xyz.size() + 3 * size_t(n));
    for (int k = 0; k < n; ++k) {
      double const a = 2 * M_PI * (k + 0.4 * u(rng)) / n, r = 0.5 + u(rng);
      ring[size_t(k)] = first + perm[size_t(k)];
      float* q = &xyz[3 * ring[size_t(k)]];
      q[0] = float(r * std::cos(a)), q[1] = float(r * std::sin(a)), q[2] = float(0.05 * u(rng));
    }
    auto const ref = part_sets(split_face(ring, xyz.data()));
    size_t corners = 0;
    for (auto const& q : ref) {
      CHECK((q.size() == 3 || q.size() == 4));
      corners += q.size();
    }
    CHECK(corners == size_t(n) + 2 * (ref.size() - 1));  // each cut adds its two ends again
    int const shift = int(u(rng) * n);
    std::vector<uint64_t> other(ring);
    std::rotate(other.begin(), other.begin() + shift, other.end());
    CHECK(part_sets(split_face(other, xyz.data())) == ref);
    std::reverse(other.begin(), other.end());
    CHECK(part_sets(split_face(other, xyz.data())) == ref);
  }
}

}  // namespace test_traverse_vtk_cells
