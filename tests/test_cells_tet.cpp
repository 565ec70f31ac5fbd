// Tet kernels (float, every arch) against the double reference, and their
// documented outcomes on degenerate input.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <cellray/mesh/generate.hpp>

#include "support/adversarial.hpp"
#include "support/cells_runner.hpp"
#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_cells_tet {

using namespace cellray;
using cellray::test::CellRunner;
using cellray::test::Rng;

namespace {

/// Rays aimed at random points of random cells of a generated tet mesh
/// (3/4 of them), and random lines (mostly misses).
struct TetCase {
  GeneratedMesh<4> g = generate_tets(3000, 7, 0.3f);
  test::QuerySet q;  // points: random points in (or, for 1/4, near) the cell
  TetCase() {
    TetMesh const m = g.mesh();
    Rng rng(11);
    for (int i = 0; i < 4000; ++i) {
      uint32_t const c = uint32_t(rng.next() % m.cell_count());
      ref::Tet const t = ref::load(m, c);
      double w[4], sum = 0;
      for (double& x : w) sum += (x = -std::log(1 - rng.uniform()));
      glm::dvec3 target(0);
      for (int k = 0; k < 4; ++k) target += (w[k] / sum) * t.p[k];
      if (i % 4 == 3) target += 0.05 * rng.in_box(-1, 1);
      glm::dvec3 const d = rng.direction() * rng.uniform(0.5, 2);
      glm::dvec3 const o = i % 4 == 2 ? rng.in_box(-2, 2) : target - rng.uniform(-1, 3) * d;
      q.add(c, test::to_query(o, d), target);
    }
  }
};

void check_tets(CellRunner const& run) {
  static TetCase const k;
  TetMesh const m = k.g.mesh();
  uint64_t const n = k.q.size();
  for (int mode = 0; mode < 2; ++mode) {  // 0: SPMD gather, 1: packet broadcast (one call per query)
    float const isos[3] = {0.3f, 0.5f, 0.42f};
    test::QueryResults const res = test::run_queries(run, m, k.q, isos, 3, 1e-2f, mode == 1);
    auto const& clip = res.clip;
    auto const& loc = res.locate;
    auto const& grad = res.gradient;
    auto const& gradc = res.gradient_central;
    auto const& iso = res.iso;
    auto const& neu = res.neubauer;
    double e_t = 0, e_s = 0, e_loc = 0, e_g = 0, e_gc = 0, e_iso = 0, e_neu = 0;
    int hits = 0, grazing = 0, hit_mismatch = 0, loc_mismatch = 0, iso_mismatch = 0, iso_hits = 0;
    for (uint64_t i = 0; i < n; ++i) {
      ref::Tet const t = ref::load(m, k.q.cells[i]);
      ref::Ray const r = test::to_ref(k.q.rays[i]);
      ref::Clip const rc = ref::clip(t, r);
      double const dl = glm::length(r.d);
      // Grazing: the interval (or its length) is within float rounding of
      // empty, where hit/miss is legitimately decided either way.
      bool const graze = std::abs(rc.t_out - rc.t_in) * dl < 1e-5;
      grazing += graze;
      if (rc.hit != bool(clip[i].hit) && !graze) ++hit_mismatch;
      if (rc.hit && clip[i].hit && !graze) {
        ++hits;
        e_t = std::max({e_t, std::abs(clip[i].t_in - rc.t_in) * dl, std::abs(clip[i].t_out - rc.t_out) * dl});
        e_s = std::max({e_s, std::abs(clip[i].s_in - rc.s_in), std::abs(clip[i].s_out - rc.s_out)});
      }
      glm::dvec3 const p(k.q.points[3 * i], k.q.points[3 * i + 1], k.q.points[3 * i + 2]);
      ref::Location const rl = ref::locate(t, p);
      double const margin = std::min({rl.param.x, rl.param.y, rl.param.z, 1 - rl.param.x - rl.param.y - rl.param.z});
      if (rl.inside != bool(loc[i].inside) && std::abs(margin) > 1e-5) ++loc_mismatch;
      e_loc = std::max(e_loc, std::abs(loc[i].value - rl.value));
      glm::dvec3 const rg = ref::gradient(t);
      double const gl = std::max(1.0, glm::length(rg));
      e_g = std::max(e_g, glm::length(glm::dvec3(grad[3 * i], grad[3 * i + 1], grad[3 * i + 2]) - rg) / gl);
      e_gc = std::max(e_gc, glm::length(glm::dvec3(gradc[3 * i], gradc[3 * i + 1], gradc[3 * i + 2]) - rg) / gl);
      ref::IsoRoot const ri = ref::iso_root(t, r, rc, isos, 3);
      // An isovalue within rounding of an end value may be decided either way.
      bool near_end = graze;
      for (float v : isos) near_end = near_end || std::abs(rc.s_in - v) < 1e-5 || std::abs(rc.s_out - v) < 1e-5;
      if (ri.hit != bool(iso[i].hit) && !near_end) ++iso_mismatch;
      if (ri.hit && iso[i].hit && !near_end) {
        ++iso_hits;
        e_iso = std::max(e_iso, std::abs(iso[i].t - ri.t) * dl);
        e_neu = std::max(e_neu, std::abs(neu[i].t - ri.t) * dl);
        CHECK(iso[i].index == ri.index);
      }
      CHECK(bool(iso[i].hit) == bool(neu[i].hit));
      if (iso[i].hit) CHECK(!std::isnan(iso[i].t));
    }
    std::printf("tet %-6s %-6s: %d clip hits (%d grazing skipped), %d iso hits; max err: t %.2e, s %.2e, "
                "locate value %.2e, grad %.2e, central grad %.2e, iso t %.2e, neubauer(2) t %.2e\n",
                run.name().c_str(), mode ? "packet" : "spmd", hits, grazing, iso_hits, e_t, e_s, e_loc, e_g, e_gc,
                e_iso, e_neu);
    CHECK(hits > 2000);
    CHECK(iso_hits > 300);
    CHECK(hit_mismatch == 0);
    CHECK(loc_mismatch == 0);
    CHECK(iso_mismatch == 0);
    // Bounds: coordinates up to ~5 from the ray origin in float (eps 6e-8)
    // through a few dot/cross products; values and gradients of O(1) fields
    // over cells of size ~0.1 (gradient error grows as 1/size).
    CHECK(e_t < 1e-5);  // measured 3.5e-6
    CHECK(e_s < 5e-6);  // measured 1.0e-6
    CHECK(e_loc < 1e-6);  // measured 2.3e-7
    CHECK(e_g < 1e-5);  // measured 1.3e-6
    CHECK(e_gc < 5e-5);  // measured 1.1e-5
    CHECK(e_iso < 5e-6);  // measured 1.0e-6
    CHECK(e_neu < 5e-6);  // measured 9.0e-7
  }
}

}  // namespace

