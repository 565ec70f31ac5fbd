// Tet marching (traverse/march.hpp) against a brute-force double-precision
// oracle (every cell clipped by cells/reference.hpp): the visible segments a
// march steps through must cover the ray exactly as the mesh's cells do, one
// after the other, with each cell's own crossing, and the march must really
// march (one tree query per stretch of mesh, not one per cell). Jittered and
// regular lattices (rays along shared edges, in shared faces, through
// vertices), a mesh with a hole the rays leave and re-enter, NaN cells, added
// degenerate cells, a value window with long transparent stretches.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/reference.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/mesh/vtk_cells.hpp>
#include <cellray/traverse/occlusion_query.hpp>

#include "support/cell_subsets.hpp"
#include "support/march_probe.hpp"
#include "support/ray_sets.hpp"
#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_traverse_march {

using namespace cellray;
using test::cells_without;
using test::lattice_rays;
using test::random_rays;
using test::union_length;
using test::MarchProbeOut;

namespace {

struct Crossing {
  double t_in, t_out, s_in, s_out;
  uint64_t cell;
};

/// Every cell crossed by the ray's line within [tmin, tmax], NaN cells
/// excluded, only crossings whose values meet `w` (as the march's filter).
template <int N> std::vector<Crossing> oracle(CellMesh<N> const& mesh, Ray const& r, ValueWindows const& w) {
  ref::Ray const rr{glm::dvec3(r.org), glm::dvec3(r.dir)};
  std::vector<Crossing> out;
  for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
    ref::Cell<N> const t = ref::load(mesh, c);
    if (ref::has_nan(t)) continue;
    ref::Clip const k = ref::clip(t, rr);
    if (!k.hit || k.t_out < double(r.tmin) || k.t_in > double(r.tmax)) continue;
    if (!w.overlaps(float(std::min(k.s_in, k.s_out)), float(std::max(k.s_in, k.s_out)))) continue;
    out.push_back({k.t_in, k.t_out, k.s_in, k.s_out, c});
  }
  return out;
}

struct Marched {
  std::vector<MarchProbeOut> out;
  int locates = 0, steps = 0;
};

template <int N>
Marched march(CellMesh<N> const& mesh, std::vector<Ray> const& rays, ValueWindows const& w, int how, int max_faint = 4) {
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  FaceNeighbours<N> const nb = [&] {
    if constexpr (N == 4) return build_tet_neighbours(mesh);
    else return build_hex_neighbours(mesh);
  }();
  Marched m;
  m.out.resize(rays.size());
  dispatch<test::MarchProbe>(test::isa(), mesh, bvh, nb, w, rays.data(), int(rays.size()), how, max_faint,
                             m.out.data());
  for (auto const& o : m.out) m.locates += o.locates, m.steps += o.steps;
  return m;
}

/// One ray's march against the oracle. `generic`: no ray along an edge or
/// in a face, so every oracle crossing longer than `tiny` must be listed.
/// Tolerances as tests/test_traverse_segment_query.cpp (positions O(1)).
template <int N>
void check_ray(CellMesh<N> const& mesh, Ray const& r, ValueWindows const& w, MarchProbeOut const& m, bool generic) {
  double const tol = 1e-4, tiny = 1e-3;
  std::vector<Crossing> const ref = oracle(mesh, r, w);
  INFO("ray org " << r.org.x << "," << r.org.y << "," << r.org.z << " dir " << r.dir.x << "," << r.dir.y << ","
                  << r.dir.z << " window " << r.tmin << ".." << r.tmax << ": " << m.count << " segments, "
                  << ref.size() << " in the oracle");
  REQUIRE(m.count < test::march_capacity);
  std::vector<std::pair<double, double>> mi, ri;
  double prev_end = double(r.tmin);
  int unmatched = 0;
  for (int i = 0; i < m.count; ++i) {
    CellSegment const& s = m.seg[i];
    // One after the other: each piece starts where the last ended, or later.
    double const a = std::max(double(s.t_in), prev_end);
    CHECK(double(s.t_out) > prev_end);
    mi.push_back({a, double(s.t_out)});
    prev_end = double(s.t_out);
    auto const it = std::find_if(ref.begin(), ref.end(), [&](Crossing const& x) { return x.cell == s.cell; });
    if (it == ref.end()) {
      unmatched += generic && s.t_out - s.t_in > tiny;
      continue;
    }
    CHECK(std::abs(double(s.t_in) - it->t_in) <= tol);
    CHECK(std::abs(double(s.t_out) - it->t_out) <= tol);
    CHECK(std::abs(double(s.v_in) - it->s_in) <= tol);
    CHECK(std::abs(double(s.v_out) - it->s_out) <= tol);
  }
  CHECK(unmatched == 0);
  for (Crossing const& x : ref) ri.push_back({x.t_in, x.t_out});
  double const lo = double(r.tmin), hi = double(r.tmax);
  CHECK(std::abs(union_length(mi, lo, hi) - union_length(ri, lo, hi)) <= tol * double(2 + m.count));
  if (!generic) return;
  for (Crossing const& x : ref) {
    if (x.t_out - x.t_in <= tiny || x.t_out < lo + tiny || x.t_in > hi - tiny) continue;
    bool found = false;
    for (int i = 0; i < m.count && !found; ++i) found = m.seg[i].cell == x.cell;
    INFO("cell " << x.cell << " t " << x.t_in << ".." << x.t_out);
    CHECK(found);
  }
}

}  // namespace

