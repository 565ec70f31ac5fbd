// The cell-segment query of DVR (traverse/segments.hpp) against a brute
// force double-precision oracle: every cell of the mesh clipped by
// cells/reference.hpp. Packet leaves clip broadcast cells, SPMD leaves one
// cell per lane; all three traversals must give the same lists bit for bit
// (a packet leaf that clips (cell, lane) pairs W at a time, as tried in
// session 6, must too). Jittered and
// regular lattices, rays along shared edges and in shared faces, windows
// ending inside the mesh, NaN cells, lists that overflow test::probe_max_segments.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>
#include <random>
#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/reference.hpp>
#include <cellray/mesh/generate.hpp>

#include "support/ray_sets.hpp"
#include "support/segment_probe.hpp"
#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_traverse_segment_query {

using namespace cellray;
using test::lattice_rays;
using test::random_rays;
using test::union_length;
using test::SegmentProbeOut;

namespace {

struct RefSegment {
  double t_in, t_out, s_in, s_out;
  uint64_t cell;
};

/// Every cell the ray's line crosses within [tmin, tmax] (the query's window
/// rule: t_out >= tmin and t_in <= tmax), NaN cells excluded, sorted by t_in.
std::vector<RefSegment> reference_segments(TetMesh const& mesh, Ray const& r) {
  ref::Ray const rr{glm::dvec3(r.org), glm::dvec3(r.dir)};
  std::vector<RefSegment> out;
  for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
    ref::Tet const t = ref::load(mesh, c);
    if (ref::has_nan(t)) continue;
    ref::Clip const k = ref::clip(t, rr);
    if (!k.hit || k.t_out < double(r.tmin) || k.t_in > double(r.tmax)) continue;
    out.push_back({k.t_in, k.t_out, k.s_in, k.s_out, c});
  }
  std::sort(out.begin(), out.end(), [](auto const& a, auto const& b) { return a.t_in < b.t_in; });
  return out;
}

std::vector<SegmentProbeOut> probe(TetMesh const& mesh, MinMaxBvh const& bvh, ValueWindows const& w,
                                   std::vector<Ray> const& rays, int how, bool gradients = false) {
  std::vector<SegmentProbeOut> out(rays.size());
  dispatch<test::SegmentProbe>(test::isa(), mesh, bvh, w, rays.data(), int(rays.size()), how, gradients, out.data());
  return out;
}

bool same_lists(SegmentProbeOut const& a, SegmentProbeOut const& b) {
  if (a.count != b.count || std::memcmp(&a.cut, &b.cut, sizeof(float)) != 0) return false;
  for (int i = 0; i < a.count; ++i) {
    CellSegment const &x = a.seg[i], &y = b.seg[i];
    if (x.cell != y.cell || std::memcmp(&x.t_in, &y.t_in, 4) || std::memcmp(&x.t_out, &y.t_out, 4) ||
        std::memcmp(&x.v_in, &y.v_in, 4) || std::memcmp(&x.v_out, &y.v_out, 4) ||
        std::memcmp(a.value[i], b.value[i], sizeof a.value[i]) || std::memcmp(a.gradient[i], b.gradient[i], sizeof a.gradient[i]))
      return false;
  }
  return true;
}

