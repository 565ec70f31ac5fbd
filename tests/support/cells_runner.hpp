#pragma once
// Runs CellQueries on one arch: `scalar` (width 1, compiled in the test
// itself from queries_impl.hpp) or a vector ISA through dispatch; the query
// sets and the all-kernels run the tet and hex tests share.

#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include <cellray/cells/queries_impl.hpp>

namespace cellray::test {

struct CellRunner {
  bool scalar = true;
  Isa isa = Isa::sse4_2;

  std::string name() const { return scalar ? "scalar" : isa_name(isa); }

  template <int N> void clip(CellMesh<N> const& m, CellSelect s, RayQuery const* r, uint64_t n, ClipOut* o) const {
    if (scalar) CellQueries<cellray::scalar>::run(m, s, r, n, o);
    else dispatch<CellQueries>(isa, m, s, r, n, o);
  }
  template <int N> void locate(CellMesh<N> const& m, CellSelect s, float const* p, uint64_t n, LocateOut* o) const {
    if (scalar) CellQueries<cellray::scalar>::run(m, s, p, n, o);
    else dispatch<CellQueries>(isa, m, s, p, n, o);
  }
  template <int N>
  void gradient(CellMesh<N> const& m, CellSelect s, float const* p, uint64_t n, GradientMethod g, float h,
                float* o) const {
    if (scalar) CellQueries<cellray::scalar>::run(m, s, p, n, g, h, o);
    else dispatch<CellQueries>(isa, m, s, p, n, g, h, o);
  }
  template <int N>
  void iso(CellMesh<N> const& m, CellSelect s, RayQuery const* r, uint64_t n, float const* v, int k,
           CellIsoOptions opt, IsoOut* o) const {
    if (scalar) CellQueries<cellray::scalar>::run(m, s, r, n, v, k, opt, o);
    else dispatch<CellQueries>(isa, m, s, r, n, v, k, opt, o);
  }
};

/// Queries of the kernel tests: query i asks about cell cells[i], with ray
/// rays[i] and point points[3i .. 3i+2].
struct QuerySet {
  std::vector<uint32_t> cells;
  std::vector<RayQuery> rays;
  std::vector<float> points;
  void add(uint32_t cell, RayQuery const& ray, glm::dvec3 const& point) {
    cells.push_back(cell);
    rays.push_back(ray);
    points.insert(points.end(), {float(point.x), float(point.y), float(point.z)});
  }
  uint64_t size() const { return cells.size(); }
};

/// Every kernel's answer to a QuerySet.
struct QueryResults {
  std::vector<ClipOut> clip;
  std::vector<LocateOut> locate;
  std::vector<float> gradient, gradient_central;  // xyz per query
  std::vector<IsoOut> iso, neubauer;              // exact; Neubauer N = 2
};

/// Runs clip, locate, analytic and central (step `h`) gradients, exact and
/// Neubauer (2 rounds) iso roots of `isos` on every query: SPMD (`packet`
/// false: one call per kernel, corners gathered per lane) or packet (one
/// call per query, corners broadcast), so both loaders are exercised.
template <int N>
QueryResults run_queries(CellRunner const& run, CellMesh<N> const& m, QuerySet const& q, float const* isos, int count,
                         float h, bool packet) {
  uint64_t const n = q.size();
  QueryResults r;
  r.clip.resize(n), r.locate.resize(n), r.gradient.resize(3 * n), r.gradient_central.resize(3 * n);
  r.iso.resize(n), r.neubauer.resize(n);
  CellIsoOptions const neubauer{CellIsoMethod::neubauer, 2, 0};
  auto one = [&](CellSelect const& sel, uint64_t i, uint64_t k) {
    run.clip(m, sel, &q.rays[i], k, &r.clip[i]);
    run.locate(m, sel, &q.points[3 * i], k, &r.locate[i]);
    run.gradient(m, sel, &q.points[3 * i], k, GradientMethod::analytic, 0.f, &r.gradient[3 * i]);
    run.gradient(m, sel, &q.points[3 * i], k, GradientMethod::central, h, &r.gradient_central[3 * i]);
    run.iso(m, sel, &q.rays[i], k, isos, count, {}, &r.iso[i]);
    run.iso(m, sel, &q.rays[i], k, isos, count, neubauer, &r.neubauer[i]);
  };
  if (!packet) one(CellSelect{q.cells.data(), 0}, 0, n);
  else
    for (uint64_t i = 0; i < n; ++i) one(CellSelect{nullptr, q.cells[i]}, i, 1);
  return r;
}

}  // namespace cellray::test