TEST_CASE("march: every visible crossing, in order, with one tree query per ray on a convex mesh", "[traverse][isa]") {
  auto const g = generate_tets(6 * 8 * 8 * 8, 3);
  TetMesh const mesh = g.mesh();
  ValueWindows const all;
  for (bool windows : {false, true}) {
    std::vector<Ray> const rays = random_rays(120, windows ? 2 : 1, windows);
    for (int how : {0, 1, 2}) {
      Marched const m = march(mesh, rays, all, how);
      for (size_t i = 0; i < rays.size(); ++i) check_ray(mesh, rays[i], all, m.out[i], true);
      // A convex mesh, every cell visible: a generic ray is located once,
      // marches to the boundary and asks once more (nothing behind it). A
      // march that went back to the tree at every cell would have ~steps
      // locates.
      INFO("traversal " << how << ", windows " << windows << ": " << m.locates << " locates, " << m.steps << " steps");
      CHECK(m.locates <= 2 * int(rays.size()));
      CHECK(m.steps > 5 * int(rays.size()));
    }
  }
}

TEST_CASE("march: rays along shared edges, in shared faces and through vertices of a regular lattice",
          "[traverse][isa]") {
  auto const g = generate_tets(6 * 6 * 6 * 6, 1, 0.f);
  TetMesh const mesh = g.mesh();
  std::vector<Ray> const rays = lattice_rays(6, 2);
  ValueWindows const all;
  Marched const m = march(mesh, rays, all, 0);
  for (size_t i = 0; i < rays.size(); ++i) check_ray(mesh, rays[i], all, m.out[i], false);
}

TEST_CASE("march: rays through and past the centres of split tets: every crossing, each cell left at its far face",
          "[traverse][isa]") {
  // Each tet split at its centroid into four (as tests/tools/refine_tets).
  // Rays aimed at a centroid, exactly or off by 1e-6, pass a vertex shared
  // by many cells and cross some for lengths at the rounding of t. The
  // onward clip (clip_tet_onward) then sees its Plücker test pass on every
  // face meeting at the vertex, and must leave by the one furthest along
  // the line, not the lowest (which gives a segment 0.02 short: the oracle
  // check fails). The locate bound below is loose (see there): it catches
  // a march that loses its way, not one that asks the tree a little more.
  auto const g = generate_tets(6 * 5 * 5 * 5, 4);
  std::vector<float> xyz = g.xyz, field = g.field;
  std::vector<uint32_t> cells;
  std::vector<glm::vec3> centres;
  for (size_t c = 0; c + 4 <= g.cells.size(); c += 4) {
    uint32_t const v = uint32_t(xyz.size() / 3);
    glm::vec3 p(0.f);
    float s = 0.f;
    for (int k = 0; k < 4; ++k) {
      uint32_t const a = g.cells[c + size_t(k)];
      p += glm::vec3(g.xyz[3 * a], g.xyz[3 * a + 1], g.xyz[3 * a + 2]) * 0.25f;
      s += 0.25f * g.field[a];
    }
    xyz.insert(xyz.end(), {p.x, p.y, p.z});
    field.push_back(s);
    centres.push_back(p);
    for (int centre_at = 0; centre_at < 4; ++centre_at)
      for (int k = 0; k < 4; ++k) cells.push_back(k == centre_at ? v : g.cells[c + size_t(k)]);
  }
  TetMesh const mesh{view(xyz), view(cells), view(field)};
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<Ray> rays;
  for (size_t i = 0; i < 160; ++i) {
    glm::vec3 const off = (i % 2 ? 1e-6f : 0.f) * glm::vec3(u(rng), u(rng), u(rng));
    glm::vec3 const aim = centres[(i * 37) % centres.size()] + off;
    glm::vec3 const org = 3.f * glm::normalize(glm::vec3(u(rng), u(rng), u(rng)) + glm::vec3(0.f, 0.f, 1e-3f));
    rays.push_back({org, 0.f, aim - org, 10.f});
  }
  ValueWindows const all;
  Marched const m = march(mesh, rays, all, 0);
  for (size_t i = 0; i < rays.size(); ++i) check_ray(mesh, rays[i], all, m.out[i], false);
  // Entering and finding nothing behind is 2 locates a ray on this convex
  // mesh; a vertex passed exactly may cost one more (the whole-cell clip's
  // march: 363 here; one that asks the tree at every stalled cell: 387,
  // session 39, also within the bound).
  INFO(m.locates << " locates, " << m.steps << " steps for " << rays.size() << " rays");
  CHECK(m.locates <= 3 * int(rays.size()));
  CHECK(m.steps > 10 * int(rays.size()));
}

