// Hex kernels (float, every arch) against the double reference; Newton and
// iso-root behaviour on distorted hexes; degenerate input.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <cellray/mesh/generate.hpp>

#include "support/adversarial.hpp"
#include "support/cells_runner.hpp"
#include "support/sanitized.hpp"
#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_cells_hex {

using namespace cellray;
using cellray::test::CellRunner;
using cellray::test::HexKind;
using cellray::test::Rng;

namespace {

struct HexCase {
  // Fewer queries in the sanitizer build (support/sanitized.hpp): the Release
  // build runs all 3000 on every ISA; the hit-count bounds scale with it.
  static constexpr int queries = test::full_or_sanitized(3000, 1000);
  GeneratedMesh<8> g;
  test::QuerySet q;
  std::vector<glm::dvec3> params;  // true trilinear coordinates of points
  explicit HexCase(GeneratedMesh<8> mesh) : g(std::move(mesh)) {
    HexMesh const m = g.mesh();
    Rng rng(23);
    for (int i = 0; i < queries; ++i) {
      uint32_t const c = uint32_t(rng.next() % m.cell_count());
      ref::Hex const h = ref::load(m, c);
      glm::dvec3 const u = rng.in_box(0.001, 0.999);
      glm::dvec3 const target = ref::position(h, u);
      glm::dvec3 const d = rng.direction() * rng.uniform(0.5, 2);
      glm::dvec3 const o = i % 4 == 2 ? rng.in_box(-2, 2) : target - rng.uniform(-1, 3) * d;
      q.add(c, test::to_query(o, d), target);
      params.push_back(u);
    }
  }
};

/// Largest errors against the double reference (measured values where the
/// bounds are set).
struct HexBounds {
  double t, s, u, loc, g, gc, iso;
};

// Hexahedra. Float rounding through the patch quadratic (conditioning
// ~1/|discriminant| near grazing rays), Newton to ~1e-7 in uvw; gradients
// over cells of size ~0.2.
constexpr HexBounds hex_bounds{
    5e-5,  // t: measured 8.3e-6
    5e-6,  // s: measured 4.8e-7
    2e-4,  // uvw: measured 3.1e-5
    1e-6,  // locate value: measured 8.3e-8
    5e-6,  // gradient: measured 2.7e-7
    5e-4,  // central gradient: measured 8.2e-5 (h = 1e-3: rounding / h)
    5e-5,  // iso t: measured 8.2e-7 (SSE4)
};

// Pyramids, points up to 0.999 of the way to the apex. There u and v are
// undetermined (the base collapses to a point; the value is not), the
// Jacobian is singular (gradients by J^-T lose digits), and central
// differences step out of the cell (not checked: measured 0.82). Iso roots
// on a ray are in closed form (invert_pyramid): measured 4.1e-7 to 5.8e-7.
constexpr HexBounds pyramid_bounds{
    5e-5,   // t: measured 2.5e-5
    5e-5,   // s: measured 8.5e-6
    0.5,    // uvw: measured 7.9e-2, at the apex
    2e-5,   // locate value: measured 4.1e-6
    5e-3,   // gradient: measured 5.3e-4
    -1,     // central gradient: not checked
    5e-6,   // iso t
};

void check_hexes(CellRunner const& run, HexCase const& k, char const* what, HexBounds const& bound) {
  HexMesh const m = k.g.mesh();
  uint64_t const n = k.q.size();
  for (int mode = 0; mode < 2; ++mode) {  // 0: SPMD gather, 1: packet broadcast (one call per query)
    float const isos[3] = {0.3f, 0.5f, 0.42f};
    test::QueryResults const res = test::run_queries(run, m, k.q, isos, 3, 1e-3f, mode == 1);
    auto const& clip = res.clip;
    auto const& loc = res.locate;
    auto const& grad = res.gradient;
    auto const& gradc = res.gradient_central;
    auto const& iso = res.iso;
    double e_t = 0, e_s = 0, e_u = 0, e_loc = 0, e_g = 0, e_gc = 0, e_iso = 0;
    int hits = 0, hit_mismatch = 0, not_inside = 0, iso_mismatch = 0, iso_hits = 0;
    for (uint64_t i = 0; i < n; ++i) {
      ref::Hex const h = ref::load(m, k.q.cells[i]);
      ref::Ray const r = test::to_ref(k.q.rays[i]);
      ref::Clip const rc = ref::clip(h, r);
      double const dl = glm::length(r.d);
      bool const graze = std::abs(rc.t_out - rc.t_in) * dl < 1e-4;
      if (rc.hit != bool(clip[i].hit) && !graze) ++hit_mismatch;
      if (rc.hit && clip[i].hit && !graze) {
        ++hits;
        e_t = std::max({e_t, std::abs(clip[i].t_in - rc.t_in) * dl, std::abs(clip[i].t_out - rc.t_out) * dl});
        e_s = std::max({e_s, std::abs(clip[i].s_in - rc.s_in), std::abs(clip[i].s_out - rc.s_out)});
        for (int a = 0; a < 3; ++a)
          e_u = std::max({e_u, std::abs(clip[i].u_in[a] - rc.u_in[a]), std::abs(clip[i].u_out[a] - rc.u_out[a])});
      }
      glm::dvec3 const p(k.q.points[3 * i], k.q.points[3 * i + 1], k.q.points[3 * i + 2]);
      ref::Location const rl = ref::locate(h, p);
      REQUIRE(rl.inside);
      not_inside += !loc[i].inside;
      e_loc = std::max(e_loc, std::abs(loc[i].value - rl.value));
      glm::dvec3 const rg = ref::gradient(h, rl.param);
      double const gl = std::max(1.0, glm::length(rg));
      e_g = std::max(e_g, glm::length(glm::dvec3(grad[3 * i], grad[3 * i + 1], grad[3 * i + 2]) - rg) / gl);
      e_gc = std::max(e_gc, glm::length(glm::dvec3(gradc[3 * i], gradc[3 * i + 1], gradc[3 * i + 2]) - rg) / gl);
      ref::IsoRoot const ri = ref::iso_root(h, r, rc, isos, 3);
      bool near_end = graze;
      for (float v : isos) near_end = near_end || std::abs(rc.s_in - v) < 1e-5 || std::abs(rc.s_out - v) < 1e-5;
      if (ri.hit != bool(iso[i].hit) && !near_end) ++iso_mismatch;
      if (ri.hit && iso[i].hit && !near_end) {
        ++iso_hits;
        e_iso = std::max(e_iso, std::abs(iso[i].t - ri.t) * dl);
      }
      if (iso[i].hit) CHECK(!std::isnan(iso[i].t));
    }
    std::printf("%s %-6s %-6s: %d clip hits, %d iso hits; max err: t %.2e, s %.2e, uvw %.2e, locate value %.2e, "
                "grad %.2e, central grad %.2e, iso t %.2e; %d inside points not found, %d iso mismatches\n",
                what, run.name().c_str(), mode ? "packet" : "spmd", hits, iso_hits, e_t, e_s, e_u, e_loc, e_g, e_gc, e_iso,
                not_inside, iso_mismatch);
    CHECK(hits > HexCase::queries / 2);  // 1500 of 3000
    CHECK(iso_hits > HexCase::queries / 15);  // 200 of 3000
    CHECK(hit_mismatch == 0);
    CHECK(not_inside == 0);
    CHECK(iso_mismatch == 0);
    CHECK(e_t < bound.t);
    CHECK(e_s < bound.s);
    CHECK(e_u < bound.u);
    CHECK(e_loc < bound.loc);
    CHECK(e_g < bound.g);
    if (bound.gc > 0) CHECK(e_gc < bound.gc);
    CHECK(e_iso < bound.iso);
  }
}

HexCase const& hex_case() {
  static HexCase const k(generate_hexes(1000, 5, 0.3f));
  return k;
}

// Pyramids as the readers store them (corners 4-7 the apex): points up to
// 0.999 of the way to the apex, where Newton converges slowly; the
// inversions on a ray (iso roots) are in closed form (invert_pyramid).
HexCase const& pyramid_case() {
  static HexCase const k(generate_pyramids(1000, 5, 0.3f));
  return k;
}

}  // namespace

