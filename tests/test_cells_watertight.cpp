// Watertightness: rays aimed exactly at shared faces, interior edges and
// interior vertices of generated and real meshes. Brute force over all cells
// (no BVH): clip intervals must chain without gaps or overlaps, sample points
// must lie in exactly one cell, and the iso crossing placed at the aimed
// point (isovalue = the field there) must be found exactly once.

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/validate.hpp>

#include "support/adversarial.hpp"
#include "support/cells_runner.hpp"
#include "support/test_data.hpp"
#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_cells_watertight {

using namespace cellray;
using cellray::test::CellRunner;
using cellray::test::Rng;

namespace {

struct Stats {
  int rays = 0, samples = 0, gaps = 0, doubles = 0, chain_gaps = 0, chain_overlaps = 0;
  int aimed_gaps = 0, aimed_doubles = 0;  // of gaps, doubles: at the aimed point (the last sample of a ray)
  int aimed = 0, lost = 0, duplicated = 0, tangent_pairs = 0, excluded = 0, hull = 0;
  double max_gap = 0, max_overlap = 0;
};

/// `g` with each hex's corners re-listed by one of 8 rotations of the cube
/// (about its vertical axis, optionally turned upside down): the same cells,
/// still positively oriented VTK hexes. The lattice lists both hexes of a
/// shared face with its corners in the same rotation, which would hide a
/// broken canonical face order (tried: patches taken in the cells' own
/// corner order went unnoticed on the unrotated lattice).
GeneratedMesh<8> rotated_hexes(GeneratedMesh<8> g, uint64_t seed) {
  static constexpr int spin[4][8] = {
      {0, 1, 2, 3, 4, 5, 6, 7}, {1, 2, 3, 0, 5, 6, 7, 4}, {2, 3, 0, 1, 6, 7, 4, 5}, {3, 0, 1, 2, 7, 4, 5, 6}};
  static constexpr int upside_down[8] = {4, 7, 6, 5, 0, 3, 2, 1};
  Rng rng(seed);
  for (size_t c = 0; c < g.cells.size(); c += 8) {
    uint32_t old[8];
    std::copy_n(&g.cells[c], 8, old);
    uint64_t const r = rng.next() % 8;
    for (int k = 0; k < 8; ++k) {
      int const i = spin[r % 4][k];
      g.cells[c + size_t(k)] = old[r < 4 ? i : upside_down[i]];
    }
  }
  return g;
}

/// `g` with each wedge (a collapsed hex a b c c d e f f: the VTK wedge
/// a c b d f e, mesh/vtk_cells.hpp) re-listed from another corner of its
/// triangles (turned by 0, 1 or 2 thirds): the same cells, still positively
/// oriented, but a triangle end shared by two wedges now has its repeated
/// corner at different vertices in the two cells, as in real meshes.
GeneratedMesh<8> rotated_wedges(GeneratedMesh<8> g, uint64_t seed) {
  Rng rng(seed);
  for (size_t c = 0; c < g.cells.size(); c += 8) {
    uint32_t* h = &g.cells[c];
    bool const wedge = h[2] == h[3] && h[6] == h[7] && h[0] != h[1] && h[1] != h[2] && h[4] != h[5];
    if (!wedge) continue;
    for (uint64_t turns = rng.next() % 3; turns > 0; --turns) {
      uint32_t const w[6] = {h[0], h[2], h[1], h[4], h[6], h[5]};  // VTK wedge order
      uint32_t const t[6] = {w[1], w[2], w[0], w[4], w[5], w[3]};  // the same wedge from its next corner
      uint32_t const back[8] = {t[0], t[2], t[1], t[1], t[3], t[5], t[4], t[4]};
      std::copy_n(back, 8, h);
    }
  }
  return g;
}

template <int N> struct Boxes {
  std::vector<glm::vec3> lo, hi;
  explicit Boxes(CellMesh<N> const& m) {
    for (uint64_t c = 0; c < m.cell_count(); ++c) {
      glm::vec3 a(1e30f), b(-1e30f);
      for (int k = 0; k < N; ++k) a = glm::min(a, m.position(m.vertex(c, k))), b = glm::max(b, m.position(m.vertex(c, k)));
      lo.push_back(a), hi.push_back(b);
    }
  }
};

/// Corner lists of the faces and edges of a tet (N = 4) or VTK hex (N = 8).
template <int N> struct CellShape;
template <> struct CellShape<4> {
  static constexpr int faces = 4, face_size = 3, edges = 6;
  static constexpr int face[4][4] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  static constexpr int edge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
};
template <> struct CellShape<8> {
  static constexpr int faces = 6, face_size = 4, edges = 12;
  static constexpr int face[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4}, {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};
  static constexpr int edge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                      {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
};

/// Which faces are shared by two cells, and which edges and vertices lie on
/// the mesh boundary: rays are aimed at interior features only, where a
/// crossing has a cell on both sides (at the boundary, "before the mesh" has
/// no value and a crossing at the boundary face is legitimately either side).
/// A face is its distinct vertex ids, as in build_hex_neighbours: a wedge's
/// triangle end (a collapsed hex face) meets another cell's triangle, and a
/// face with fewer than three distinct ids (collapsed to an edge or a point)
/// is no face.
template <int N> struct Topology {
  using S = CellShape<N>;
  std::map<std::vector<uint64_t>, int> face_count;
  std::set<std::pair<uint64_t, uint64_t>> boundary_edges;
  std::set<uint64_t> boundary_vertices;
  std::vector<uint64_t> face_key(CellMesh<N> const& m, uint64_t c, int f) const {
    std::vector<uint64_t> k;
    for (int i = 0; i < S::face_size; ++i) k.push_back(m.vertex(c, S::face[f][i]));
    std::sort(k.begin(), k.end());
    k.erase(std::unique(k.begin(), k.end()), k.end());
    return k;
  }
  explicit Topology(CellMesh<N> const& m) {
    for (uint64_t c = 0; c < m.cell_count(); ++c)
      for (int f = 0; f < S::faces; ++f)
        if (auto const k = face_key(m, c, f); k.size() >= 3) ++face_count[k];
    for (uint64_t c = 0; c < m.cell_count(); ++c)
      for (int f = 0; f < S::faces; ++f) {
        auto const k = face_key(m, c, f);
        if (k.size() < 3 || face_count[k] != 1) continue;
        for (int i = 0; i < S::face_size; ++i) {
          uint64_t const a = m.vertex(c, S::face[f][i]), b = m.vertex(c, S::face[f][(i + 1) % S::face_size]);
          boundary_vertices.insert(a);
          if (a != b) boundary_edges.insert({std::min(a, b), std::max(a, b)});
        }
      }
  }
  bool shared_face(CellMesh<N> const& m, uint64_t c, int f) const {
    auto const it = face_count.find(face_key(m, c, f));
    return it != face_count.end() && it->second == 2;
  }
  bool interior_edge(uint64_t a, uint64_t b) const { return !boundary_edges.count({std::min(a, b), std::max(a, b)}); }
  bool interior_vertex(uint64_t v) const { return !boundary_vertices.count(v); }
};

/// A point on a random interior face (kind 0), edge (1) or vertex (2) of a
/// random cell, and the field there in double.
template <int N>
void aim(Rng& rng, CellMesh<N> const& m, Topology<N> const& topo, int kind, glm::dvec3& target, double& value) {
  using S = CellShape<N>;
  for (;;) {
    uint64_t const c = rng.next() % m.cell_count();
    ref::Cell<N> const cell = ref::load(m, c);
    if (kind == 0) {
      int const f = int(rng.next() % S::faces);
      if (!topo.shared_face(m, c, f)) continue;
      int const* v = S::face[f];
      double a = rng.uniform(0.05, 0.95), b = rng.uniform(0.05, 0.95);
      if (N == 4) {
        if (a + b > 1) a = 1 - a, b = 1 - b;
        target = cell.p[v[0]] + a * (cell.p[v[1]] - cell.p[v[0]]) + b * (cell.p[v[2]] - cell.p[v[0]]);
        value = cell.s[v[0]] + a * (cell.s[v[1]] - cell.s[v[0]]) + b * (cell.s[v[2]] - cell.s[v[0]]);
      } else {
        auto bl = [&](auto const* q) { return (1 - b) * ((1 - a) * q[v[0]] + a * q[v[1]]) + b * ((1 - a) * q[v[3]] + a * q[v[2]]); };
        target = bl(cell.p), value = bl(cell.s);
      }
      return;
    }
    if (kind == 1) {
      int const* e = S::edge[rng.next() % S::edges];
      if (cell.id[e[0]] == cell.id[e[1]]) continue;  // a collapsed edge (wedge, pyramid)
      if (!topo.interior_edge(cell.id[e[0]], cell.id[e[1]])) continue;
      double const a = rng.uniform(0.05, 0.95);
      target = cell.p[e[0]] + a * (cell.p[e[1]] - cell.p[e[0]]);
      value = cell.s[e[0]] + a * (cell.s[e[1]] - cell.s[e[0]]);
      return;
    }
    int const i = int(rng.next() % N);
    if (!topo.interior_vertex(cell.id[i])) continue;
    target = cell.p[i], value = cell.s[i];
    return;
  }
}

/// `convex`: the mesh fills a convex domain, so any hole along a ray inside
/// the hull of the hit intervals is a watertightness failure; otherwise only
/// holes shorter than 1e-4 of the ray's span count (longer ones are the
/// mesh's own concave boundary).
///
/// Iso crossings: the ray is aimed at point P (t = 3) with the isovalue
/// equal to the field at P, so a crossing sits exactly on the shared face,
/// edge or vertex. Counted within a window of 1e-4 x the mesh diagonal around
/// P, in each cell its first crossing: r from the double reference, h from
/// the float kernel. Crossings along a ray alternate, so r and h must have
/// the same parity: an odd difference is a crossing lost (h < r) or counted
/// twice (h > r). An even difference is a tangent pair: the field along the
/// ray has an extremum at P within rounding of the isovalue (the two cells'
/// slopes have opposite signs there), the double reference sees the
/// isovalue touched twice and float not at all, or the reverse; both
/// answers are consistent, which one is right depends on the last bit of
/// the face value. Excluded and counted: rays where a cell crosses the
/// isovalue before the window and its interval reaches P (the per-cell
/// query returns a cell's first crossing only, so one at P cannot be seen),
/// and hex rays where P lies strictly inside a cell's interval: the ray
/// crosses a curved face of that cell twice and its clip interval, the hull
/// of its patch crossings, covers part of the neighbour (HexClip's
/// documented limitation); the crossing at P is then seen by both.
template <int N>
std::array<Stats, 3> measure(CellRunner const& run, CellMesh<N> const& m, int rays_per_kind, bool convex, uint64_t seed) {
  std::array<Stats, 3> sts;
  Rng rng(seed);
  Boxes<N> const boxes(m);
  Topology<N> const topo(m);
  uint64_t const nc = m.cell_count();
  glm::vec3 mlo(1e30f), mhi(-1e30f);
  for (uint64_t c = 0; c < nc; ++c) mlo = glm::min(mlo, boxes.lo[c]), mhi = glm::max(mhi, boxes.hi[c]);
  double const window = 1e-4 * glm::length(glm::dvec3(mhi - mlo));
  std::vector<uint32_t> all(nc);
  for (uint64_t c = 0; c < nc; ++c) all[c] = uint32_t(c);
  std::vector<RayQuery> rq(nc);
  std::vector<ClipOut> clip(nc);
  std::vector<IsoOut> iso(nc);
  for (int kind = 0; kind < 3; ++kind) {  // 0 face, 1 edge, 2 vertex
    Stats& st = sts[size_t(kind)];
    for (int r = 0; r < rays_per_kind; ++r) {
      glm::dvec3 target;
      double iso_value;
      aim(rng, m, topo, kind, target, iso_value);
      glm::dvec3 const d = rng.direction();
      RayQuery const q = test::to_query(target - 3.0 * d, d);
      std::fill(rq.begin(), rq.end(), q);
      run.clip(m, {all.data(), 0}, rq.data(), nc, clip.data());
      float const isof[1] = {test::rounded(iso_value)};
      run.iso(m, {all.data(), 0}, rq.data(), nc, isof, 1, {}, iso.data());
      ++st.rays;
      // Chain of intervals.
      std::vector<std::pair<float, float>> iv;
      for (uint64_t k = 0; k < nc; ++k)
        if (clip[k].hit) iv.push_back({clip[k].t_in, clip[k].t_out});
      if (iv.empty()) continue;
      std::sort(iv.begin(), iv.end());
      float reach = iv[0].second;
      float const span = iv.back().second - iv[0].first;
      for (size_t k = 1; k < iv.size(); ++k) {
        float const gap = iv[k].first - reach;
        if (gap > 0 && (convex || gap < 1e-4f * span)) ++st.chain_gaps, st.max_gap = std::max(st.max_gap, double(gap));
        // Doubly covered length (a zero-length sliver inside another interval counts as its own length).
        float const overlap = std::min(reach, iv[k].second) - iv[k].first;
        if (overlap > 0) ++st.chain_overlaps, st.max_overlap = std::max(st.max_overlap, double(overlap));
        reach = std::max(reach, iv[k].second);
      }
      // Sample points: 32 along the covered span plus the aimed-at point.
      std::vector<float> pts;
      for (int s = 0; s <= 32; ++s) {
        double const t = s == 32 ? 3.0 : iv[0].first + (span * (s + 0.5)) / 32;
        pts.insert(pts.end(),
                   {test::rounded(q.ox + t * q.dx), test::rounded(q.oy + t * q.dy), test::rounded(q.oz + t * q.dz)});
      }
      for (size_t s = 0; s < pts.size() / 3; ++s) {
        glm::vec3 const p(pts[3 * s], pts[3 * s + 1], pts[3 * s + 2]);
        std::vector<uint32_t> cand;
        for (uint64_t k = 0; k < nc; ++k)
          if (glm::all(glm::greaterThanEqual(p, boxes.lo[k])) && glm::all(glm::lessThanEqual(p, boxes.hi[k])))
            cand.push_back(uint32_t(k));
        if (cand.empty()) continue;  // outside the mesh
        std::vector<float> cp;
        for (size_t k = 0; k < cand.size(); ++k) cp.insert(cp.end(), {p.x, p.y, p.z});
        std::vector<LocateOut> lo(cand.size());
        run.locate(m, {cand.data(), 0}, cp.data(), cand.size(), lo.data());
        int inside = 0;
        for (auto const& l : lo) inside += l.inside;
        if (inside == 0) {
          // Outside every cell: a gap only if the double reference finds it inside one.
          bool in_ref = false;
          for (uint32_t k : cand) in_ref = in_ref || ref::locate(ref::load(m, k), glm::dvec3(p)).inside;
          if (!in_ref) continue;
          ++st.gaps;
          st.aimed_gaps += s == 32;
        }
        ++st.samples;
        if (inside > 1) ++st.doubles, st.aimed_doubles += s == 32;
      }
      // Iso crossings at the aimed point (see above).
      ref::Ray const rr = test::to_ref(q);
      int ref_n = 0, fast_n = 0;
      bool multi = false;
      bool hull = false;
      for (uint64_t k = 0; k < nc; ++k) {
        if (iso[k].hit && std::abs(iso[k].t - 3.0) < window) ++fast_n;
        bool const spans = clip[k].hit && clip[k].t_in <= 3.0 + window && clip[k].t_out >= 3.0 - window;
        if (spans && iso[k].hit && iso[k].t < 3.0 - window) multi = true;
        hull = hull || (clip[k].hit && clip[k].t_in < 3.0 - window && clip[k].t_out > 3.0 + window);
        ref::Cell<N> const ck = ref::load(m, k);
        ref::Clip const rc = ref::clip(ck, rr);
        if (!rc.hit || rc.t_in > 3.0 + window || rc.t_out < 3.0 - window) continue;
        std::vector<double> const x = ref::crossings(ck, rr, rc, double(isof[0]));
        if (!x.empty() && std::abs(x.front() - 3.0) < window) ++ref_n;
        for (size_t j = 1; j < x.size(); ++j) multi = multi || std::abs(x[j] - 3.0) < window;
      }
      if (hull) {
        ++st.hull;
        continue;
      }
      if (multi) {
        ++st.excluded;
        continue;
      }
      st.aimed += ref_n % 2;
      if ((ref_n - fast_n) % 2 == 0) st.tangent_pairs += std::abs(ref_n - fast_n) / 2;
      else if (fast_n < ref_n) st.lost += ref_n - fast_n;
      else st.duplicated += fast_n - ref_n;
    }
  }
  return sts;
}

void report(char const* name, CellRunner const& run, std::array<Stats, 3> const& all) {
  char const* kinds[3] = {"face", "edge", "vertex"};
  for (int k = 0; k < 3; ++k) {
  Stats const& s = all[size_t(k)];
  std::printf("watertight %-16s %-6s %-6s: %d rays, %d samples: %d gaps (%d at the aimed point), %d double (%d at the "
              "aimed point); chain: %d gaps (max %.1e), %d overlaps (max %.1e); iso at the aimed point: %d crossings, %d "
              "lost, %d duplicated, %d tangent pairs; rays excluded: %d (a cell crosses twice), %d (hull over a curved "
              "face)\n",
              name, kinds[k], run.name().c_str(), s.rays, s.samples, s.gaps, s.aimed_gaps, s.doubles, s.aimed_doubles,
              s.chain_gaps, s.max_gap, s.chain_overlaps, s.max_overlap,
              s.aimed, s.lost, s.duplicated, s.tangent_pairs, s.excluded, s.hull);
  }
}

/// What rays aimed at a hexahedral mesh's faces, edges and vertices must
/// show (see "watertight: generated tets and hexes"). `duplicates`: iso
/// crossings reported more than once, per crossing, at most (more cells
/// around a vertex allow more).
void check_hex_guarantees(std::array<Stats, 3> const& h, int duplicates = 6) {
  CHECK(h[0].lost == 0);
  CHECK(h[0].duplicated == 0);
  CHECK(h[0].aimed > 40);
  for (auto const& k : h) {
    CHECK(k.gaps == 0);
    CHECK(k.chain_gaps == 0);
    // Containment tolerance (hex_inside_tolerance) claims the aimed point,
    // on a face, edge or vertex, for several cells by design (every ray's);
    // a span sample only if it falls within 1e-5 (trilinear units) of a
    // shared face: expected ~0.1 of 1980 samples, measured 0.
    CHECK(k.doubles - k.aimed_doubles <= k.samples / 500);
    CHECK(k.lost <= k.aimed / 10);  // measured <= 2 of 41 (SSE4, edge rays)
    CHECK(k.duplicated <= duplicates * k.aimed);  // lattices: measured <= 118 of 37 (vertex rays: up to 8 cells touch the vertex)
  }
}

}  // namespace

// Guarantees by construction hold through face interiors: canonical face
// evaluation makes a cell's exit bit-identical to its neighbour's entry
// (tets: plane and face value; hexes: bilinear patch and value), so no gap,
// no overlap, and no iso crossing lost or doubled. Asserted exactly (0).
// Likewise exact: the 32 samples spread along each ray lie inside cells or
// within rounding of one face, where the half-open face rule gives the
// point to exactly one tet (hexes: see below), so no span sample is in no
// tet or in two (one within rounding of an edge would take ~1e-6 odds).
//
// Rays through edges and vertices leave one cell through one face plane or
// patch and enter the next through another (or through a cell that touches
// the ray only at that point, with an interval of rounding length): each
// plane is evaluated consistently, but different planes through one edge do
// not meet in exactly one float line. The end values of these near-zero
// intervals straddle an isovalue equal to the edge/vertex value by rounding,
// so a crossing exactly at an edge or vertex can be missed (neither cell
// sees the sign change) or reported by several cells at the same t
// (harmless for the renderer, which merges layers within 1e-5 x diagonal).
// The same holds for the aimed point itself: within rounding of the edge or
// vertex, each cell around it decides by its own planes, so it may be in no
// cell or in several -- at most one such sample per ray. These rates follow
// the kernels' rounding, which differs by ISA and compiler (g++ contracts
// a*b+c into FMA on AVX2/AVX-512: with -ffp-contract=off those give SSE4's
// counts exactly). Bounds hold for every build measured: g++ 12 (default and
// -ffp-contract=off) and clang 14, each ISA, this file alone or in the
// stage's unity TU, and with the aimed point moved exactly onto the vertex
// or edge (a stress case for rounding: far more rays double there; g++'s
// misfolding, see test::rounded, came close: 20 of 60 vertex rays doubled).
TEST_CASE("watertight: generated tets and hexes", "[cells][watertight][isa]") {
  CellRunner const run{false, test::isa()};
  auto const tets = generate_tets(3000, 3, 0.3f);
  auto const t = measure(run, tets.mesh(), 60, true, 1);
  report("generated tets", run, t);
  CHECK(t[0].gaps == 0);
  CHECK(t[0].doubles == 0);
  CHECK(t[0].chain_gaps == 0);
  CHECK(t[0].chain_overlaps == 0);
  CHECK(t[0].lost == 0);
  CHECK(t[0].duplicated == 0);
  CHECK(t[0].aimed > 40);
  for (auto const& k : t) {
    CHECK(k.gaps == k.aimed_gaps);  // span samples: exact (above)
    CHECK(k.doubles == k.aimed_doubles);
    // The aimed point at an edge or vertex: measured <= 1 gap and <= 9
    // doubles of 60 (vertex rays), and <= 7 and <= 38 with the point exactly
    // on the vertex: bounds for any rounding, still failing if most rays do.
    CHECK(k.aimed_gaps <= k.rays / 5);
    CHECK(k.aimed_doubles <= 3 * k.rays / 4);
    CHECK(k.max_gap < 1e-5);  // measured up to 2.4e-7
    CHECK(k.max_overlap < 1e-5);  // measured up to 9.5e-7
    CHECK(k.lost <= k.aimed / 4);  // measured <= 5 of 43 (SSE4, edge rays)
    CHECK(k.duplicated <= k.aimed + 10);  // measured <= 36 of 46 (vertex rays)
  }
  auto const hexes = rotated_hexes(generate_hexes(343, 3, 0.3f), 5);
  auto const h = measure(run, hexes.mesh(), 60, true, 2);
  report("generated hexes", run, h);
  check_hex_guarantees(h);
}

// Hexahedra, wedges and pyramids together, all read as collapsed hexahedra
// (mesh/vtk_cells.hpp): a quad between a hex and a wedge or a pyramid's base
// is one bilinear patch from both sides, a triangle (a face with two equal
// corners: wedge ends) one plane through its corners in ascending id order
// (cells/hex.hpp add_triangle_faces), so the guarantees of the hexes above hold
// across the types, exactly. Twice: listed as generate_hex_family lists
// them (every cell then turned by rotated_hexes, which keeps the vertex a
// wedge repeats), and with every wedge relisted from another corner, so
// that two cells repeat different vertices of their shared triangle, as
// real meshes list them. (Before triangles were crossed as planes, the
// relisted case had gaps of up to 1.4e-6 in a third of the rays: the two
// cells' patches of one triangle rounded differently.)
TEST_CASE("watertight: hexes, wedges and pyramids across their shared faces", "[cells][watertight][isa]") {
  CellRunner const run{false, test::isa()};
  auto const generated = generate_hex_family(343, 7, 0.3f);
  auto const family = rotated_hexes(generated, 8);
  auto const h = measure(run, family.mesh(), 60, false, 6);
  report("hex family", run, h);
  check_hex_guarantees(h);
  auto const relisted = rotated_hexes(rotated_wedges(generated, 9), 8);
  auto const w = measure(run, relisted.mesh(), 60, false, 6);
  report("relisted wedges", run, w);
  check_hex_guarantees(w);
}

// Cells gathered per lane (SPMD leaves, the march) clip as the packet load
// (one cell broadcast to every lane) clips them, bit for bit: entry and exit
// t, values and cell coordinates, hexahedra, wedges and pyramids alike.
// Lanes that all hold one kind of cell listed alike cross their triangles
// with the corner cycle turned once for every lane (lane_triangle_hit's
// shared pattern), lanes of mixed kinds or listings by per-lane selects:
// rays in cell order give batches of both, shuffled rays the second. On
// the hex family as generate_hex_family lists it and relisted.
TEST_CASE("hex family: cells gathered per lane clip as the packet clips them, bit for bit", "[cells][watertight][isa]") {
  CellRunner const run{false, test::isa()};
  Rng rng(31);
  auto const generated = generate_hex_family(216, 5, 0.3f);
  int compared = 0, differ = 0, hits = 0;
  for (auto const& g : {generated, rotated_hexes(rotated_wedges(generated, 4), 6)}) {
    CellMesh<8> const m = g.mesh();
    uint64_t const cells = m.cell_count();
    int const per_cell = 8;
    std::vector<RayQuery> rays;
    for (uint64_t c = 0; c < cells; ++c)
      for (int r = 0; r < per_cell; ++r) {
        glm::dvec3 target(0.0);
        double sum = 0;
        for (int k = 0; k < 8; ++k) {
          double const w = rng.uniform(0.1, 1.0);
          target += w * glm::dvec3(m.position(m.vertex(c, k))), sum += w;
        }
        glm::dvec3 const d = rng.direction(), o = target / sum - 2.0 * d;
        rays.push_back({float(o.x), float(o.y), float(o.z), float(d.x), float(d.y), float(d.z)});
      }
    uint64_t const n = rays.size();
    std::vector<ClipOut> packet(n);
    for (uint64_t c = 0; c < cells; ++c)
      run.clip(m, CellSelect{nullptr, c}, rays.data() + c * per_cell, per_cell, packet.data() + c * per_cell);
    std::vector<size_t> order(n);
    for (size_t i = 0; i < n; ++i) order[i] = i;
    for (int pass = 0; pass < 2; ++pass) {
      if (pass == 1)
        for (size_t i = n - 1; i > 0; --i) std::swap(order[i], order[size_t(rng.next() % (i + 1))]);
      std::vector<RayQuery> lane_rays(n);
      std::vector<uint32_t> ids(n);
      for (size_t i = 0; i < n; ++i) lane_rays[i] = rays[order[i]], ids[i] = uint32_t(order[i] / per_cell);
      std::vector<ClipOut> lanes(n);
      run.clip(m, CellSelect{ids.data(), 0}, lane_rays.data(), n, lanes.data());
      for (size_t i = 0; i < n; ++i) {
        ClipOut const& a = lanes[i];
        ClipOut const& b = packet[order[i]];
        ++compared;
        bool same = a.hit == b.hit;
        if (same && a.hit) {
          float const fa[10] = {a.t_in, a.t_out, a.s_in, a.s_out, a.u_in[0], a.u_in[1], a.u_in[2], a.u_out[0], a.u_out[1], a.u_out[2]};
          float const fb[10] = {b.t_in, b.t_out, b.s_in, b.s_out, b.u_in[0], b.u_in[1], b.u_in[2], b.u_out[0], b.u_out[1], b.u_out[2]};
          for (int k = 0; k < 10; ++k) same = same && fa[k] == fb[k];
          ++hits;
        }
        if (!same && differ < 5)
          std::printf("%s pass %d cell %zu: per lane hit %d t [%.9g, %.9g] u_in (%.9g %.9g %.9g), packet hit %d t [%.9g, %.9g] "
                      "u_in (%.9g %.9g %.9g)\n",
                      run.name().c_str(), pass, order[i] / per_cell, a.hit, double(a.t_in), double(a.t_out),
                      double(a.u_in[0]), double(a.u_in[1]), double(a.u_in[2]), b.hit, double(b.t_in), double(b.t_out),
                      double(b.u_in[0]), double(b.u_in[1]), double(b.u_in[2]));
        differ += int(!same);
      }
    }
  }
  std::printf("hex family per lane vs packet, %s: %d clips compared (%d hits), %d differ\n", run.name().c_str(), compared,
              hits, differ);
  CHECK(hits > compared * 95 / 100);  // rays aimed at points near each cell's centre
  CHECK(differ == 0);
}

// A triangle between a tet and a wedge's end or a pyramid's side (two scene
// parts, two kernels, as a mixed mesh renders): the ray's exit from the tet
// and its entry into the other cell are the same t and the same value, bit
// for bit, however the collapsed cell is listed (which vertex it repeats,
// which corner it starts from) and whatever the vertex ids' order, in SPMD
// and packet loads. Rays cross the triangle's interior, a quarter of them
// 1e-3 to 2e-3 (barycentric) from an edge: closer, within the hull's patch
// tolerance, the side face's crossing may come first, by design.
TEST_CASE("watertight: a triangle shared by a tet and a wedge or a pyramid", "[cells][watertight][isa]") {
  CellRunner const run{false, test::isa()};
  Rng rng(23);
  int compared = 0, differ = 0, missed = 0;
  for (int trial = 0; trial < 120; ++trial) {
    auto jitter = [&](double x, double y, double z) {
      return glm::dvec3(x, y, z) + 0.15 * rng.in_box(-1, 1);
    };
    // Shared triangle a b c in z ~ 0; the tet's apex below; above it the
    // wedge's top triangle, or the pyramid's base corners over a and b (its
    // apex is c, its base the quad a b e d).
    glm::dvec3 const corner[9] = {jitter(0, 0, 0),  jitter(1, 0, 0),  jitter(0.5, 1, 0),
                                  jitter(0.5, 0.3, -1), jitter(0, 0, 1), jitter(1, 0, 1),
                                  jitter(0, 0, 1), jitter(1, 0, 1), jitter(0.5, 1, 1)};
    enum { a, b, c, apex, d, e, a2, b2, c2 };
    // Random global ids: the canonical order must not follow the listing.
    std::array<uint32_t, 9> id{0, 1, 2, 3, 4, 5, 6, 7, 8};
    for (int i = 8; i > 0; --i) std::swap(id[size_t(i)], id[size_t(rng.next() % uint64_t(i + 1))]);
    std::vector<float> xyz(27), field(9);
    for (int k = 0; k < 9; ++k) {
      for (int j = 0; j < 3; ++j) xyz[3 * id[size_t(k)] + size_t(j)] = float(corner[k][j]);
      field[id[size_t(k)]] = float(rng.uniform(-5, 5));
    }
    std::vector<uint32_t> tet{id[a], id[b], id[c], id[apex]};
    // The wedge a b c / a2 b2 c2 from a random corner, and the pyramid with
    // its base from a random corner, both as the readers list them.
    int const turn = int(rng.next() % 3), base_turn = int(rng.next() % 4);
    int const tri[3] = {a, b, c}, top[3] = {a2, b2, c2}, quad[4] = {a, b, e, d};
    std::array<uint32_t, 6> wedge;
    for (int k = 0; k < 3; ++k) wedge[size_t(k)] = id[tri[(k + turn) % 3]], wedge[size_t(k + 3)] = id[top[(k + turn) % 3]];
    std::array<uint32_t, 5> pyramid;
    for (int k = 0; k < 4; ++k) pyramid[size_t(k)] = id[quad[(k + base_turn) % 4]];
    pyramid[4] = id[c];
    std::vector<uint32_t> collapsed;
    for (int k : wedge_as_hex) collapsed.push_back(wedge[size_t(k)]);
    for (int k : pyramid_as_hex) collapsed.push_back(pyramid[size_t(k)]);
    CellMesh<4> const tets{view(xyz), view(tet), view(field), "field"};
    CellMesh<8> const hexes{view(xyz), view(collapsed), view(field), "field"};
    std::vector<RayQuery> rays;
    for (int r = 0; r < 16; ++r) {
      double l1 = rng.uniform(), l2 = rng.uniform();
      if (l1 + l2 > 1) l1 = 1 - l1, l2 = 1 - l2;
      if (r % 4 == 0) l1 = 1e-3 * (1 + rng.uniform());  // near the edge a c
      glm::dvec3 const p = corner[a] + l1 * (corner[b] - corner[a]) + l2 * (corner[c] - corner[a]);
      glm::dvec3 const dir = glm::normalize(glm::dvec3(rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), 1));
      glm::dvec3 const o = p - 2.0 * dir;
      rays.push_back({float(o.x), float(o.y), float(o.z), float(dir.x), float(dir.y), float(dir.z)});
    }
    auto const n = uint64_t(rays.size());
    std::vector<ClipOut> out_tet(n);
    run.clip(tets, CellSelect{nullptr, 0}, rays.data(), n, out_tet.data());
    for (uint64_t cell = 0; cell < 2; ++cell) {
      std::vector<uint32_t> const ids(n, uint32_t(cell));
      for (CellSelect const sel : {CellSelect{ids.data(), 0}, CellSelect{nullptr, cell}}) {
        std::vector<ClipOut> out(n);
        run.clip(hexes, sel, rays.data(), n, out.data());
        for (uint64_t i = 0; i < n; ++i) {
          if (!out_tet[i].hit || !out[i].hit) {
            ++missed;
            continue;
          }
          ++compared;
          bool const same = out_tet[i].t_out == out[i].t_in && out_tet[i].s_out == out[i].s_in;
          if (!same && differ < 5)
            std::printf("%s trial %d %s ray %d: tet exit t %.9g s %.9g, entry t %.9g s %.9g\n", run.name().c_str(),
                        trial, cell == 0 ? "wedge" : "pyramid", int(i), double(out_tet[i].t_out), double(out_tet[i].s_out),
                        double(out[i].t_in), double(out[i].s_in));
          differ += int(!same);
        }
      }
    }
  }
  std::printf("tet | wedge or pyramid triangles, %s: %d crossings compared, %d differ, %d missed\n", run.name().c_str(),
              compared, differ, missed);
  CHECK(missed == 0);
  CHECK(compared == 120 * 16 * 4);
  CHECK(differ == 0);
}