TEST_CASE("march: parallelepipeds step by the slab clip: every crossing, rays along edges, in faces, through vertices",
          "[traverse][isa]") {
  // Every cell a parallelepiped: the march clips by slabs in the cell's own
  // coordinates (CellOps<A, 8>::march_clip_window), the locate by the same
  // test, so a located cell always progresses; faces seen from two sides
  // agree to rounding only. Regular lattice: rays along shared edges, in
  // shared faces, through vertices; the same lattice sheared by an affine
  // map; a lattice whose cells are half parallelepipeds, half distorted
  // (lanes of one step take either clip).
  auto regular = generate_hexes(6 * 6 * 6, 1, 0.f);
  auto sheared = generate_hexes(6 * 6 * 6, 1, 0.f);
  for (size_t v = 0; 3 * v < sheared.xyz.size(); ++v) {
    float* p = &sheared.xyz[3 * v];
    float const x = p[0], y = p[1], z = p[2];
    p[0] = x + 0.3f * y - 0.1f * z, p[1] = y + 0.2f * z, p[2] = z - 0.15f * x;
  }
  auto half = generate_hexes(6 * 6 * 6, 4, 0.f);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> shift(-0.05f, 0.05f);
  for (size_t v = 0; 3 * v < half.xyz.size(); ++v) {
    float* p = &half.xyz[3 * v];
    bool const interior = std::abs(p[0]) < 0.99f && std::abs(p[1]) < 0.99f && std::abs(p[2]) < 0.99f;
    if (interior && p[0] > 0.f)
      for (int a = 0; a < 3; ++a) p[a] += shift(rng);
  }
  ValueWindows const all;
  std::vector<Ray> const lattice = lattice_rays(6, 2), generic = random_rays(120, 17, false);
  int n_para = 0;
  for (auto const* g : {&regular, &sheared, &half}) {
    HexMesh const mesh = g->mesh();
    for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
      CellCorners<scalar, 8> const k = broadcast_corners<scalar, 8>(mesh, c);
      n_para += bool(isa_detail::parallelepiped_lanes<scalar>(k));
    }
    INFO((g == &regular ? "regular" : g == &sheared ? "sheared" : "half distorted") << " lattice on "
                                                                                   << isa_name(test::isa()));
    if (g != &sheared) {
      Marched const m = march(mesh, lattice, all, 0);
      for (size_t i = 0; i < lattice.size(); ++i) check_ray(mesh, lattice[i], all, m.out[i], false);
    }
    for (int how : {0, 1}) {
      Marched const m = march(mesh, generic, all, how);
      for (size_t i = 0; i < generic.size(); ++i) check_ray(mesh, generic[i], all, m.out[i], true);
      // Convex: entered once, left once; a located cell that the step's
      // clip could not progress through would send the lane back each time.
      CHECK(m.locates <= 2 * int(generic.size()));
      CHECK(m.steps > 3 * int(generic.size()));
    }
  }
  // Regular and sheared: all 2 x 216; the distorted half: about half of 216.
  CHECK(n_para > 2 * 216 + 216 / 4);
  CHECK(n_para < 3 * 216 - 216 / 4);
}

TEST_CASE("march: rays leave the mesh through a hole and are located again behind it", "[traverse][isa]") {
  auto const g = generate_tets(6 * 8 * 8 * 8, 5);
  // A slab through the middle, |z| < 0.25, removed: every ray along z crosses it.
  std::vector<uint32_t> const cells = cells_without(g, [](glm::vec3 c) { return std::abs(c.z) < 0.25f; });
  TetMesh const mesh{view(g.xyz), view(cells), view(g.field)};
  std::vector<Ray> rays;
  for (int i = 0; i < 64; ++i)
    rays.push_back({{-0.9f + 0.028f * float(i), 0.7f - 0.021f * float(i), -2.f}, 0.f, {0.05f, 0.03f, 1.f}, 10.f});
  ValueWindows const all;
  Marched const m = march(mesh, rays, all, 0);
  for (size_t i = 0; i < rays.size(); ++i) check_ray(mesh, rays[i], all, m.out[i], true);
  CHECK(m.locates >= 2 * int(rays.size()));  // in front of the hole and behind it
}