TEST_CASE("tet kernels, scalar arch, match the double reference", "[cells][tet]") { check_tets(CellRunner{}); }

TEST_CASE("tet kernels match the double reference", "[cells][tet][isa]") {
  check_tets(CellRunner{false, test::isa()});
}

namespace {

test::OwnedMesh<4> one_tet(glm::dvec3 const (&p)[4], double const (&s)[4]) {
  test::OwnedMesh<4> m;
  int const perm[4] = {2, 0, 3, 1};  // ids not in corner order
  m.add_cell(p, s, perm);
  return m;
}

}  // namespace

TEST_CASE("tet degenerate input has documented outcomes", "[cells][tet][isa]") {
  CellRunner const run{false, test::isa()};
  glm::dvec3 const good[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  float const iso[1] = {0.5f};
  SECTION("zero-volume tet: no clip interval, contains nothing, zero gradient, no iso hit") {
    glm::dvec3 const flat[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.3, 0}};
    auto const o = one_tet(flat, {0, 1, 0, 1});
    RayQuery const r = test::to_query({0.2, 0.2, -1}, {0, 0, 1});
    ClipOut c;
    run.clip(o.mesh(), {}, &r, 1, &c);
    CHECK(c.hit == 0);
    float const p[3] = {0.2f, 0.2f, 0.f};
    LocateOut l;
    run.locate(o.mesh(), {}, p, 1, &l);
    CHECK(l.inside == 0);
    float g[3];
    run.gradient(o.mesh(), {}, p, 1, GradientMethod::analytic, 0.f, g);
    CHECK((g[0] == 0 && g[1] == 0 && g[2] == 0));
    IsoOut h;
    run.iso(o.mesh(), {}, &r, 1, iso, 1, {}, &h);
    CHECK(h.hit == 0);
  }
  SECTION("ray parallel to a face: inside the face's plane slab it clips, outside it misses") {
    auto const o = one_tet(good, {0, 1, 0, 0});
    RayQuery const rays[3] = {test::to_query({-1, 0.2, 0.2}, {1, 0, 0}),    // parallel to x=0? no: to y=0 and z=0
                              test::to_query({-1, -0.1, 0.2}, {1, 0, 0}),   // below y = 0: misses
                              test::to_query({-1, 0, 0.2}, {1, 0, 0})};     // in the plane y = 0
    ClipOut c[3];
    run.clip(o.mesh(), {}, rays, 3, c);
    CHECK(c[0].hit == 1);
    CHECK(c[0].t_in == Approx(1.0).margin(1e-6));
    CHECK(c[0].t_out == Approx(1.6).margin(1e-6));
    CHECK(c[1].hit == 0);
    CHECK(c[2].hit == 1);  // the half-open face rule keeps the closed face for clipping
    CHECK(c[2].t_out == Approx(1.8).margin(1e-6));
  }
  SECTION("isovalue equal to a vertex value, constant cells, NaN values") {
    RayQuery const r = test::to_query({0.1, 0.1, -1}, {0, 0, 1});  // from s=0.2 at z=0 to s=0.8+ inside
    {
      auto const o = one_tet(good, {0, 0, 0, 1});  // s = z
      float const at_vertex[1] = {1.f};             // only the apex (not on the ray)
      float const at_entry[1] = {0.f};              // the entry face value
      IsoOut h;
      run.iso(o.mesh(), {}, &r, 1, at_vertex, 1, {}, &h);
      CHECK(h.hit == 0);
      run.iso(o.mesh(), {}, &r, 1, at_entry, 1, {}, &h);
      CHECK(h.hit == 0);  // s >= iso at both ends: the crossing belongs to the previous cell
      float const mid[1] = {0.5f};
      run.iso(o.mesh(), {}, &r, 1, mid, 1, {}, &h);
      CHECK(h.hit == 1);
      CHECK(h.t == Approx(1.5).margin(1e-6));
    }
    {
      auto const o = one_tet(good, {0.5, 0.5, 0.5, 0.5});
      IsoOut h;
      run.iso(o.mesh(), {}, &r, 1, iso, 1, {}, &h);
      CHECK(h.hit == 0);  // constant cell equal to the isovalue: no surface
      float g[3];
      float const p[3] = {0.1f, 0.1f, 0.1f};
      run.gradient(o.mesh(), {}, p, 1, GradientMethod::analytic, 0.f, g);
      CHECK((g[0] == 0 && g[1] == 0 && g[2] == 0));
    }
    {
      auto const o = one_tet(good, {0, test::nanf, 1, 0});
      IsoOut h;
      run.iso(o.mesh(), {}, &r, 1, iso, 1, {}, &h);
      CHECK(h.hit == 0);  // NaN cells are invisible
      CHECK(std::isinf(h.t));
      LocateOut l;
      float const p[3] = {0.1f, 0.1f, 0.1f};
      run.locate(o.mesh(), {}, p, 1, &l);
      CHECK(l.inside == 1);  // geometry is fine; the value says NaN
      CHECK(std::isnan(l.value));
    }
  }
}

TEST_CASE("shading normal points from high to low values and never NaN", "[cells]") {
  using V = Vec3<scalar>;
  V const n = shading_normal<scalar>(V{0.f, 2.f, 0.f}, V{1.f, 0.f, 0.f});
  CHECK(n.y == Approx(-1.f));
  V const z = shading_normal<scalar>(V{0.f, 0.f, 0.f}, V{0.f, 0.f, 2.f});
  CHECK(z.z == Approx(-1.f));
  V const q = shading_normal<scalar>(V{test::nanf, 0.f, 0.f}, V{0.f, 3.f, 0.f});
  CHECK(q.y == Approx(-1.f));
  V const f = face_forward<scalar>(V{0.f, 0.f, 1.f}, V{0.f, 0.f, 1.f});
  CHECK(f.z == -1.f);
}

}  // namespace test_cells_tet
