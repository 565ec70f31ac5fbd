#pragma once
// Runs CellQueries on one arch: `scalar` (width 1, compiled in the test
// itself from queries_impl.hpp) or a vector ISA through dispatch.

#include <string>

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

}  // namespace cellray::test