TEST_CASE("march: NaN cells and degenerate cells are gaps, not ends", "[traverse][isa]") {
  auto g = generate_tets(6 * 7 * 7 * 7, 6);
  // NaN at a few interior vertices: their cells are invisible.
  for (size_t v = 0; v < g.field.size(); v += 37) g.field[v] = std::numeric_limits<float>::quiet_NaN();
  // Degenerate cells: a repeated vertex id over existing vertices, and
  // zero-volume cells over four new coplanar vertices inside the mesh.
  std::vector<uint32_t> cells = g.cells;
  for (uint32_t c = 0; c + 4 <= uint32_t(g.cells.size()); c += 4 * 97)
    cells.insert(cells.end(), {g.cells[c], g.cells[c], g.cells[c + 1], g.cells[c + 2]});
  std::vector<float> xyz = g.xyz, field = g.field;
  for (int k = 0; k < 6; ++k) {
    uint32_t const v = uint32_t(xyz.size() / 3);
    float const z = -0.6f + 0.25f * float(k);
    for (glm::vec2 p : {glm::vec2(-0.5f, -0.4f), glm::vec2(0.6f, -0.3f), glm::vec2(0.1f, 0.7f), glm::vec2(0.f, 0.f)}) {
      xyz.insert(xyz.end(), {p.x, p.y, z});
      field.push_back(0.5f);
    }
    cells.insert(cells.end(), {v, v + 1, v + 2, v + 3});
  }
  TetMesh const mesh{view(xyz), view(cells), view(field)};
  ValueWindows const all;
  std::vector<Ray> const rays = random_rays(90, 7, false);
  Marched const m = march(mesh, rays, all, 0);
  for (size_t i = 0; i < rays.size(); ++i) check_ray(mesh, rays[i], all, m.out[i], true);
}

TEST_CASE("march: a value window skips transparent stretches through the tree, whatever max_faint", "[traverse][isa]") {
  auto const g = generate_tets(6 * 8 * 8 * 8, 9);
  TetMesh const mesh = g.mesh();
  float const lo = *std::min_element(g.field.begin(), g.field.end()), hi = *std::max_element(g.field.begin(), g.field.end());
  ValueWindows w;
  w.lo[0] = lo + 2.f * (hi - lo) / 3.f, w.hi[0] = hi;  // the top third, as the cool-warm preset
  std::vector<Ray> const rays = random_rays(120, 10, false);
  int locates[3] = {}, steps[3] = {};
  int const faint[3] = {0, 4, 1000};
  for (int k = 0; k < 3; ++k) {
    Marched const m = march(mesh, rays, w, 0, faint[k]);
    locates[k] = m.locates, steps[k] = m.steps;
    for (size_t i = 0; i < rays.size(); ++i) check_ray(mesh, rays[i], w, m.out[i], true);
  }
  // Going back to the tree after every invisible cell locates most often
  // and steps least; never going back (1000) marches every transparent
  // stretch to the mesh's boundary.
  INFO("max_faint 0, 4, 1000: locates " << locates[0] << ", " << locates[1] << ", " << locates[2] << "; steps "
                                        << steps[0] << ", " << steps[1] << ", " << steps[2]);
  CHECK(locates[0] >= locates[1]);
  CHECK(locates[1] >= locates[2]);
  CHECK(steps[0] < steps[1]);
  CHECK(steps[1] < steps[2]);
}

