// Cell kernels per ISA: (ray or point, cell) pairs per second through
// CellQueries, SPMD (gathered corners) and packet (broadcast corners).
// Items = pairs, so output reads cells/s. Answers are checked against the
// double reference before timing.

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include <cellray/cells/queries.hpp>
#include <cellray/cells/reference.hpp>
#include <cellray/mesh/generate.hpp>

#include "support/adversarial.hpp"

using namespace cellray;

namespace {

template <int N> struct Workload {
  GeneratedMesh<N> g;
  std::vector<uint32_t> cells;
  std::vector<RayQuery> rays;
  std::vector<float> points;
  explicit Workload(uint64_t n_cells) {
    if constexpr (N == 4) g = generate_tets(n_cells, 9);
    else g = generate_hexes(n_cells, 9);
    CellMesh<N> const m = g.mesh();
    test::Rng rng(5);
    for (int i = 0; i < 1 << 14; ++i) {
      uint32_t const c = uint32_t(rng.next() % m.cell_count());
      ref::Cell<N> const cell = ref::load(m, c);
      glm::dvec3 centre(0);
      for (auto const& p : cell.p) centre += p / double(N);
      glm::dvec3 const target = centre + 0.3 * (cell.p[rng.next() % N] - centre);
      glm::dvec3 const d = rng.direction();
      cells.push_back(c);
      rays.push_back(test::to_query(target - 2.0 * d, d));
      points.insert(points.end(), {float(target.x), float(target.y), float(target.z)});
    }
  }
};

template <int N> Workload<N> const& workload() {
  static Workload<N> const w(N == 4 ? 200000 : 50000);
  return w;
}

enum Kernel { clip, locate, iso_exact, iso_neubauer2, gradient_central };
enum Mode { spmd, packet };

template <int N, Kernel K, Mode M, Isa I> void BM_cell(benchmark::State& state) {
  if (!isa_available(I)) {
    state.SkipWithError("ISA not supported");
    return;
  }
  auto const& w = workload<N>();
  CellMesh<N> const m = w.g.mesh();
  uint64_t const n = w.cells.size();
  std::vector<ClipOut> co(n);
  std::vector<LocateOut> lo(n);
  std::vector<IsoOut> io(n);
  std::vector<float> go(3 * n);
  float const isos[2] = {0.3f, 0.5f};
  auto run = [&]() {
    if constexpr (M == spmd) {
      CellSelect const sel{w.cells.data(), 0};
      if constexpr (K == clip) dispatch<CellQueries>(I, m, sel, w.rays.data(), n, co.data());
      if constexpr (K == locate) dispatch<CellQueries>(I, m, sel, w.points.data(), n, lo.data());
      if constexpr (K == iso_exact) dispatch<CellQueries>(I, m, sel, w.rays.data(), n, isos, 2, CellIsoOptions{}, io.data());
      if constexpr (K == iso_neubauer2)
        dispatch<CellQueries>(I, m, sel, w.rays.data(), n, isos, 2, CellIsoOptions{CellIsoMethod::neubauer, 2, 0}, io.data());
      if constexpr (K == gradient_central)
        dispatch<CellQueries>(I, m, sel, w.points.data(), n, GradientMethod::central, 1e-3f, go.data());
    } else {
      // Packet: runs of 16 queries share a cell (W rays against one cell).
      for (uint64_t i = 0; i < n; i += 16) {
        CellSelect const sel{nullptr, w.cells[i]};
        if constexpr (K == clip) dispatch<CellQueries>(I, m, sel, &w.rays[i], 16, &co[i]);
        if constexpr (K == locate) dispatch<CellQueries>(I, m, sel, &w.points[3 * i], 16, &lo[i]);
        if constexpr (K == iso_exact) dispatch<CellQueries>(I, m, sel, &w.rays[i], 16, isos, 2, CellIsoOptions{}, &io[i]);
        if constexpr (K == iso_neubauer2)
          dispatch<CellQueries>(I, m, sel, &w.rays[i], 16, isos, 2, CellIsoOptions{CellIsoMethod::neubauer, 2, 0}, &io[i]);
        if constexpr (K == gradient_central)
          dispatch<CellQueries>(I, m, sel, &w.points[3 * i], 16, GradientMethod::central, 1e-3f, &go[3 * i]);
      }
    }
  };
  run();
  if constexpr (K == clip && M == spmd) {  // answer check before timing
    for (uint64_t i = 0; i < n; i += 97) {
      ref::Clip const rc = ref::clip(ref::load(m, w.cells[i]), test::to_ref(w.rays[i]));
      if (rc.hit != bool(co[i].hit) || (rc.hit && std::abs(rc.t_in - co[i].t_in) > 1e-4)) {
        state.SkipWithError("clip disagrees with the reference");
        return;
      }
    }
  }
  for (auto _ : state) {
    run();
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(n));
}

#define CELL_BENCH(N, K, M)                                  \
  BENCHMARK_TEMPLATE(BM_cell, N, K, M, Isa::sse4_2);        \
  BENCHMARK_TEMPLATE(BM_cell, N, K, M, Isa::avx2);          \
  BENCHMARK_TEMPLATE(BM_cell, N, K, M, Isa::avx512);

CELL_BENCH(4, clip, spmd)
CELL_BENCH(4, clip, packet)
CELL_BENCH(4, locate, spmd)
CELL_BENCH(4, iso_exact, spmd)
CELL_BENCH(4, iso_neubauer2, spmd)
CELL_BENCH(8, clip, spmd)
CELL_BENCH(8, clip, packet)
CELL_BENCH(8, locate, spmd)
CELL_BENCH(8, iso_exact, spmd)
CELL_BENCH(8, iso_neubauer2, spmd)
CELL_BENCH(8, gradient_central, spmd)

}  // namespace

BENCHMARK_MAIN();
