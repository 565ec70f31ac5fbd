// Face neighbours (mesh/neighbours.hpp) of tet meshes (build_tet_neighbours):
// M cells/s on the real component8_heat_608k (OpenFOAM; its cell order is
// not spatially coherent, so each vertex's cells are spread over the whole
// array) and on 1M generated tets, on 1 thread and on all threads. Issue
// #23's target is 10 M cells/s on 2 threads in a fresh process; the first
// iteration here is the closest to that (later ones may reuse freed pages),
// so `cellray-render <mesh> --mode dvr --stats` (neighbours_ms) is the
// fresh-process figure.
//
//   bench_mesh --benchmark_filter='BM_neighbours/mesh:0/'   (component8_608k)
//
// Arguments: mesh (0 component8_heat_608k from $CELLRAY_DATA_DIR, skipped
// with the reason when missing; 1 generated, 1M tets), threads (0 = all).
//
// And of hexahedral meshes (build_hex_neighbours), the same way:
//
//   bench_mesh --benchmark_filter='BM_hex_neighbours/mesh:0/'   (boxturb48_dns)
//
// mesh 0 boxturb48_dns (110k hexes), 1 flange_snappy_89k.vtu with its tets
// folded into hexes as cellray-render does (222k hex-family cells), 2
// generated, 1M hexes.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdlib>
#include <memory>
#include <string>
#include <sys/stat.h>

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>

using namespace cellray;

namespace {

/// The mesh of argument `which`, loaded once; empty with `why` set when its
/// file is missing (bench_data.hpp's data_file would end the whole run).
struct Subject {
  std::unique_ptr<UnstructuredGrid> grid;
  GeneratedMesh<4> generated;
  TetMesh tets;
  std::string why;
};

/// $CELLRAY_DATA_DIR/<name>, or "" with `why` set when the file is missing.
std::string data_path(char const* name, std::string& why) {
  char const* env = std::getenv("CELLRAY_DATA_DIR");
  std::string const dir = env && *env ? std::string(env) : std::string(CELLRAY_DEFAULT_DATA_DIR);
  std::string const path = dir + "/" + name;
  struct stat st;
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) {
    why = path + " missing: set CELLRAY_DATA_DIR to the shared data set";
    return "";
  }
  return path;
}

Subject const& subject(int64_t which) {
  static std::unique_ptr<Subject> cache[2];
  auto& s = cache[which == 0 ? 0 : 1];
  if (s) return *s;
  s = std::make_unique<Subject>();
  if (which == 0) {
    std::string const path = data_path("openfoam/component8_heat_608k.vtk", s->why);
    if (path.empty()) return *s;
    s->grid = std::make_unique<UnstructuredGrid>(read_mesh(path));
    s->tets = s->grid->tet_mesh();
  } else {
    s->generated = generate_tets(1000000);
    s->tets = s->generated.mesh();
  }
  return *s;
}

void BM_neighbours(benchmark::State& state) {
  Subject const& s = subject(state.range(0));
  if (!s.why.empty()) return state.SkipWithError(s.why.c_str());
  int const threads = state.range(1) > 0 ? int(state.range(1)) : tbb::info::default_concurrency();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
  for (auto _ : state) {
    TetNeighbours nb = build_tet_neighbours(s.tets);
    benchmark::DoNotOptimize(nb.data());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(s.tets.cell_count()));
  state.counters["Mcells/s"] =
      benchmark::Counter(double(s.tets.cell_count()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["threads"] = threads;
  state.SetLabel(state.range(0) == 0 ? "component8_heat_608k" : "generated_1M");
}

struct HexSubject {
  std::unique_ptr<UnstructuredGrid> grid;
  GeneratedMesh<8> generated;
  HexMesh hexes;
  std::string why;
};

HexSubject const& hex_subject(int64_t which) {
  static std::unique_ptr<HexSubject> cache[3];
  auto& s = cache[std::min<int64_t>(which, 2)];
  if (s) return *s;
  s = std::make_unique<HexSubject>();
  if (which < 2) {
    std::string const path =
        data_path(which == 0 ? "openfoam/boxturb48_dns.vtk" : "openfoam/flange_snappy_89k.vtu", s->why);
    if (path.empty()) return *s;
    s->grid = std::make_unique<UnstructuredGrid>(read_mesh(path));
    if (!s->grid->tets.empty() && s->grid->tet_count() <= s->grid->hex_count()) s->grid->fold_tets_into_hexes();
    s->hexes = s->grid->hex_mesh();
  } else {
    s->generated = generate_hexes(1000000);
    s->hexes = s->generated.mesh();
  }
  return *s;
}

void BM_hex_neighbours(benchmark::State& state) {
  HexSubject const& s = hex_subject(state.range(0));
  if (!s.why.empty()) return state.SkipWithError(s.why.c_str());
  int const threads = state.range(1) > 0 ? int(state.range(1)) : tbb::info::default_concurrency();
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
  for (auto _ : state) {
    HexNeighbours nb = build_hex_neighbours(s.hexes);
    benchmark::DoNotOptimize(nb.data());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(s.hexes.cell_count()));
  state.counters["Mcells/s"] =
      benchmark::Counter(double(s.hexes.cell_count()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["threads"] = threads;
  char const* const names[] = {"boxturb48_dns", "flange_snappy_89k", "generated_1M"};
  state.SetLabel(names[std::min<int64_t>(state.range(0), 2)]);
}

}  // namespace

BENCHMARK(BM_neighbours)
    ->ArgsProduct({{0, 1}, {1, 0}})
    ->ArgNames({"mesh", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK(BM_hex_neighbours)
    ->ArgsProduct({{0, 1, 2}, {1, 0}})
    ->ArgNames({"mesh", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK_MAIN();