namespace {

/// Grouped first-cell locates (FirstCellGroup: four packets per traversal,
/// one clip setup per cell when the packets share their origin) against
/// each packet's own traversal, bit for bit, and against the oracle's first
/// visible crossing past tmin.
template <int N> void check_first_cells(CellMesh<N> const& mesh, char const* type) {
  float const lo = *std::min_element(mesh.values(), mesh.values() + mesh.vertex_count());
  float const hi = *std::max_element(mesh.values(), mesh.values() + mesh.vertex_count());
  ValueWindows w;
  w.lo[0] = lo + 0.4f * (hi - lo), w.hi[0] = hi;
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  // A camera's rays (one origin; pixel rows in packets, so a group's
  // packets are neighbours), then rays from scattered origins.
  std::vector<Ray> camera_rays;
  glm::vec3 const eye(0.35f, 0.3f, -2.7f);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x)
      camera_rays.push_back({eye, y < 8 ? 0.f : 2.2f, glm::vec3(-0.9f + 0.12f * float(x), -0.9f + 0.12f * float(y), 0.f) - eye, 1e30f});
  std::vector<Ray> const camera = camera_rays, scattered = random_rays(256, 5, false);
  for (std::vector<Ray> const* rays : {&camera, &scattered}) {
    int const n = int(rays->size());
    std::vector<test::FirstCellsOut> grouped(rays->size()), alone(rays->size());
    dispatch<test::FirstCellsProbe>(test::isa(), mesh, bvh, w, rays->data(), n, grouped.data(), alone.data());
    int found = 0, off = 0;
    for (int i = 0; i < n; ++i) {
      Ray const& r = (*rays)[size_t(i)];
      INFO(type << (rays == &camera ? ", one origin" : ", scattered origins") << ", ray " << i);
      CHECK(grouped[size_t(i)].cell == alone[size_t(i)].cell);
      CHECK(std::memcmp(&grouped[size_t(i)].t_in, &alone[size_t(i)].t_in, sizeof(float)) == 0);
      // The oracle: the smallest t_in of the visible crossings ending past
      // tmin; visible as the march filters (visible_values): a linear field
      // by its values on the ray, a trilinear one by its corners'.
      double best = std::numeric_limits<double>::infinity();
      for (Crossing const& x : oracle(mesh, r, ValueWindows{})) {
        ref::Cell<N> const cell = ref::load(mesh, x.cell);
        double vmin = std::min(x.s_in, x.s_out), vmax = std::max(x.s_in, x.s_out);
        if (N == 8) vmin = *std::min_element(cell.s, cell.s + N), vmax = *std::max_element(cell.s, cell.s + N);
        if (x.t_out > double(r.tmin) + 1e-4 && w.overlaps(float(vmin), float(vmax))) best = std::min(best, x.t_in);
      }
      found += alone[size_t(i)].cell >= 0;
      if (std::isinf(best)) off += alone[size_t(i)].cell >= 0;
      else off += alone[size_t(i)].cell < 0 || std::abs(double(alone[size_t(i)].t_in) - best) > 1e-4;
    }
    INFO(type << ": " << found << " of " << n << " rays found a cell, " << off << " differ from the oracle");
    CHECK(found > n / 4);
    CHECK(off <= n / 100);
  }
}

}  // namespace

TEST_CASE("march: four packets locate their first cells together as each would alone", "[traverse][isa]") {
  auto const tets = generate_tets(6 * 8 * 8 * 8, 4);
  auto const family = generate_hex_family(8 * 8 * 8, 4);
  check_first_cells(tets.mesh(), "tets");
  check_first_cells(family.mesh(), "hex family");
}

TEST_CASE("march: tets folded into hexahedra step through the tet kernels, cell for cell as the tets march",
          "[traverse][isa]") {
  // Every tet as the hexahedron 0 1 2 2 3 3 3 3 (fold_tets_into_hexes): the
  // hexahedral march clips a folded tet with the tet kernel over the same
  // corners in the same order, leaves through the hexahedron face opposite
  // the tet's exit corner and counts it visible by its end values, so it
  // steps through the same cells with the same segments and locates as
  // often. A wrong exit face sends a lane into the wrong cell (or back to
  // the tree). The segments agree to rounding, not bit for bit: the tet
  // march clips onward from the entry face (clip_tet_onward), the folded
  // hexahedra with the whole-cell clip.
  auto const g = generate_tets(6 * 8 * 8 * 8, 5);
  TetMesh const tets = g.mesh();
  std::vector<uint32_t> folded;
  for (size_t c = 0; c + 4 <= g.cells.size(); c += 4)
    for (int k : tet_as_hex) folded.push_back(g.cells[c + size_t(k)]);
  HexMesh const hexes{view(g.xyz), view(folded), view(g.field)};
  MinMaxBvh const hb = build_minmax_bvh(hexes);
  HexNeighbours const hn = build_hex_neighbours(hexes);
  float const lo = *std::min_element(g.field.begin(), g.field.end()), hi = *std::max_element(g.field.begin(), g.field.end());
  ValueWindows top;
  top.lo[0] = lo + 2.f * (hi - lo) / 3.f, top.hi[0] = hi;
  std::vector<Ray> rays = random_rays(150, 12, false);
  std::vector<Ray> const windowed = random_rays(60, 13, true);
  rays.insert(rays.end(), windowed.begin(), windowed.end());
  INFO("on " << isa_name(test::isa()));
  for (bool const windowed_values : {false, true}) {
    ValueWindows const w = windowed_values ? top : ValueWindows{};
    Marched const a = march(tets, rays, w, 0);
    std::vector<MarchProbeOut> b(rays.size());
    dispatch<test::MarchProbe>(test::isa(), hexes, hb, hn, w, rays.data(), int(rays.size()), 0, 4, b.data());
    int segments = 0, other_cell = 0, differ = 0, locates = 0;
    auto near = [](float a, float b) { return std::abs(a - b) <= 1e-5f * std::max(1.f, std::abs(a)); };
    for (size_t i = 0; i < rays.size(); ++i) {
      MarchProbeOut const &x = a.out[i], &y = b[i];
      INFO("ray " << i);
      CHECK(x.count == y.count);
      CHECK(x.steps == y.steps);
      CHECK(x.locates == y.locates);
      locates += y.locates;
      for (int k = 0; k < std::min(x.count, y.count); ++k, ++segments) {
        other_cell += x.seg[k].cell != y.seg[k].cell;
        differ += !near(x.seg[k].t_in, y.seg[k].t_in) || !near(x.seg[k].t_out, y.seg[k].t_out) ||
                  !near(x.seg[k].v_in, y.seg[k].v_in) || !near(x.seg[k].v_out, y.seg[k].v_out);
      }
    }
    CHECK(segments > (windowed_values ? 200 : 1000));
    CHECK(other_cell == 0);
    CHECK(differ == 0);
    // It marches: on this convex mesh without a window, a locate to enter
    // and one to find nothing more, not one per cell.
    if (!windowed_values) CHECK(locates <= 2 * int(rays.size()));
  }
}