TEST_CASE("hex kernels, scalar arch, match the double reference", "[cells][hex]") {
  check_hexes(CellRunner{}, hex_case(), "hex", hex_bounds);
}

TEST_CASE("hex kernels match the double reference", "[cells][hex][isa]") {
  check_hexes(CellRunner{false, test::isa()}, hex_case(), "hex", hex_bounds);
}

TEST_CASE("pyramid kernels, scalar arch, match the double reference", "[cells][hex]") {
  check_hexes(CellRunner{}, pyramid_case(), "pyramid", pyramid_bounds);
}

TEST_CASE("pyramid kernels match the double reference", "[cells][hex][isa]") {
  check_hexes(CellRunner{false, test::isa()}, pyramid_case(), "pyramid", pyramid_bounds);
}

TEST_CASE("distorted hexes: Newton convergence and iso roots (exact vs Neubauer 1/2/4)", "[cells][hex][isa]") {
  CellRunner const run{false, test::isa()};
  HexKind const kinds[] = {HexKind::parallelepiped, HexKind::jittered, HexKind::twisted,
                           HexKind::nearly_flat,    HexKind::non_planar, HexKind::inverted};
  for (HexKind kind : kinds) {
    Rng rng(100 + int(kind));
    int const cells = 40, per_cell = 30;
    test::OwnedMesh<8> om;
    std::vector<uint32_t> ids;
    std::vector<float> pts;
    std::vector<RayQuery> rays;
    std::vector<float> isov;  // one isovalue per ray
    for (int c = 0; c < cells; ++c) {
      glm::dvec3 p[8];
      test::distorted_hex(rng, kind, p);
      double s[8];
      for (double& v : s) v = rng.uniform();
      int const perm[8] = {3, 6, 0, 5, 7, 1, 4, 2};
      om.add_cell(p, s, perm);
    }
    HexMesh const m = om.mesh();
    for (int c = 0; c < cells; ++c) {
      ref::Hex const h = ref::load(m, uint64_t(c));
      for (int j = 0; j < per_cell; ++j) {
        glm::dvec3 const u = rng.in_box(0.001, 0.999);
        glm::dvec3 const x = ref::position(h, u);
        glm::dvec3 const d = rng.direction();
        ids.push_back(uint32_t(c));
        pts.insert(pts.end(), {float(x.x), float(x.y), float(x.z)});
        RayQuery const q = test::to_query(x - 3.0 * glm::length(h.p[6] - h.p[0]) * d, d);
        rays.push_back(q);
        // Half the isovalues near the field's extreme along the ray: pairs of
        // close crossings (double roots, grazing hits of the surface).
        ref::Ray const r = test::to_ref(q);
        ref::Clip const rc = ref::clip(h, r);
        double iso = rng.uniform();
        if (j % 2 == 1 && rc.hit) {
          double best = -1;
          glm::dvec3 w = rc.u_in;
          for (int k = 1; k < 32; ++k) best = std::max(best, ref::value_on_ray(h, r, rc.t_in + (rc.t_out - rc.t_in) * k / 32, w));
          iso = best - std::pow(10.0, rng.uniform(-4, -1)) * std::abs(best);
        }
        isov.push_back(float(iso));
      }
    }
    uint64_t const n = ids.size();
    std::vector<LocateOut> loc(n);
    run.locate(m, {ids.data(), 0}, pts.data(), n, loc.data());
    int noconv = 0, lost = 0;
    double e_val = 0;
    for (uint64_t i = 0; i < n; ++i) {
      noconv += !loc[i].converged;
      lost += !loc[i].inside;
      if (loc[i].converged) {
        ref::Location const rl = ref::locate(ref::load(m, ids[i]), glm::dvec3(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]));
        e_val = std::max(e_val, std::abs(loc[i].value - rl.value));
      }
    }
    // Iso: one ray and isovalue per entry, per method.
    int ref_hits = 0, exact_miss = 0, exact_extra = 0, exact_far = 0;
    int neu_miss[3] = {}, neu_far[3] = {};
    double e_exact = 0;
    for (uint64_t i = 0; i < n; ++i) {
      CellSelect const sel{&ids[i], 0};
      IsoOut ex, nb[3];
      run.iso(m, sel, &rays[i], 1, &isov[i], 1, {}, &ex);
      int const steps[3] = {1, 2, 4};
      for (int s = 0; s < 3; ++s) run.iso(m, sel, &rays[i], 1, &isov[i], 1, {CellIsoMethod::neubauer, steps[s], 0}, &nb[s]);
      ref::Hex const h = ref::load(m, ids[i]);
      ref::Ray const r = test::to_ref(rays[i]);
      ref::Clip const rc = ref::clip(h, r);
      std::vector<double> const x = ref::crossings(h, r, rc, isov[i]);
      double const size = glm::length(h.p[6] - h.p[0]);
      double const tol = 1e-3 * size;  // "found the same crossing"
      if (ex.hit) CHECK(!std::isnan(ex.t));
      if (x.empty()) {
        exact_extra += ex.hit;
        continue;
      }
      ++ref_hits;
      if (!ex.hit) ++exact_miss;
      else if (std::abs(ex.t - x.front()) > tol) ++exact_far;
      else e_exact = std::max(e_exact, std::abs(ex.t - x.front()) / size);
      for (int s = 0; s < 3; ++s) {
        if (!nb[s].hit) ++neu_miss[s];
        else if (std::abs(nb[s].t - x.front()) > tol) ++neu_far[s];
      }
    }
    auto pct = [&](int a, int b) { return b ? 100.0 * a / b : 0.0; };
    std::printf("%-6s %-14s: Newton %5.2f%% not converged, %5.2f%% inside points lost, value err %.1e | %d ref iso "
                "hits: exact %5.2f%% missed %5.2f%% off (>1e-3 size) %d extra, err %.1e | Neubauer missed/off: "
                "N=1 %5.2f%%/%5.2f%% N=2 %5.2f%%/%5.2f%% N=4 %5.2f%%/%5.2f%%\n",
                run.name().c_str(), test::hex_kind_name(kind), pct(noconv, int(n)), pct(lost, int(n)), e_val, ref_hits,
                pct(exact_miss, ref_hits), pct(exact_far, ref_hits), exact_extra, e_exact, pct(neu_miss[0], ref_hits),
                pct(neu_far[0], ref_hits), pct(neu_miss[1], ref_hits), pct(neu_far[1], ref_hits),
                pct(neu_miss[2], ref_hits), pct(neu_far[2], ref_hits));
    CHECK(ref_hits > 300);
    // Measured 0 to 3.5% (pairs of crossings closer than float resolves).
    CHECK(exact_miss + exact_far <= ref_hits / 20);
    if (kind == HexKind::parallelepiped) {
      // The cubic is exact here: only pairs of crossings within float
      // rounding of a double root may be missed.
      CHECK(exact_miss + exact_far <= ref_hits / 100);
      CHECK(noconv == 0);
    }
    if (kind != HexKind::nearly_flat) CHECK(lost <= int(n) / 100);
    // Never worse than Neubauer at finding crossings.
    CHECK(exact_miss <= neu_miss[1]);
  }
}