TEST_CASE("watertight: real meshes (post.vtk tets, disk_out_ref.vtu hexes)", "[cells][watertight][isa]") {
  CellRunner const run{false, test::isa()};
  auto const post = read_mesh(test::real_file("vtk-data/post.vtk"));
  auto const t = measure(run, post.tet_mesh(), 20, false, 3);
  report("post.vtk", run, t);
  CHECK(t[0].doubles == 0);
  CHECK(t[0].chain_gaps == 0);  // holes shorter than 1e-4 x span (longer ones are the mesh's boundary)
  CHECK(t[0].chain_overlaps == 0);
  CHECK(t[0].lost == 0);
  CHECK(t[0].duplicated == 0);
  for (auto const& k : t) {
    CHECK(k.doubles == k.aimed_doubles);  // span samples: exact (see above)
    CHECK(k.gaps <= k.samples / 50);
    CHECK(k.lost <= k.aimed / 4);  // measured <= 3 of 16 (SSE4, vertex rays)
  }
  auto const disk = read_mesh(test::real_file("vtk-data/disk_out_ref.vtu"));
  auto const h = measure(run, disk.hex_mesh().with_array("Temp"), 10, false, 4);
  report("disk_out_ref.vtu", run, h);
  CHECK(h[0].lost == 0);
  CHECK(h[0].duplicated == 0);
  for (auto const& k : h) {
    CHECK(k.gaps == 0);
    CHECK(k.chain_gaps == 0);
    CHECK(k.lost <= k.aimed / 10);  // measured 0
  }
}