namespace {

/// Every cell of both parts crossed by the ray within [tmin, tmax] (double
/// reference clips), as oracle(): `cell` is the tet's id, or the
/// hexahedron's + 2^40.
constexpr uint64_t hex_tag = uint64_t(1) << 40;
std::vector<Crossing> mixed_oracle(TetMesh const& tets, HexMesh const& hexes, Ray const& r) {
  ref::Ray const rr{glm::dvec3(r.org), glm::dvec3(r.dir)};
  std::vector<Crossing> out;
  auto add = [&](ref::Clip const& k, uint64_t cell) {
    if (k.hit && k.t_out >= double(r.tmin) && k.t_in <= double(r.tmax)) out.push_back({k.t_in, k.t_out, k.s_in, k.s_out, cell});
  };
  for (uint64_t c = 0; c < tets.cell_count(); ++c) add(ref::clip(ref::load(tets, c), rr), c);
  for (uint64_t c = 0; c < hexes.cell_count(); ++c) add(ref::clip(ref::load(hexes, c), rr), c + hex_tag);
  return out;
}

/// A smooth field over a mixed gmsh mesh from tests/data, its two parts
/// (sharing the grid's vertices), their trees and linked neighbours.
struct MixedParts {
  UnstructuredGrid grid;
  std::vector<float> field;
  TetMesh tets;
  HexMesh hexes;
  MinMaxBvh tet_bvh, hex_bvh;
  TetNeighbours tet_nb;
  HexNeighbours hex_nb;
  explicit MixedParts(std::string const& file) : grid(read_mesh(std::string(CELLRAY_TEST_DATA) + "/gmsh/" + file)) {
    field.resize(grid.vertex_count());
    for (uint64_t v = 0; v < grid.vertex_count(); ++v) {
      float const* q = &grid.xyz[3 * v];
      field[v] = std::sin(3.f * q[0]) + q[1] * q[1] + 0.5f * q[2];
    }
    tets = grid.tet_mesh().with_values(view(field));
    hexes = grid.hex_mesh().with_values(view(field));
    tet_bvh = build_minmax_bvh(tets), hex_bvh = build_minmax_bvh(hexes);
    tet_nb = build_tet_neighbours(tets), hex_nb = build_hex_neighbours(hexes);
  }
};

/// Generic rays from outside [lo, hi] to random points of its middle
/// (the box shrunk to 30% about its centre: where both files' parts meet).
std::vector<Ray> rays_into(glm::vec3 lo, glm::vec3 hi, int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u01(0.f, 1.f), u(-1.f, 1.f);
  std::vector<Ray> rays;
  glm::vec3 const c = 0.5f * (lo + hi);
  float const diag = glm::length(hi - lo);
  for (int i = 0; i < n; ++i) {
    glm::vec3 const target = c + 0.3f * (glm::vec3(u01(rng), u01(rng), u01(rng)) - 0.5f) * (hi - lo);
    glm::vec3 d(u(rng), u(rng), u(rng));
    if (!(glm::length(d) > 0.1f)) d = glm::vec3(0.3f, 0.5f, 0.8f);
    glm::vec3 const org = c - 1.5f * diag * glm::normalize(d) + 0.2f * (target - c);
    rays.push_back({org, 0.f, target - org, 2.f});
  }
  return rays;
}

}  // namespace

