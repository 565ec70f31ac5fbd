// Cell types against tetrahedra at the same cell count: issue #21's bar (a
// mixed mesh renders per ray within 1.5x of a tet-only mesh with the same
// number of cells) and the bytes each type costs per cell.
//
//   ./build/bench/bench_mixed --benchmark_min_time=1
//
// Generated meshes on the same jittered lattice and analytic field
// (mesh/generate.hpp), about CELLRAY_BENCH_CELLS cells each (default
// 100000): tetrahedra, hexahedra, wedges, pyramids, the hexahedron family
// mixed (hexahedra, wedges and pyramids, generate_hex_family) and the tets
// folded into collapsed hexahedra (fold_tets_into_hexes' layout, what
// `--fold-tets` renders). Wedges and pyramids are collapsed hexahedra, as
// the readers store them. One thread, 512x512 primary rays of the fitted
// camera, the library's defaults:
//   iso: the opaque isosurface at 0.45, exact roots, analytic normals;
//   dvr: cell segments marching through face neighbours, cool-warm with
//        opacity over the top third of the range, unit distance diagonal / 35.
// Every iteration renders the mesh and then the tetrahedra, so `x_tets`
// (the mesh's time over the tets', summed over the run) is a ratio of
// alternated frames, which this noisy 2-core machine's slow spells do not
// bias. Counters per cell: `idx_B` index bytes, `bvh_B` the BVH's,
// `nbr_B` the face neighbours' (DVR).

#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>

#include <tbb/global_control.h>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/mesh/vtk_cells.hpp>
#include <cellray/render/camera.hpp>
#include <cellray/render/render.hpp>

using namespace cellray;

namespace {

uint64_t target_cells() {
  char const* e = std::getenv("CELLRAY_BENCH_CELLS");
  return e ? std::strtoull(e, nullptr, 10) : 100000;
}

/// One generated mesh with its tree, neighbours and scenes.
struct Subject {
  GeneratedMesh<4> gt;
  GeneratedMesh<8> gh;
  bool tets = false;
  MinMaxBvh bvh;
  TetNeighbours tet_neighbours;
  HexNeighbours hex_neighbours;
  Scene iso, dvr;
  glm::vec3 lo{0.f}, hi{0.f};
  uint64_t cells = 0, index_bytes = 0, neighbour_bytes = 0;
};

/// The tets stored as collapsed hexahedra (tet_as_hex, as
/// fold_tets_into_hexes stores them).
GeneratedMesh<8> folded(GeneratedMesh<4> const& t) {
  GeneratedMesh<8> g;
  g.xyz = t.xyz, g.field = t.field, g.field_t1 = t.field_t1, g.lattice = t.lattice;
  g.cells.reserve(t.cells.size() * 2);
  for (size_t c = 0; c < t.cells.size(); c += 4)
    for (int k : tet_as_hex) g.cells.push_back(t.cells[c + size_t(k)]);
  return g;
}

/// The tree, neighbours and scenes of mesh `m` (viewing the subject's arrays).
template <int N> void prepare(Subject& s, CellMesh<N> const& m, FaceNeighbours<N>& neighbours) {
  s.bvh = build_minmax_bvh(m);
  if constexpr (N == 4) neighbours = build_tet_neighbours(m);
  else neighbours = build_hex_neighbours(m);
  s.iso = Scene(m, s.bvh);
  s.dvr = Scene(m, s.bvh, nullptr, &neighbours);
  s.cells = m.cell_count();
  s.neighbour_bytes = neighbours.memory_bytes();
}

Subject& subject(std::string const& name) {
  static std::map<std::string, std::unique_ptr<Subject>> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return *it->second;
  auto s = std::make_unique<Subject>();
  uint64_t const n = target_cells();
  if (name == "tets") s->gt = generate_tets(n), s->tets = true;
  else if (name == "hexes") s->gh = generate_hexes(n);
  else if (name == "wedges") s->gh = generate_wedges(n);
  else if (name == "pyramids") s->gh = generate_pyramids(n);
  else if (name == "hex_family") s->gh = generate_hex_family(n * 2 / 3);  // a third of the lattice cells split in two
  else if (name == "folded_tets") s->gh = folded(generate_tets(n));
  if (s->tets) prepare(*s, s->gt.mesh(), s->tet_neighbours);
  else prepare(*s, s->gh.mesh(), s->hex_neighbours);
  s->index_bytes = (s->tets ? s->gt.cells.size() : s->gh.cells.size()) * sizeof(uint32_t);
  s->iso.bounds(s->lo, s->hi);
  return *cache.emplace(name, std::move(s)).first->second;
}

IsoParams iso_params() {
  IsoParams p;
  p.surfaces.push_back({0.45f});
  return p;
}

DvrParams dvr_params(Subject const& s) {
  float lo = INFINITY, hi = -INFINITY;
  for (float v : s.tets ? s.gt.field : s.gh.field) lo = std::min(lo, v), hi = std::max(hi, v);
  DvrParams p;
  p.tf = transfer_function_preset("cool-warm", lo, hi);
  p.tf.unit_distance = glm::length(s.hi - s.lo) / 35.f;
  return p;
}

void BM_against_tets(benchmark::State& state, std::string const& name, bool dvr) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
  Subject& s = subject(name);
  Subject& t = subject("tets");
  int const size = 512;
  Camera const cam = fit_camera(s.lo, s.hi, size, size), tcam = fit_camera(t.lo, t.hi, size, size);
  IsoParams const iso = iso_params();
  DvrParams const sp = dvr_params(s), tp = dvr_params(t);
  auto frame = [&](Subject const& m, Camera const& c, DvrParams const& p) {
    auto const start = std::chrono::steady_clock::now();
    Image const img = dvr ? render_dvr(m.dvr, c, p) : render_iso(m.iso, c, iso);
    benchmark::DoNotOptimize(img.rgba.data());
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  frame(s, cam, sp), frame(t, tcam, tp);  // warm caches and the TBB arena
  double mine = 0, theirs = 0;
  for (auto _ : state) {
    double const a = frame(s, cam, sp);
    theirs += frame(t, tcam, tp);
    mine += a;
    state.SetIterationTime(a);
  }
  auto const c = double(s.cells);
  state.counters["cells"] = c;
  state.counters["Mrays/s"] = benchmark::Counter(double(size) * size * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["x_tets"] = mine / theirs;
  state.counters["idx_B"] = double(s.index_bytes) / c;
  state.counters["bvh_B"] = double(s.bvh.memory_bytes()) / c;
  if (dvr) state.counters["nbr_B"] = double(s.neighbour_bytes) / c;
}

int register_all() {
  for (bool dvr : {false, true})
    for (char const* m : {"tets", "hexes", "wedges", "pyramids", "hex_family", "folded_tets"}) {
      std::string const n = std::string(dvr ? "dvr/" : "iso/") + m;
      benchmark::RegisterBenchmark(n.c_str(), BM_against_tets, std::string(m), dvr)
          ->UseManualTime()
          ->Unit(benchmark::kMillisecond);
    }
  return 0;
}

int const registered = register_all();

}  // namespace

BENCHMARK_MAIN();