namespace {
test::OwnedMesh<8> one_hex(glm::dvec3 const (&p)[8], double const (&s)[8]) {
  test::OwnedMesh<8> m;
  int const perm[8] = {5, 2, 7, 0, 3, 6, 1, 4};
  m.add_cell(p, s, perm);
  return m;
}
}  // namespace

TEST_CASE("hex degenerate input has documented outcomes", "[cells][hex][isa]") {
  CellRunner const run{false, test::isa()};
  glm::dvec3 cube[8];
  for (int i = 0; i < 8; ++i) cube[i] = test::unit_corner(i);
  double const sz[8] = {0, 0, 0, 0, 1, 1, 1, 1};  // s = w = z
  float const half[1] = {0.5f};
  SECTION("flat hex: no clip interval, no containment, no iso hit, finite output") {
    glm::dvec3 flat[8];
    for (int i = 0; i < 8; ++i) flat[i] = {cube[i].x, cube[i].y, 0.0};
    auto const o = one_hex(flat, sz);
    RayQuery const r = test::to_query({0.3, 0.4, -1}, {0, 0, 1});
    ClipOut c;
    run.clip(o.mesh(), {}, &r, 1, &c);
    CHECK(c.hit == 0);
    float const p[3] = {0.3f, 0.4f, 0.f};
    LocateOut l;
    run.locate(o.mesh(), {}, p, 1, &l);
    CHECK(l.inside == 0);
    CHECK(l.converged == 0);
    IsoOut h;
    run.iso(o.mesh(), {}, &r, 1, half, 1, {}, &h);
    CHECK(h.hit == 0);
    float g[3];
    run.gradient(o.mesh(), {}, p, 1, GradientMethod::analytic, 0.f, g);
    CHECK((std::isfinite(g[0]) && std::isfinite(g[1]) && std::isfinite(g[2])));
  }
  SECTION("inverted (mirrored) hex works like its mirror image") {
    glm::dvec3 inv[8];
    for (int i = 0; i < 8; ++i) inv[i] = {-cube[i].x, cube[i].y, cube[i].z};
    auto const o = one_hex(inv, sz);
    RayQuery const r = test::to_query({-0.3, 0.4, -1}, {0, 0, 1});
    IsoOut h;
    run.iso(o.mesh(), {}, &r, 1, half, 1, {}, &h);
    CHECK(h.hit == 1);
    CHECK(h.t == Approx(1.5).margin(1e-5));
    float const p[3] = {-0.3f, 0.4f, 0.6f};
    LocateOut l;
    run.locate(o.mesh(), {}, p, 1, &l);
    CHECK(l.inside == 1);
    CHECK(l.value == Approx(0.6).margin(1e-5));
  }
  SECTION("rays parallel to faces, iso at vertex values, constant and NaN cells") {
    auto const o = one_hex(cube, sz);
    RayQuery const rays[3] = {test::to_query({-1, 0.5, 0.25}, {1, 0, 0}),   // parallel to z faces
                              test::to_query({-1, 0.5, 1.5}, {1, 0, 0}),    // parallel, outside
                              test::to_query({-1, 0.5, 1.0}, {1, 0, 0})};   // in the top face plane
    ClipOut c[3];
    run.clip(o.mesh(), {}, rays, 3, c);
    CHECK(c[0].hit == 1);
    CHECK(c[0].t_in == Approx(1.0).margin(1e-5));
    CHECK(c[0].t_out == Approx(2.0).margin(1e-5));
    CHECK(c[0].s_in == Approx(0.25).margin(1e-5));
    CHECK(c[1].hit == 0);
    CHECK(c[2].hit == 1);  // the side patches' edges, within the patch tolerance
    RayQuery const up = test::to_query({0.3, 0.4, -1}, {0, 0, 1});
    float const at_vertex[2] = {0.f, 1.f};  // the values of the bottom and top corners
    IsoOut h;
    run.iso(o.mesh(), {}, &up, 1, at_vertex, 2, {}, &h);
    // s >= iso at both ends for 0 (belongs to the cell below) and s reaches 1
    // exactly at the exit: one crossing, at the exit face, for iso 1.
    CHECK(h.hit == 1);
    CHECK(h.index == 1);
    CHECK(h.t == Approx(2.0).margin(1e-5));
    double const flat_s[8] = {0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5};
    auto const k = one_hex(cube, flat_s);
    run.iso(k.mesh(), {}, &up, 1, half, 1, {}, &h);
    CHECK(h.hit == 0);
    double const nan_s[8] = {0, 0, 0, test::nanf, 1, 1, 1, 1};
    auto const q = one_hex(cube, nan_s);
    run.iso(q.mesh(), {}, &up, 1, half, 1, {}, &h);
    CHECK(h.hit == 0);
    CHECK(std::isinf(h.t));
    run.iso(q.mesh(), {}, &up, 1, half, 1, {CellIsoMethod::neubauer, 2, 0}, &h);
    CHECK(h.hit == 0);
  }
}

}  // namespace test_cells_hex