TEST_CASE("march: a mixed mesh's tets and hexahedra (wedges, pyramids) march as one across linked faces",
          "[traverse][isa]") {
  // mixed22: a hex block glued to a tet block, pyramids between (convex);
  // sphere_bl_small: prisms and hexahedra grown from a sphere, tets out to a
  // box, pyramids between (rays cross the sphere's hole).
  for (char const* file : {"mixed22.msh", "sphere_bl_small.msh"}) {
    MixedParts m(file);
    REQUIRE(m.tets.cell_count() > 0);
    REQUIRE(m.hexes.cell_count() > 0);
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (uint64_t v = 0; v < m.grid.vertex_count(); ++v) lo = glm::min(lo, m.tets.position(v)), hi = glm::max(hi, m.tets.position(v));
    std::vector<Ray> const rays = rays_into(lo, hi, 160, 21);
    int const n = int(rays.size());
    auto run = [&](int how, std::vector<test::MixedMarchProbeOut>& out) {
      out.assign(rays.size(), {});
      dispatch<test::MixedMarchProbe>(test::isa(), m.tets, m.tet_bvh, m.tet_nb, m.hexes, m.hex_bvh, m.hex_nb,
                                      rays.data(), n, how, out.data());
      int locates = 0, crossings = 0;
      for (auto const& o : out) locates += o.locates, crossings += o.crossings;
      return std::make_pair(locates, crossings);
    };
    std::vector<test::MixedMarchProbeOut> out;
    auto const unlinked = run(0, out);
    CHECK(unlinked.second == 0);  // without links a lane never crosses to the other part
    link_face_neighbours(m.tets, m.tet_nb, m.hexes, m.hex_nb);
    for (int how : {0, 1, 2}) {
      auto const linked = run(how, out);
      INFO(file << ", traversal " << how << ": " << linked.first << " locates and " << linked.second
                << " crossings linked; " << unlinked.first << " locates unlinked");
      CHECK(linked.second > n / 4);
      CHECK(linked.first < unlinked.first);
      // A locate where a ray enters the mesh and where it leaves it (mixed22,
      // convex: twice; sphere_bl: twice more through the hole), not at every
      // change of part.
      CHECK(linked.first <= 4 * n);
      double const tol = 1e-4, tiny = 1e-3;
      for (int i = 0; i < n; ++i) {
        Ray const& r = rays[size_t(i)];
        test::MixedMarchProbeOut const& o = out[size_t(i)];
        std::vector<Crossing> const ref = mixed_oracle(m.tets, m.hexes, r);
        INFO("ray " << i << ": " << o.count << " segments, " << ref.size() << " in the oracle");
        REQUIRE(o.count < test::march_capacity);
        std::vector<std::pair<double, double>> mi, ri;
        double prev_end = double(r.tmin);
        for (int k = 0; k < o.count; ++k) {
          CellSegment const& sg = o.seg[k];
          CHECK(double(sg.t_out) > prev_end);  // one after the other
          mi.push_back({std::max(double(sg.t_in), prev_end), double(sg.t_out)});
          prev_end = double(sg.t_out);
          uint64_t const key = sg.cell + (sg.piece ? hex_tag : 0);
          auto const it = std::find_if(ref.begin(), ref.end(), [&](Crossing const& x) { return x.cell == key; });
          if (it == ref.end()) {  // a graze the double clip misses
            CHECK(sg.t_out - sg.t_in <= tiny);
            continue;
          }
          CHECK(std::abs(double(sg.t_in) - it->t_in) <= tol);
          CHECK(std::abs(double(sg.t_out) - it->t_out) <= tol);
          CHECK(std::abs(double(sg.v_in) - it->s_in) <= tol * 10);
          CHECK(std::abs(double(sg.v_out) - it->s_out) <= tol * 10);
        }
        for (Crossing const& x : ref) ri.push_back({x.t_in, x.t_out});
        double const a = double(r.tmin), b = double(r.tmax);
        CHECK(std::abs(union_length(mi, a, b) - union_length(ri, a, b)) <= tol * double(2 + o.count));
        for (Crossing const& x : ref) {  // every crossing longer than `tiny` was stepped through
          if (x.t_out - x.t_in <= tiny || x.t_out < a + tiny || x.t_in > b - tiny) continue;
          bool found = false;
          for (int k = 0; k < o.count && !found; ++k) found = o.seg[k].cell + (o.seg[k].piece ? hex_tag : 0) == x.cell;
          CHECK(found);
        }
      }
    }
  }
}

namespace {

/// Short rays from random points inside random cells (as AO rays leave an
/// isosurface hit inside its hit cell), with the cell they start in: tets
/// at random barycentric weights, hexahedra at random trilinear coordinates
/// in [0.05, 0.95]^3.
template <int N>
void ao_like_rays(CellMesh<N> const& mesh, int n, uint32_t seed, float radius, std::vector<Ray>& rays,
                  std::vector<int32_t>& start) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u01(0.f, 1.f), u(-1.f, 1.f);
  std::uniform_int_distribution<uint64_t> pick(0, mesh.cell_count() - 1);
  for (int i = 0; i < n; ++i) {
    uint64_t const c = pick(rng);
    float w[N];
    if constexpr (N == 4) {
      float sum = 0.f;
      for (float& x : w) sum += (x = 0.05f + u01(rng));
      for (float& x : w) x /= sum;
    } else {
      float const uvw[3] = {0.05f + 0.9f * u01(rng), 0.05f + 0.9f * u01(rng), 0.05f + 0.9f * u01(rng)};
      for (int k = 0; k < 8; ++k) {  // VTK order: bit 0 of (k ^ k >> 1) is u, bit 1 of k is v, bit 2 w
        int const iu = (k ^ (k >> 1)) & 1, iv = (k >> 1) & 1, iw = (k >> 2) & 1;
        w[k] = (iu ? uvw[0] : 1 - uvw[0]) * (iv ? uvw[1] : 1 - uvw[1]) * (iw ? uvw[2] : 1 - uvw[2]);
      }
    }
    glm::vec3 p(0.f);
    for (int k = 0; k < N; ++k) p += w[k] * mesh.position(mesh.vertex(c, k));
    glm::vec3 d(u(rng), u(rng), u(rng));
    if (!(glm::length(d) > 0.1f)) d = glm::vec3(0.3f, 0.5f, 0.8f);
    rays.push_back({p, 1e-5f, glm::normalize(d), radius});
    start.push_back(int32_t(c));
  }
}