// The snappy flange (issue #21): hexahedra, wedges, and the pyramids and
// tets its polyhedra split into, with the tets folded into hexahedra as
// `cellray-render` keeps this mesh (one part), so every pair of types meets
// across a face somewhere. The 3,000 cells nearest the first tet cut from
// a polyhedron (brute force is quadratic in the cells), 10 of them with a
// negative Jacobian at a corner (validate's `distorted`: pyramids over
// warped faces, as snappyHexMesh left them; none inside out): the ball's own
// boundary faces are not aimed at (Topology), and holes along a ray longer
// than 1e-4 of its span are that boundary, not a crack (convex = false).
TEST_CASE("watertight: the snappy flange's hexes, wedges, pyramids and tets across their shared faces",
          "[cells][watertight][isa][data]") {
  auto const path = test::shared_data_file("openfoam/flange_snappy_89k.vtu");
  if (!path) return;
  CellRunner const run{false, test::isa()};
  UnstructuredGrid g = read_mesh(*path);
  uint64_t const first_tet = g.hex_count();  // folded tets come after the hexahedra (the file has no tets of its own)
  g.fold_tets_into_hexes();
  HexMesh const all = g.hex_mesh();
  auto const centre_of = [&](uint64_t c) {
    glm::dvec3 m(0.0);
    for (int k = 0; k < 8; ++k) m += glm::dvec3(all.position(all.vertex(c, k)));
    return m / 8.0;
  };
  glm::dvec3 const centre = centre_of(first_tet);
  std::vector<std::pair<double, uint64_t>> by_distance;
  for (uint64_t c = 0; c < all.cell_count(); ++c) by_distance.push_back({glm::length(centre_of(c) - centre), c});
  std::nth_element(by_distance.begin(), by_distance.begin() + 3000, by_distance.end());
  std::vector<uint32_t> ball;
  int kinds[4] = {0, 0, 0, 0};  // hexahedra, wedges, pyramids, tets
  for (size_t i = 0; i < 3000; ++i) {
    uint64_t const c = by_distance[i].second;
    uint32_t id[8];
    for (int k = 0; k < 8; ++k) id[k] = uint32_t(all.vertex(c, k)), ball.push_back(id[k]);
    bool const tet = id[2] == id[3] && id[4] == id[5] && id[5] == id[6] && id[6] == id[7];
    bool const pyramid = !tet && id[4] == id[5] && id[5] == id[6] && id[6] == id[7];
    bool const wedge = !tet && !pyramid && id[2] == id[3] && id[6] == id[7];
    ++kinds[tet ? 3 : pyramid ? 2 : wedge ? 1 : 0];
  }
  std::printf("flange ball: %d hexahedra, %d wedges, %d pyramids, %d tets\n", kinds[0], kinds[1], kinds[2], kinds[3]);
  for (int k : kinds) REQUIRE(k > 100);
  // The ball moved and scaled to about [-1, 1]^3, the size measure's rays
  // are made for: they start 3 units before the aimed point, and on the
  // ball's own scale float t would resolve a cell's length in a few hundred
  // steps only. The field is the generated meshes' (analytic_field): the
  // flange's temperature varies by a few ulps of its own float values across
  // some of these cells, so its rounded isovalues would put the crossing
  // anywhere along the ray -- a test of conditioning, not of the kernels.
  float const scale = float(1.0 / by_distance[3000].first);
  std::vector<float> xyz(g.xyz.size()), field(g.vertex_count());
  for (size_t i = 0; i < xyz.size(); ++i) xyz[i] = (g.xyz[i] - float(centre[int(i % 3)])) * scale;
  for (size_t v = 0; v < field.size(); ++v) field[v] = analytic_field({xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]});
  HexMesh const mesh(view(xyz), view(ball), view(field), "field");
  ValidationReport const v = validate(mesh);
  std::printf("flange ball: %llu distorted, %llu inverted, %llu zero-volume\n", (unsigned long long)v.distorted.count,
              (unsigned long long)v.inverted.count, (unsigned long long)v.zero_volume.count);
  auto const h = measure(run, mesh, 60, false, 11);
  report("snappy flange", run, h);
  // The guarantees of the generated hexahedra: through faces exactly (quads,
  // triangles and the mixed pairs, a pyramid's side against a tet's face,
  // its base against a hexahedron's, chain and cross as one surface; 52 of
  // 52 crossings), no gap anywhere (span doubles: measured <= 1 of 1,979;
  // lost: <= 1 of 54, edge rays). Up to 24 cells meet at a vertex of the
  // split polyhedra (8 in a hexahedral lattice): measured up to 324
  // duplicates of 48 crossings (SSE4 vertex rays).
  check_hex_guarantees(h, 10);
  // Overlaps are not checked: a ray that crosses a warped quad twice gets
  // the hull of its crossings (HexClip's documented limitation); here one
  // edge ray between two pyramids of one polyhedron, sharing a side, overlaps
  // by 3e-2 of the ball's radius.
}

