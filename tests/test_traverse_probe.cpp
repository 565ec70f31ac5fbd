// Point location for sample_points (traverse/probe.hpp): every point checked
// against a brute-force double-precision search over all cells
// (cells/reference.hpp), on every ISA, including points exactly on shared
// vertices, on edges and faces, outside the mesh, in NaN cells, and a mesh
// with a zero-volume cell.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/reference.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/render.hpp>
#include <cellray/traverse/queries.hpp>

#include "support/adversarial.hpp"
#include "support/render_fixtures.hpp"
#include "support/test_isa.hpp"

namespace test_traverse_probe {

using namespace cellray;

namespace {

constexpr double inf = std::numeric_limits<double>::infinity();

/// The double-precision answer at p: how far outside the nearest cell
/// without a NaN value p lies (0: inside, boundary included; tets: minus
/// the lowest barycentric weight, hexes: the largest trilinear coordinate
/// distance from [0,1]), and that cell's value there.
struct RefValue {
  double outside = inf;
  double value = std::numeric_limits<double>::quiet_NaN();
};

template <int N> RefValue reference_at(CellMesh<N> const& mesh, glm::dvec3 const& p) {
  RefValue r;
  for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
    ref::Cell<N> const cell = ref::load(mesh, c);
    if (ref::has_nan(cell)) continue;
    glm::dvec3 lo = cell.p[0], hi = cell.p[0];
    for (int k = 1; k < N; ++k) lo = glm::min(lo, cell.p[k]), hi = glm::max(hi, cell.p[k]);
    glm::dvec3 const pad = 1e-3 * (hi - lo);
    if (glm::any(glm::lessThan(p, lo - pad)) || glm::any(glm::greaterThan(p, hi + pad))) continue;
    ref::Location const L = ref::locate(cell, p);
    double out = inf;
    if constexpr (N == 4) {
      double const det = glm::dot(cell.p[1] - cell.p[0], glm::cross(cell.p[2] - cell.p[0], cell.p[3] - cell.p[0]));
      if (det == 0) continue;  // a zero-volume tet holds nothing
      double const w0 = 1 - L.param.x - L.param.y - L.param.z;
      out = std::max(0.0, -std::min({w0, L.param.x, L.param.y, L.param.z}));
    } else {
      if (!L.converged) continue;
      glm::dvec3 const u = L.param;
      out = std::max({0.0, -u.x, -u.y, -u.z, u.x - 1, u.y - 1, u.z - 1});
    }
    if (out < r.outside) r = {out, L.value};
  }
  return r;
}

/// Points on the mesh's own vertices, at the midpoints of every cell edge,
/// at the centre of every face (in float: on or within rounding of them) and
/// at random in and around the mesh, plus a few far outside or not finite.
/// `on_mesh[i]`: point i was made on a vertex, edge or face.
template <int N>
std::vector<float> make_points(CellMesh<N> const& mesh, uint64_t seed, std::vector<uint8_t>& on_mesh) {
  std::vector<float> xyz;
  auto add = [&](glm::vec3 p, bool on) {
    xyz.insert(xyz.end(), {p.x, p.y, p.z});
    on_mesh.push_back(on);
  };
  for (uint64_t v = 0; v < mesh.vertex_count(); ++v) add(mesh.position(v), true);
  static constexpr int tet_edges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  static constexpr int hex_edges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                           {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  static constexpr int tet_faces[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  static constexpr int hex_faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                          {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};
  for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
    auto P = [&](int k) { return mesh.position(mesh.vertex(c, k)); };
    if constexpr (N == 4) {
      for (auto const& e : tet_edges) add(0.5f * (P(e[0]) + P(e[1])), true);
      for (auto const& f : tet_faces) add((P(f[0]) + P(f[1]) + P(f[2])) / 3.f, true);
    } else {
      for (auto const& e : hex_edges) add(0.5f * (P(e[0]) + P(e[1])), true);
      for (auto const& f : hex_faces) add(0.25f * (P(f[0]) + P(f[1]) + P(f[2]) + P(f[3])), true);
    }
  }
  test::Rng rng(seed);
  for (int i = 0; i < 1500; ++i) add(glm::vec3(rng.in_box(-1.2, 1.2)), false);
  float const nan = std::numeric_limits<float>::quiet_NaN(), big = std::numeric_limits<float>::infinity();
  for (glm::vec3 p : {glm::vec3(5.f, 0.f, 0.f), glm::vec3(0.f, -3.f, 0.5f), glm::vec3(nan, 0.f, 0.f),
                      glm::vec3(0.f, big, 0.f), glm::vec3(-1e30f, 1e30f, 0.f)})
    add(p, false);
  return xyz;
}

struct Tally {
  int found = 0, lost = 0, wrong = 0, spurious = 0, on_mesh_found = 0, differ = 0;
};

/// Checks sample_points (sorted, on TBB), the per-ISA entry on the points in
/// input order (incoherent packets), and the scene-level call against the
/// brute-force reference.
template <int N> Tally check_probe(CellMesh<N> const& mesh, std::vector<float> const& xyz,
                                   std::vector<uint8_t> const& on_mesh) {
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  TreeView const tree(bvh);
  uint64_t const n = xyz.size() / 3;
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (uint64_t v = 0; v < mesh.vertex_count(); ++v)
    if (std::isfinite(mesh.value(v))) lo = std::min(lo, mesh.value(v)), hi = std::max(hi, mesh.value(v));
  double const range = double(hi) - double(lo);
  std::vector<float> const sorted = sample_points(tree, mesh, xyz, test::isa());
  std::vector<float> in_order(n, std::numeric_limits<float>::quiet_NaN());
  dispatch<ProbeEntry>(test::isa(), tree, mesh, xyz.data(), n, in_order.data());
  Scene const scene(mesh, bvh);
  std::vector<float> const from_scene = sample_points(scene, xyz, test::isa_options());
  Tally t;
  for (uint64_t i = 0; i < n; ++i) {
    glm::dvec3 const p(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    bool const finite = std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
    RefValue const r = finite ? reference_at(mesh, p) : RefValue{};
    float const v = sorted[i];
    // Each point stops at the first cell in the tree's order that holds it,
    // whatever its packet: the three calls agree bit for bit.
    auto same = [](float a, float b) { return a == b || (a != a && b != b); };
    t.differ += !same(v, in_order[i]) || !same(v, from_scene[i]);
    if (r.outside <= 1e-9) {
      if (v != v) {
        ++t.lost;
        UNSCOPED_INFO("lost (" << p.x << ", " << p.y << ", " << p.z << "), reference " << r.value);
      } else {
        ++t.found;
        t.on_mesh_found += on_mesh[i];
        if (std::abs(double(v) - r.value) > 2e-5 * range) {
          ++t.wrong;
          UNSCOPED_INFO("value " << v << " at (" << p.x << ", " << p.y << ", " << p.z << "), reference " << r.value);
        }
      }
    } else if (r.outside > 1e-4 && v == v) {
      ++t.spurious;
      UNSCOPED_INFO("spurious " << v << " at (" << p.x << ", " << p.y << ", " << p.z << "), " << r.outside
                                << " outside the nearest cell");
    }
  }
  INFO("found " << t.found << " (on vertices/edges/faces " << t.on_mesh_found << "), lost " << t.lost << ", wrong "
                << t.wrong << ", spurious " << t.spurious << ", differ between calls " << t.differ);
  CHECK(t.lost == 0);
  CHECK(t.wrong == 0);
  CHECK(t.spurious == 0);
  CHECK(t.differ == 0);
  return t;
}

/// A generated hex lattice twisted about z (0.7 rad over its height) and
/// bent along x: curved, non-planar faces everywhere.
GeneratedMesh<8> twisted_hexes(uint64_t cells, uint64_t seed) {
  GeneratedMesh<8> g = generate_hexes(cells, seed, 0.3f);
  for (size_t v = 0; v < g.xyz.size(); v += 3) {
    float const x = g.xyz[v], y = g.xyz[v + 1], z = g.xyz[v + 2];
    float const a = 0.35f * (z + 1.f);
    g.xyz[v] = std::cos(a) * x - std::sin(a) * y + 0.15f * std::sin(2.f * y);
    g.xyz[v + 1] = std::sin(a) * x + std::cos(a) * y;
  }
  return g;
}

}  // namespace

TEST_CASE("point location finds every point a double-precision search finds, shared vertices, edges and faces included",
          "[traverse][isa][probe]") {
  SECTION("tetrahedra") {
    auto const g = generate_tets(6 * 5 * 5 * 5, 7);
    std::vector<uint8_t> on;
    std::vector<float> const xyz = make_points(g.mesh(), 3, on);
    Tally const t = check_probe(g.mesh(), xyz, on);
    CHECK(t.on_mesh_found > 3000);
    CHECK(t.found > 4000);
  }
  SECTION("twisted hexahedra") {
    auto const g = twisted_hexes(5 * 5 * 5, 7);
    std::vector<uint8_t> on;
    std::vector<float> const xyz = make_points(g.mesh(), 4, on);
    Tally const t = check_probe(g.mesh(), xyz, on);
    CHECK(t.on_mesh_found > 1500);
    CHECK(t.found > 2000);
  }
}

TEST_CASE("point location: NaN cells hold nothing, their neighbours' shared faces still do", "[traverse][isa][probe]") {
  auto check = [](auto g, int min_found) {
    uint64_t nans = 0;
    for (size_t v = 0; v < g.field.size(); ++v)
      if (v % 11 == 3) g.field[v] = std::numeric_limits<float>::quiet_NaN(), ++nans;
    for (size_t v = 0; v < g.field.size(); ++v)
      if (v % 13 == 5) g.field[v] = std::numeric_limits<float>::infinity();
    auto const mesh = g.mesh();
    std::vector<uint8_t> on;
    std::vector<float> const xyz = make_points(mesh, 5, on);
    Tally const t = check_probe(mesh, xyz, on);
    CHECK(nans > 10);
    CHECK(t.found > min_found);
  };
  SECTION("tetrahedra") { check(generate_tets(6 * 5 * 5 * 5, 8), 500); }
  SECTION("hexahedra") { check(twisted_hexes(6 * 6 * 6, 8), 300); }
}

TEST_CASE("point location: a zero-volume cell holds nothing and hides nothing", "[traverse][isa][probe]") {
  SECTION("a flat tetrahedron on the boundary face z = -1") {
    auto g = generate_tets(6 * 4 * 4 * 4, 9);
    // Lattice vertices (0,0,0), (1,0,0), (0,1,0), (1,1,0): coplanar (z = -1).
    uint32_t const p = uint32_t(g.lattice + 1);
    g.cells.insert(g.cells.end(), {0u, 1u, p, p + 1});
    std::vector<uint8_t> on;
    std::vector<float> const xyz = make_points(g.mesh(), 6, on);
    Tally const t = check_probe(g.mesh(), xyz, on);
    CHECK(t.found > 1000);
  }
  SECTION("a flat hexahedron inside the mesh") {
    auto g = twisted_hexes(4 * 4 * 4, 9);
    // The face of lattice cell 0 at k = 1, repeated: a hex of zero volume
    // lying on a face shared by two cells.
    uint32_t const p = uint32_t(g.lattice + 1), k1 = p * p;
    uint32_t const f[4] = {k1, k1 + 1, k1 + p + 1, k1 + p};
    g.cells.insert(g.cells.end(), {f[0], f[1], f[2], f[3], f[0], f[1], f[2], f[3]});
    std::vector<uint8_t> on;
    std::vector<float> const xyz = make_points(g.mesh(), 7, on);
    Tally const t = check_probe(g.mesh(), xyz, on);
    CHECK(t.found > 800);
  }
}

TEST_CASE("point location in wedges and pyramids: next to a pyramid's apex and a wedge's collapsed edge",
          "[traverse][isa][probe]") {
  // Wedges and pyramids are hexahedra with corners repeated, so their
  // trilinear map is singular where corners meet (a pyramid's apex, w = 1; a
  // wedge's collapsed side, v = 1), and Newton's inversion has the least to
  // go on there. Points are made by the map itself at parametric
  // coordinates up to 1e-4 from the singular side (and at random), so the
  // cell and the value they must give are known without inverting anything.
  // Bent and twisted as twisted_hexes is: curved faces, non-affine cells.
  auto check = [](GeneratedMesh<8> g, bool pyramids, uint64_t seed) {
    for (size_t v = 0; v < g.xyz.size(); v += 3) {
      float const x = g.xyz[v], y = g.xyz[v + 1], z = g.xyz[v + 2];
      float const a = 0.35f * (z + 1.f);
      g.xyz[v] = std::cos(a) * x - std::sin(a) * y + 0.15f * std::sin(2.f * y);
      g.xyz[v + 1] = std::sin(a) * x + std::cos(a) * y;
    }
    HexMesh const mesh = g.mesh();
    test::Rng rng(seed);
    std::vector<float> xyz;
    std::vector<double> want;
    std::vector<int> made_at;  // index into near[]
    static constexpr double near[] = {0.5, 0.9, 0.99, 0.999, 0.9999};
    for (uint64_t c = 0; c < mesh.cell_count(); c += 3) {
      ref::Cell<8> const cell = ref::load(mesh, c);
      for (int k = 0; k < 5; ++k) {
        glm::dvec3 u(rng.uniform(0.02, 0.98), rng.uniform(0.02, 0.98), rng.uniform(0.02, 0.98));
        (pyramids ? u.z : u.y) = near[k];
        made_at.push_back(k);
        glm::dvec3 const p = ref::position(cell, u);
        xyz.insert(xyz.end(), {float(p.x), float(p.y), float(p.z)});
        want.push_back(ref::value(cell, u));
      }
    }
    MinMaxBvh const bvh = build_minmax_bvh(mesh);
    Scene const scene(mesh, bvh);
    std::vector<float> const got = sample_points(scene, xyz, test::isa_options());
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (float v : g.field) lo = std::min(lo, v), hi = std::max(hi, v);
    int lost = 0, wrong = 0;
    int lost_at[5] = {0, 0, 0, 0, 0};
    for (size_t i = 0; i < want.size(); ++i) {
      if (got[i] != got[i]) {
        ++lost;
        ++lost_at[made_at[i]];
      } else if (std::abs(double(got[i]) - want[i]) > 2e-5 * (double(hi) - lo)) {
        ++wrong;
        UNSCOPED_INFO("value " << got[i] << " at (" << xyz[3 * i] << ", " << xyz[3 * i + 1] << ", " << xyz[3 * i + 2]
                               << "), made as " << want[i]);
      }
    }
    INFO(want.size() << " points: lost " << lost << " (at 0.5, 0.9, 0.99, 0.999, 0.9999 of the way to the collapsed side: "
                     << lost_at[0] << ", " << lost_at[1] << ", " << lost_at[2] << ", " << lost_at[3] << ", " << lost_at[4]
                     << "), wrong " << wrong);
    CHECK(want.size() > 1000);
    CHECK(lost == 0);
    CHECK(wrong == 0);
  };
  SECTION("pyramids, apex at w = 1") { check(generate_pyramids(6 * 6 * 6 * 6, 14), true, 15); }
  SECTION("wedges, collapsed side at v = 1") { check(generate_wedges(2 * 7 * 7 * 7, 16), false, 17); }
}

TEST_CASE("sample_points over a scene: the first part (tets, then hexes) that holds a point gives its value",
          "[traverse][isa][probe]") {
  // Two tet parts overlapping in x in [0, 1] (different fields), and a hex
  // part beside them; the host-buffer overload writes the same values.
  auto const a = generate_tets(6 * 4 * 4 * 4, 10);
  auto b = generate_tets(6 * 4 * 4 * 4, 11);
  auto h = generate_hexes(4 * 4 * 4, 12);
  for (size_t v = 0; v < b.xyz.size(); v += 3) b.xyz[v] += 1.f;
  for (size_t v = 0; v < b.field.size(); ++v) b.field[v] += 10.f;
  for (size_t v = 0; v < h.xyz.size(); v += 3) h.xyz[v] += 2.5f;
  TetMesh const ma = a.mesh(), mb = b.mesh();
  HexMesh const mh = h.mesh();
  MinMaxBvh const ba = build_minmax_bvh(ma), bb = build_minmax_bvh(mb), bh = build_minmax_bvh(mh);
  Scene scene;
  scene.hexes.push_back({mh, &bh});
  scene.tets.push_back({ma, &ba});
  scene.tets.push_back({mb, &bb});
  test::Rng rng(13);
  std::vector<float> xyz;
  for (int i = 0; i < 3000; ++i) {
    glm::dvec3 const q = rng.in_box(-1.2, 1.2);
    xyz.insert(xyz.end(), {float(q.x * 2.0 + 1.3), float(q.y), float(q.z)});
  }
  std::vector<float> const v = sample_points(scene, xyz, test::isa_options());
  std::vector<float> host(xyz.size() / 3, 12345.f);
  sample_points(scene, xyz.data(), host.size(), host.data(), test::isa_options());
  int from[3] = {0, 0, 0}, bad = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    glm::dvec3 const p(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    RefValue const ra = reference_at(ma, p), rb = reference_at(mb, p), rh = reference_at(mh, p);
    bool const same = v[i] == host[i] || (v[i] != v[i] && host[i] != host[i]);
    bad += !same;
    // Away from the parts' boundaries (1e-4), exactly one answer is right.
    RefValue const* want = nullptr;
    int part = -1;
    if (ra.outside == 0) want = &ra, part = 0;
    else if (ra.outside > 1e-4 && rb.outside == 0) want = &rb, part = 1;
    else if (ra.outside > 1e-4 && rb.outside > 1e-4 && rh.outside == 0) want = &rh, part = 2;
    if (want) {
      bool const ok = v[i] == v[i] && std::abs(double(v[i]) - want->value) < 1e-4;
      bad += !ok;
      from[part] += ok;
    } else if (ra.outside > 1e-4 && rb.outside > 1e-4 && rh.outside > 1e-4) {
      bad += v[i] == v[i];
    }
  }
  INFO("from the first tet part " << from[0] << ", the second " << from[1] << ", the hexes " << from[2]);
  CHECK(bad == 0);
  CHECK(from[0] > 300);
  CHECK(from[1] > 300);
  CHECK(from[2] > 300);
  CHECK_THROWS_AS(sample_points(scene, nullptr, 3, host.data(), test::isa_options()), InvalidArgument);
  sample_points(scene, nullptr, 0, nullptr, test::isa_options());  // nothing to do
}

}  // namespace test_traverse_probe