/// march_occluded from known cells against the tree's occlusion query, on
/// a convex mesh and on one with a slab removed (rays leaving the mesh there
/// are the tree's to finish).
template <int N> void check_march_occlusion(GeneratedMesh<N> const& g, char const* type) {
  std::vector<uint32_t> const holed = cells_without(g, [](glm::vec3 c) { return std::abs(c.x) < 0.2f; });
  for (bool hole : {false, true}) {
    CellMesh<N> const mesh = hole ? CellMesh<N>{view(g.xyz), view(holed), view(g.field)} : g.mesh();
    MinMaxBvh const bvh = build_minmax_bvh(mesh);
    FaceNeighbours<N> const nb = [&] {
      if constexpr (N == 4) return build_tet_neighbours(mesh);
      else return build_hex_neighbours(mesh);
    }();
    TreeView const tree(bvh);
    std::vector<Ray> rays;
    std::vector<int32_t> start;
    ao_like_rays(mesh, 600, hole ? 13u : 12u, 0.4f, rays, start);
    IsoQuery q;
    q.isos.count = 2;
    q.isos.values[0] = 0.3f, q.isos.values[1] = 0.55f;
    int const n = int(rays.size());
    std::vector<uint8_t> occ(static_cast<size_t>(n)), und(static_cast<size_t>(n));
    std::vector<float> done(static_cast<size_t>(n));
    dispatch<test::MarchOcclusionProbe>(test::isa(), mesh, bvh, nb, rays.data(), start.data(), n, q.isos, occ.data(),
                                        und.data(), done.data());
    std::vector<uint8_t> const tree_answer = occluded_rays(tree, mesh, rays, q, false, test::isa());
    // The tree over [t_done, tmax] finishes what the march could not.
    std::vector<Ray> rest;
    for (int i = 0; i < n; ++i)
      if (und[size_t(i)]) rest.push_back(rays[size_t(i)]), rest.back().tmin = done[size_t(i)];
    std::vector<uint8_t> const rest_answer = occluded_rays(tree, mesh, rest, q, false, test::isa());
    int differ = 0, undecided = 0, occluded = 0, j = 0, undecided_inside = 0;
    for (int i = 0; i < n; ++i) {
      bool answer = occ[size_t(i)] != 0;
      if (und[size_t(i)]) {
        CHECK(!answer);
        answer = rest_answer[size_t(j++)] != 0;
        ++undecided;
        // A ray whose end lies well inside the cube (boundary vertices are
        // jittered by up to 0.06) never left the convex mesh.
        glm::vec3 const e = rays[size_t(i)].org + rays[size_t(i)].tmax * rays[size_t(i)].dir;
        undecided_inside += std::max(std::abs(e.x), std::max(std::abs(e.y), std::abs(e.z))) < 0.9f;
      }
      differ += answer != (tree_answer[size_t(i)] != 0);
      occluded += answer;
    }
    INFO(type << (hole ? ", with a hole" : ", convex") << ": " << occluded << " occluded, " << undecided
              << " undecided of " << n << ", " << undecided_inside << " of those ending inside the cube");
    CHECK(differ == 0);
    CHECK(occluded > n / 10);
    CHECK(occluded < n - n / 10);
    // Only rays that leave the mesh are left to the tree (a march that gave
    // up on every ray would leave them all), but for a hexahedron's exit
    // face picked wrong next to an edge (CellMarch's file comment).
    if (!hole) CHECK(undecided_inside <= (N == 4 ? 0 : n / 100));
    CHECK(undecided < n / 2);
  }
}

}  // namespace

TEST_CASE("march: occlusion of short rays from known cells answers as the tree does", "[traverse][isa]") {
  check_march_occlusion(generate_tets(6 * 10 * 10 * 10, 11), "tets");
  check_march_occlusion(generate_hexes(10 * 10 * 10, 11), "hexahedra");
}

}  // namespace test_traverse_march