// The reference renderer's view of a cell along a ray (ref::FieldOnRay, in
// cells/reference.hpp since the renderer stopped branching on the type):
// its crossings against the independent 512-step oracle, and its values and
// control-value cuts against exact point location.
namespace test_cells_hex {
TEST_CASE("ref::FieldOnRay: hex crossings agree with the 512-step oracle, cuts and values with locate",
          "[cells][hex][reference]") {
  GeneratedMesh<8> const g = generate_hex_family(600, 7, 0.35f);  // hexes, wedges, pyramids
  HexMesh const m = g.mesh();
  test::Rng rng(41);
  int crossings = 0, extra = 0, cuts = 0;
  for (int i = 0; i < 400; ++i) {
    uint64_t const c = rng.next() % m.cell_count();
    ref::Hex const h = ref::load(m, c);
    glm::dvec3 const target = ref::position(h, rng.in_box(0.05, 0.95));
    glm::dvec3 const d = rng.direction();
    ref::Ray const r{target - 2.0 * d, d};
    ref::FieldOnRay<8> const f(h, r, 64);
    ref::Clip const& k = f.clip();
    REQUIRE(k.hit);
    double const size = glm::length(h.p[6] - h.p[0]);
    double lo = h.s[0], hi = h.s[0];
    for (double s : h.s) lo = std::min(lo, s), hi = std::max(hi, s);
    double const iso = ref::locate(h, target).value;  // crossed at the target, at least
    std::vector<double> xs;
    f.crossings(iso, xs);
    std::vector<double> const oracle = ref::crossings(h, r, k, iso);
    // Every crossing the oracle finds, FieldOnRay finds at the same t; what
    // it finds beyond (a root pair inside one oracle step) is a true root.
    for (double t : oracle) {
      bool const found = std::any_of(xs.begin(), xs.end(), [&](double x) { return std::abs(x - t) <= 1e-9 * size; });
      CHECK(found);
      crossings += found;
    }
    extra += int(xs.size()) - int(oracle.size());
    CHECK(xs.size() >= oracle.size());
    for (double x : xs) {
      double v = 0;
      REQUIRE(f.at(x, v, nullptr));
      CHECK(std::abs(v - iso) <= 1e-9 * (hi - lo));
    }
    // Values and gradients at t: exact location's.
    double const t = 0.5 * (k.t_in + k.t_out);
    double v = 0;
    glm::dvec3 grad;
    REQUIRE(f.at(t, v, &grad));
    ref::Location const at = ref::locate(h, r.o + t * r.d);
    CHECK(std::abs(v - at.value) <= 1e-10 * (hi - lo + 1));
    CHECK(glm::length(grad - ref::gradient(h, at.param)) <= 1e-8 * (glm::length(grad) + 1));
    CHECK(glm::length(f.gradient_at(t) - grad) <= 1e-8 * (glm::length(grad) + 1));
    // Control-value cuts inside the clip: the field there is the control value.
    std::vector<float> const controls = {float(lo + 0.25 * (hi - lo)), float(iso), float(lo + 0.75 * (hi - lo))};
    std::vector<double> cut;
    f.cuts(k.t_in, k.t_out, controls, cut);
    for (double x : cut) {
      CHECK(x > k.t_in);
      CHECK(x < k.t_out);
      REQUIRE(f.at(x, v, nullptr));
      double nearest = std::abs(v - controls[0]);
      for (float cv : controls) nearest = std::min(nearest, std::abs(v - cv));
      CHECK(nearest <= 1e-9 * (hi - lo));
      ++cuts;
    }
  }
  // The rays go through an iso crossing each: nearly all are found.
  CHECK(crossings >= 380);
  CHECK(cuts >= 380);
  INFO("root pairs found beyond the oracle: " << extra);
}

TEST_CASE("ref::FieldOnRay: a tet's field along a ray is its clip's line, exactly", "[cells][tet][reference]") {
  GeneratedMesh<4> const g = generate_tets(600, 5, 0.3f);
  TetMesh const m = g.mesh();
  test::Rng rng(43);
  for (int i = 0; i < 200; ++i) {
    ref::Tet const c = ref::load(m, rng.next() % m.cell_count());
    glm::dvec3 const target = 0.25 * (c.p[0] + c.p[1] + c.p[2] + c.p[3]);
    glm::dvec3 const d = rng.direction();
    ref::Ray const r{target - d, d};
    ref::FieldOnRay<4> const f(c, r);
    ref::Clip const& k = f.clip();
    REQUIRE(k.hit);
    double const t = k.t_in + 0.3 * (k.t_out - k.t_in);
    double v = 0;
    glm::dvec3 grad;
    REQUIRE(f.at(t, v, &grad));
    double const spread = std::abs(k.s_out - k.s_in) + 1;
    CHECK(std::abs(v - ref::locate(c, r.o + t * r.d).value) <= 1e-9 * spread);
    CHECK(glm::length(grad - ref::gradient(c)) == 0.0);
    float const mid = float(0.5 * (k.s_in + k.s_out));
    std::vector<double> cut, xs;
    f.cuts(k.t_in, k.t_out, {mid}, cut);
    f.crossings(double(mid), xs);
    if (double(mid) > std::min(k.s_in, k.s_out) && double(mid) < std::max(k.s_in, k.s_out)) {
      REQUIRE(cut.size() == 1);
      REQUIRE(xs.size() == 1);
      CHECK(std::abs(cut[0] - xs[0]) <= 1e-9 * (k.t_out - k.t_in));
    }
  }
}
}  // namespace test_cells_hex
