// Min-max BVH build and refit throughput (M cells/s) per builder, for
// generated tets and hexes of 100k, 1M (and 5M with CELLRAY_BENCH_LARGE=1)
// cells, on 1 thread and on all threads; counters give bytes per cell, SAH
// cost and the tree shape. `BM_tree` is the table of tree statistics per
// builder (SAH cost, nodes, leaves, leaf sizes, depth, bytes per cell) for
// the traversal benchmarks to compare against; it times `bvh_stats`.
// `BM_refit_plan` refits through a RefitPlan (its bytes per cell as a
// counter), `BM_make_plan` times making one.
//
//   bench_bvh --benchmark_min_time=0.1
//   bench_bvh --benchmark_filter='BM_build/2/4/1000000'   (morton, tets, 1M)
//   bench_bvh --benchmark_filter='BM_tree' --benchmark_counters_tabular=true
//
// Arguments: builder (0 spatial_median, 1 binned_sah, 2 morton), corners
// (4 tets, 8 hexes), target cells, threads (0 = all).

#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <cellray/bvh/bvh.hpp>
#include <cellray/mesh/generate.hpp>

using namespace cellray;

namespace {

template <int N> GeneratedMesh<N> const& cached_mesh(uint64_t cells) {
  static std::map<uint64_t, std::unique_ptr<GeneratedMesh<N>>> cache;
  auto& slot = cache[cells];
  if (!slot) {
    if constexpr (N == 4) slot = std::make_unique<GeneratedMesh<4>>(generate_tets(cells));
    else slot = std::make_unique<GeneratedMesh<8>>(generate_hexes(cells));
  }
  return *slot;
}

/// 5M-cell cases only when the environment asks (they take minutes).
bool large() {
  char const* v = std::getenv("CELLRAY_BENCH_LARGE");
  return v && std::strcmp(v, "1") == 0;
}

std::vector<int64_t> sizes() {
  if (large()) return {100000, 1000000, 5000000};
  return {100000, 1000000};
}

int thread_count(int64_t arg) { return arg > 0 ? int(arg) : tbb::info::default_concurrency(); }

/// Every cell in exactly one leaf: the answer checked before timing.
bool items_once(MinMaxBvh const& bvh, uint64_t cells) {
  if (bvh.item_count() != cells) return false;
  std::vector<uint8_t> seen(cells, 0);
  for (uint64_t s = 0; s < cells; ++s)
    if (seen[bvh.item(s)]++) return false;
  return true;
}

void set_tree_counters(benchmark::State& state, MinMaxBvh const& bvh, uint64_t cells) {
  BvhStats const st = bvh_stats(bvh);
  state.counters["Mcells/s"] = benchmark::Counter(double(cells) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["B/cell"] = st.bytes_per_cell;
  state.counters["SAH"] = st.sah_cost;
  state.counters["depth"] = st.max_depth;
  state.counters["leaf"] = st.mean_leaf_items;
  state.counters["threads"] = thread_count(state.range(3));
  state.counters["cells"] = double(cells);
}

template <int N> void run_build(benchmark::State& state) {
  auto const& gen = cached_mesh<N>(uint64_t(state.range(2)));
  CellMesh<N> const mesh = gen.mesh();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, size_t(thread_count(state.range(3))));
  BuildOptions opt;
  opt.builder = BvhBuilder(state.range(0));
  MinMaxBvh bvh = build_minmax_bvh(mesh, opt);
  if (!items_once(bvh, mesh.cell_count())) {
    state.SkipWithError("BVH does not hold every cell exactly once");
    return;
  }
  for (auto _ : state) {
    bvh = build_minmax_bvh(mesh, opt);
    benchmark::DoNotOptimize(bvh.nodes());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(mesh.cell_count()));
  state.SetLabel(builder_name(opt.builder));
  set_tree_counters(state, bvh, mesh.cell_count());
}

void BM_build(benchmark::State& state) {
  if (state.range(1) == 4) run_build<4>(state);
  else run_build<8>(state);
}

/// Refit for the second time step ("field_t1") into reused storage; the
/// tree is a morton build (the refit cost depends on the item count, not
/// on the builder).
template <int N> void run_refit(benchmark::State& state) {
  auto const& gen = cached_mesh<N>(uint64_t(state.range(2)));
  CellMesh<N> const mesh = gen.mesh();
  CellMesh<N> const t1 = mesh.with_array("field_t1");
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, size_t(thread_count(state.range(3))));
  BuildOptions opt;
  opt.builder = BvhBuilder(state.range(0));
  MinMaxBvh const bvh = build_minmax_bvh(mesh, opt);
  ValueRanges ranges;
  refit_ranges(bvh, t1, ranges);
  if (ranges != build_minmax_bvh(t1, opt).ranges()) {
    state.SkipWithError("refit differs from a rebuild");
    return;
  }
  for (auto _ : state) {
    refit_ranges(bvh, t1, ranges);
    benchmark::DoNotOptimize(ranges.data());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(mesh.cell_count()));
  state.SetLabel("refit");
  set_tree_counters(state, bvh, mesh.cell_count());
}

void BM_refit(benchmark::State& state) {
  if (state.range(1) == 4) run_refit<4>(state);
  else run_refit<8>(state);
}