/// Checks one ray's list against the oracle. Tolerances: positions and t are
/// O(1) here and the float clip's plane distances err by a few ulps of that,
/// i.e. ~1e-6; 1e-4 leaves room for rays at a shallow angle to a face, whose
/// crossing t moves by (error / sin angle). Checked:
/// * every query segment is its cell's crossing (t and values); on rays
///   along edges or in faces (`generic` false) a cell the oracle puts the
///   ray just outside of may be reported too, with a crossing no longer than
///   `tiny`, or lying inside the union below (DVR integrates the union);
/// * the union of the query's segments over the window, up to the cut,
///   covers what the oracle's covers (no gap: DVR would skip it);
/// * generic rays: every oracle crossing longer than `tiny` is listed.
void check_ray(TetMesh const& mesh, Ray const& r, SegmentProbeOut const& q, bool generic) {
  double const tol = 1e-4, tiny = 1e-3;
  std::vector<RefSegment> const ref = reference_segments(mesh, r);
  INFO("ray org " << r.org.x << "," << r.org.y << "," << r.org.z << " dir " << r.dir.x << "," << r.dir.y << ","
                  << r.dir.z << " window " << r.tmin << ".." << r.tmax << ": " << q.count << " segments, "
                  << ref.size() << " in the oracle");
  int unmatched = 0;
  std::vector<std::pair<double, double>> qi, ri;
  for (int i = 0; i < q.count; ++i) {
    CellSegment const& s = q.seg[i];
    if (i > 0) CHECK(q.seg[i - 1].t_in <= s.t_in);  // front to back
    qi.push_back({double(s.t_in), double(s.t_out)});
    auto const it = std::find_if(ref.begin(), ref.end(), [&](RefSegment const& x) { return x.cell == s.cell; });
    if (it == ref.end()) {
      unmatched += generic && s.t_out - s.t_in > tiny;
      continue;
    }
    CHECK(std::abs(double(s.t_in) - it->t_in) <= tol);
    CHECK(std::abs(double(s.t_out) - it->t_out) <= tol);
    // Values: the field is O(1) with gradients O(1): the same tolerance.
    CHECK(std::abs(double(s.v_in) - it->s_in) <= tol);
    CHECK(std::abs(double(s.v_out) - it->s_out) <= tol);
  }
  CHECK(unmatched == 0);
  for (RefSegment const& x : ref) ri.push_back({x.t_in, x.t_out});
  double const hi = std::min(double(r.tmax), double(q.cut));
  CHECK(std::abs(union_length(qi, double(r.tmin), hi) - union_length(ri, double(r.tmin), hi)) <=
        tol * double(2 + q.count));
  if (!generic) return;
  for (RefSegment const& x : ref) {
    if (x.t_out - x.t_in <= tiny || x.t_in >= double(q.cut) - tol) continue;
    if (x.t_out < double(r.tmin) + tiny || x.t_in > double(r.tmax) - tiny) continue;
    bool found = false;
    for (int i = 0; i < q.count && !found; ++i) found = q.seg[i].cell == x.cell;
    INFO("cell " << x.cell << " t " << x.t_in << ".." << x.t_out);
    CHECK(found);
  }
}

void check_all(TetMesh const& mesh, std::vector<Ray> const& rays, bool generic = true) {
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  ValueWindows const all;
  auto const packet = probe(mesh, bvh, all, rays, 0);
  auto const spmd = probe(mesh, bvh, all, rays, 1);
  auto const hybrid = probe(mesh, bvh, all, rays, 2);
  int differ = 0;
  for (size_t i = 0; i < rays.size(); ++i) differ += !same_lists(packet[i], spmd[i]) + !same_lists(packet[i], hybrid[i]);
  CHECK(differ == 0);
  for (size_t i = 0; i < rays.size(); ++i) check_ray(mesh, rays[i], packet[i], generic);
}

}  // namespace

TEST_CASE("segments: packet, SPMD and hybrid vs the double oracle on jittered tets, whole lines and windows", "[traverse][isa]") {
  auto const g = generate_tets(6 * 6 * 6 * 6, 3);
  TetMesh const mesh = g.mesh();
  check_all(mesh, random_rays(150, 1, false));
  check_all(mesh, random_rays(150, 2, true));
}

TEST_CASE("segments: shared edges and faces of a regular lattice", "[traverse][isa]") {
  auto const g = generate_tets(6 * 6 * 6 * 6, 1, 0.f);
  check_all(g.mesh(), lattice_rays(6, 3), false);
}

TEST_CASE("segments: gradients are the tets' analytic gradients", "[traverse][isa]") {
  auto const g = generate_tets(6 * 5 * 5 * 5, 4);
  TetMesh const mesh = g.mesh();
  std::vector<Ray> const rays = random_rays(64, 5, false);
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  auto const q = probe(mesh, bvh, ValueWindows{}, rays, 0, true);
  int checked = 0;
  for (auto const& o : q)
    for (int i = 0; i < o.count; ++i) {
      ref::Tet const t = ref::load(mesh, o.seg[i].cell);
      // Solve e_0k . g = s_k - s_0 in double.
      glm::dmat3 e;
      glm::dvec3 ds;
      for (int k = 0; k < 3; ++k) {
        glm::dvec3 const d = t.p[k + 1] - t.p[0];
        e[0][k] = d.x, e[1][k] = d.y, e[2][k] = d.z;  // row k = e_0k
        ds[k] = t.s[k + 1] - t.s[0];
      }
      glm::dvec3 const grad = glm::inverse(e) * ds;
      // float gradient of a well-shaped tet (jitter 0.3): relative error
      // ~1e-6 of |grad| ~ 1; 1e-4 absolute covers the worst conditioned.
      for (int a = 0; a < 3; ++a) CHECK(std::abs(double(o.gradient[i][a]) - grad[a]) <= 1e-4 * (1.0 + glm::length(grad)));
      ++checked;
    }
  CHECK(checked > 200);
}