// Two tets share the face {1, 2^31 + 1, 7}: ids whose low 31 bits are
// equal, listed in opposite order by the two cells. Ordering by 31 bits
// would tie them and let each cell keep its own order (a different anchor
// corner for the face plane); full 64-bit ordering makes both cells evaluate
// the face alike, so exit and entry agree bit for bit.
TEST_CASE("canonical face order uses all 64 bits of vertex ids", "[cells][watertight][isa]") {
  CellRunner const run{false, test::isa()};
  uint64_t const two31 = uint64_t(1) << 31, nv = two31 + 16;
  test::Reservation xyz_mem(3 * nv * sizeof(float)), val_mem(nv * sizeof(float));
  if (!xyz_mem || !val_mem) {
    WARN("cannot reserve address space for 2^31 vertices; skipped");
    return;
  }
  float* xyz = xyz_mem.as<float>();
  float* val = val_mem.as<float>();
  uint64_t const lo = 1, hi = two31 + 1, x = 7, a = 9, b = 11;
  auto put = [&](uint64_t v, glm::dvec3 const& p, double s) {
    xyz[3 * v] = float(p.x), xyz[3 * v + 1] = float(p.y), xyz[3 * v + 2] = float(p.z), val[v] = float(s);
  };
  put(lo, {0.1, 0.2, 0.0}, 0.3);
  put(hi, {1.3, 0.1, 0.1}, 0.9);
  put(x, {0.3, 1.1, 0.2}, 0.1);
  put(a, {0.4, 0.5, 1.2}, 0.7);
  put(b, {0.6, 0.3, -1.1}, 0.2);
  std::vector<uint64_t> const cells = {lo, hi, x, a, hi, lo, x, b};
  TetMesh const m{Span<float>{xyz, 3 * nv}, view(cells), Span<float>{val, nv}};
  Rng rng(5);
  int shared = 0, mismatched = 0;
  for (int i = 0; i < 200; ++i) {
    double u = rng.uniform(0.02, 0.98), v = rng.uniform(0.02, 0.98);
    if (u + v > 1) u = 1 - u, v = 1 - v;
    glm::dvec3 const p0(0.1, 0.2, 0.0), p1(1.3, 0.1, 0.1), p2(0.3, 1.1, 0.2);
    glm::dvec3 const target = p0 + u * (p1 - p0) + v * (p2 - p0);
    glm::dvec3 const d = rng.direction();
    RayQuery const q[2] = {test::to_query(target - 2.0 * d, d), test::to_query(target - 2.0 * d, d)};
    uint32_t const ids[2] = {0, 1};
    ClipOut gathered[2], broadcast[2];
    run.clip(m, {ids, 0}, q, 2, gathered);
    run.clip(m, {nullptr, 0}, &q[0], 1, &broadcast[0]);
    run.clip(m, {nullptr, 1}, &q[1], 1, &broadcast[1]);
    for (ClipOut const* c : {gathered, broadcast}) {
      if (!c[0].hit || !c[1].hit) continue;
      ++shared;
      // Whichever cell comes first along the ray, its exit is the other's entry.
      bool const a_first = c[0].t_in < c[1].t_in;
      ClipOut const& first = c[a_first ? 0 : 1];
      ClipOut const& second = c[a_first ? 1 : 0];
      mismatched += !(first.t_out == second.t_in && first.s_out == second.s_in);
    }
  }
  std::printf("64-bit ids %-6s: %d rays through the shared face, %d with exit != entry\n", run.name().c_str(), shared,
              mismatched);
  CHECK(shared > 300);
  CHECK(mismatched == 0);
}

}  // namespace test_cells_watertight