/// Refit as above through a RefitPlan made once outside the timing (the
/// "plan B/cell" counter is its size; "B/cell" stays the tree's).
template <int N> void run_refit_plan(benchmark::State& state) {
  auto const& gen = cached_mesh<N>(uint64_t(state.range(2)));
  CellMesh<N> const mesh = gen.mesh();
  CellMesh<N> const t1 = mesh.with_array("field_t1");
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, size_t(thread_count(state.range(3))));
  BuildOptions opt;
  opt.builder = BvhBuilder(state.range(0));
  MinMaxBvh const bvh = build_minmax_bvh(mesh, opt);
  RefitPlan const plan = make_refit_plan(bvh, mesh);
  ValueRanges ranges;
  refit_ranges(bvh, plan, t1, ranges);
  if (ranges != build_minmax_bvh(t1, opt).ranges()) {
    state.SkipWithError("refit through the plan differs from a rebuild");
    return;
  }
  for (auto _ : state) {
    refit_ranges(bvh, plan, t1, ranges);
    benchmark::DoNotOptimize(ranges.data());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(mesh.cell_count()));
  state.SetLabel("refit_plan");
  set_tree_counters(state, bvh, mesh.cell_count());
  state.counters["plan B/cell"] = double(plan.bytes()) / double(mesh.cell_count());
}

void BM_refit_plan(benchmark::State& state) {
  if (state.range(1) == 4) run_refit_plan<4>(state);
  else run_refit_plan<8>(state);
}

/// Time to make a RefitPlan (once per tree and connectivity).
template <int N> void run_make_plan(benchmark::State& state) {
  auto const& gen = cached_mesh<N>(uint64_t(state.range(2)));
  CellMesh<N> const mesh = gen.mesh();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, size_t(thread_count(state.range(3))));
  BuildOptions opt;
  opt.builder = BvhBuilder(state.range(0));
  MinMaxBvh const bvh = build_minmax_bvh(mesh, opt);
  RefitPlan plan;
  for (auto _ : state) {
    plan = make_refit_plan(bvh, mesh);
    benchmark::DoNotOptimize(plan.ids());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(mesh.cell_count()));
  state.SetLabel("make_refit_plan");
  state.counters["plan B/cell"] = double(plan.bytes()) / double(mesh.cell_count());
}

void BM_make_plan(benchmark::State& state) {
  if (state.range(1) == 4) run_make_plan<4>(state);
  else run_make_plan<8>(state);
}

/// Tree statistics of one builder's BVH (built once, outside the timing).
template <int N> void run_tree(benchmark::State& state) {
  auto const& gen = cached_mesh<N>(uint64_t(state.range(2)));
  CellMesh<N> const mesh = gen.mesh();
  BuildOptions opt;
  opt.builder = BvhBuilder(state.range(0));
  MinMaxBvh const bvh = build_minmax_bvh(mesh, opt);
  if (!items_once(bvh, mesh.cell_count())) {
    state.SkipWithError("BVH does not hold every cell exactly once");
    return;
  }
  BvhStats st;
  for (auto _ : state) {
    st = bvh_stats(bvh);
    benchmark::DoNotOptimize(st.leaves);  // not the double: GCC may hand "+r" an integer register
  }
  state.SetLabel(builder_name(opt.builder));
  state.counters["SAH"] = st.sah_cost;
  state.counters["nodes"] = double(st.nodes);
  state.counters["leaves"] = double(st.leaves);
  state.counters["leaf"] = st.mean_leaf_items;
  uint64_t max_leaf = 0, small = 0;  // largest leaf; leaves of 1-2 items
  for (size_t k = 0; k < st.leaf_size_histogram.size(); ++k)
    if (st.leaf_size_histogram[k]) {
      max_leaf = k;
      if (k <= 2) small += st.leaf_size_histogram[k];
    }
  state.counters["leaf_max"] = double(max_leaf);
  state.counters["leaf<=2"] = st.leaves ? double(small) / double(st.leaves) : 0.0;
  state.counters["depth"] = st.max_depth;
  state.counters["leaf_depth"] = st.mean_leaf_depth;
  state.counters["B/cell"] = st.bytes_per_cell;
}

void BM_tree(benchmark::State& state) {
  if (state.range(1) == 4) run_tree<4>(state);
  else run_tree<8>(state);
}

void tree_args(benchmark::internal::Benchmark* b) {
  for (int64_t cells : sizes())
    for (int64_t corners : {4, 8})
      for (int64_t builder : {0, 1, 2}) b->Args({builder, corners, cells, 0});
}

void build_args(benchmark::internal::Benchmark* b) {
  for (int64_t cells : sizes())
    for (int64_t corners : {4, 8})
      for (int64_t builder : {0, 1, 2})
        for (int64_t threads : {1, 0}) b->Args({builder, corners, cells, threads});
}

void refit_args(benchmark::internal::Benchmark* b) {
  for (int64_t cells : sizes())
    for (int64_t corners : {4, 8})
      for (int64_t threads : {1, 0}) b->Args({2, corners, cells, threads});
}

}  // namespace

BENCHMARK(BM_build)->Apply(build_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_refit)->Apply(refit_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_refit_plan)->Apply(refit_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_make_plan)->Apply(refit_args)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_tree)->Apply(tree_args)->Unit(benchmark::kMillisecond)->Iterations(1);

BENCHMARK_MAIN();