TEST_CASE("segments: NaN cells give no segment and leave no gap elsewhere", "[traverse][isa]") {
  auto g = generate_tets(6 * 6 * 6 * 6, 6);
  for (size_t v = 0; v < g.field.size(); v += 7) g.field[v] = std::numeric_limits<float>::quiet_NaN();
  TetMesh const mesh = g.mesh();
  std::vector<Ray> const rays = random_rays(120, 7, false);
  check_all(mesh, rays);
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  auto const q = probe(mesh, bvh, ValueWindows{}, rays, 0);
  int nan_free = 0;
  for (auto const& o : q)
    for (int i = 0; i < o.count; ++i) nan_free += !ref::has_nan(ref::load(mesh, o.seg[i].cell));
  int total = 0;
  for (auto const& o : q) total += o.count;
  CHECK(nan_free == total);
  CHECK(total > 100);
}

TEST_CASE("segments: a window with more than max_segments cells keeps the nearest and cuts at the next",
          "[traverse][isa]") {
  // 24^3 lattice cells, 6 tets each: a ray along the cube's diagonal crosses
  // well over 48 tets.
  auto const g = generate_tets(6 * 24 * 24 * 24, 8);
  TetMesh const mesh = g.mesh();
  std::vector<Ray> rays;
  for (int i = 0; i < 16; ++i) {
    float const e = 0.02f * float(i % 8), f = 0.015f * float(i / 8);
    rays.push_back({{-1.5f, -1.5f + e, -1.5f + f}, 0.f, {1.f, 1.f, 1.f}, 10.f});
  }
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  ValueWindows const all;
  auto const packet = probe(mesh, bvh, all, rays, 0), spmd = probe(mesh, bvh, all, rays, 1);
  for (size_t i = 0; i < rays.size(); ++i) {
    std::vector<RefSegment> const ref = reference_segments(mesh, rays[i]);
    REQUIRE(ref.size() > size_t(test::probe_max_segments) + 4);
    CHECK(same_lists(packet[i], spmd[i]));
    SegmentProbeOut const& q = packet[i];
    CHECK(q.count == test::probe_max_segments);
    // The cut is the oracle's 49th entry (within the clip's rounding), and
    // the list holds the 48 before it.
    CHECK(std::abs(double(q.cut) - ref[size_t(test::probe_max_segments)].t_in) <= 1e-4);
    check_ray(mesh, rays[i], q, true);
    for (int k = 0; k < test::probe_max_segments; ++k) {
      if (ref[size_t(k)].t_out - ref[size_t(k)].t_in <= 1e-3 || ref[size_t(k)].t_in >= double(q.cut) - 1e-4) continue;
      bool found = false;
      for (int j = 0; j < q.count && !found; ++j) found = q.seg[j].cell == ref[size_t(k)].cell;
      CHECK(found);
    }
  }
}

TEST_CASE("segments: a value window drops only cells transparent along the ray", "[traverse][isa]") {
  auto const g = generate_tets(6 * 6 * 6 * 6, 9);
  TetMesh const mesh = g.mesh();
  float const lo = *std::min_element(g.field.begin(), g.field.end()), hi = *std::max_element(g.field.begin(), g.field.end());
  ValueWindows w;
  w.lo[0] = lo + 2.f * (hi - lo) / 3.f, w.hi[0] = hi;  // the top third, as the cool-warm preset
  std::vector<Ray> const rays = random_rays(150, 10, false);
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  auto const packet = probe(mesh, bvh, w, rays, 0), spmd = probe(mesh, bvh, w, rays, 1);
  int kept = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    CHECK(same_lists(packet[i], spmd[i]));
    SegmentProbeOut const& q = packet[i];
    for (int k = 0; k < q.count; ++k) CHECK(std::max(q.seg[k].v_in, q.seg[k].v_out) >= w.lo[0]);
    kept += q.count;
    // Every oracle segment clearly reaching into the window is kept.
    for (RefSegment const& x : reference_segments(mesh, rays[i])) {
      if (std::max(x.s_in, x.s_out) < double(w.lo[0]) + 1e-4 || x.t_out - x.t_in <= 1e-3) continue;
      bool found = false;
      for (int j = 0; j < q.count && !found; ++j) found = q.seg[j].cell == x.cell;
      CHECK(found);
    }
  }
  CHECK(kept > 50);
}

}  // namespace test_traverse_segment_query
