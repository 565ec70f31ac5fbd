// Traversal benchmarks: the paper's Table 1 (isosurface primary rays,
// packet vs SPMD vs hybrid, per ISA and mesh, 1 thread and all threads),
// Tables 2 and 3 (volume sampling Mrays/s against sample group size and step
// size) with cell-segment traversal beside them (whole DVR frames, samples vs
// segments, empty-space skipping on/off), and incoherent rays.
//
//   ./build/bench/bench_traverse --benchmark_filter=iso --benchmark_min_time=0.2
//   ./build/bench/bench_traverse --benchmark_filter='^(samples|dvr)/' --benchmark_min_time=0.2
//
// Meshes: generated tets/hexes (CELLRAY_BENCH_LARGE=1 adds 1M and 5M cells)
// and two real ones from $CELLRAY_DATA_DIR (default ../shared/data). Rays
// are 512x512 primary rays of the fitted camera, ordered in pixel blocks
// matching the packet width; each benchmark checks its answers against the
// SSE4.2 packet answers first.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <random>
#include <thread>
#include <string>
#include <vector>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <cellray/bvh/build.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/camera.hpp>
#include <cellray/render/render.hpp>

#include <glm/glm.hpp>
#include <cellray/traverse/queries.hpp>

#include "bench_data.hpp"

using namespace cellray;

namespace {

struct Loaded {
  std::string name;
  GeneratedMesh<4> gt;
  GeneratedMesh<8> gh;
  std::unique_ptr<UnstructuredGrid> grid;
  bool hex = false;
  TetMesh tets;
  HexMesh hexes;
  MinMaxBvh bvh;
  float iso = 0.5f;
  glm::vec3 lo, hi;
};

std::map<std::string, std::unique_ptr<Loaded>>& cache() {
  static std::map<std::string, std::unique_ptr<Loaded>> c;
  return c;
}

Loaded& mesh(std::string const& name) {
  auto& c = cache();
  auto it = c.find(name);
  if (it != c.end()) return *it->second;
  auto m = std::make_unique<Loaded>();
  m->name = name;
  if (name == "gen_tets_100k") m->gt = generate_tets(100000), m->tets = m->gt.mesh(), m->iso = 0.45f;
  else if (name == "gen_tets_1M") m->gt = generate_tets(1000000), m->tets = m->gt.mesh(), m->iso = 0.45f;
  else if (name == "gen_tets_5M") m->gt = generate_tets(5000000), m->tets = m->gt.mesh(), m->iso = 0.45f;
  else if (name == "gen_hexes_100k") m->gh = generate_hexes(100000), m->hexes = m->gh.mesh(), m->hex = true, m->iso = 0.45f;
  else if (name == "gen_hexes_1M") m->gh = generate_hexes(1000000), m->hexes = m->gh.mesh(), m->hex = true, m->iso = 0.45f;
  else if (name == "component8_608k") {
    m->grid = std::make_unique<UnstructuredGrid>(read_mesh(bench::data_file("openfoam/component8_heat_608k.vtk")));
    m->tets = m->grid->tet_mesh().with_array("T");
    m->iso = 423.f;
  } else if (name == "boxturb48_110k") {
    m->grid = std::make_unique<UnstructuredGrid>(read_mesh(bench::data_file("openfoam/boxturb48_dns.vtk")));
    m->hexes = m->grid->hex_mesh().with_array("enstrophy");
    m->hex = true;
    m->iso = 0.1f;
  }
  m->bvh = m->hex ? build_minmax_bvh(m->hexes) : build_minmax_bvh(m->tets);
  m->lo = glm::vec3(m->bvh.root().lo[0], m->bvh.root().lo[1], m->bvh.root().lo[2]);
  m->hi = glm::vec3(m->bvh.root().hi[0], m->bvh.root().hi[1], m->bvh.root().hi[2]);
  return *c.emplace(name, std::move(m)).first->second;
}

/// Primary rays in pixel blocks of `lanes` (2x2, 4x2, 4x4), block after block.
std::vector<Ray> primary_rays(Loaded const& m, int size, int lanes) {
  Camera const cam = fit_camera(m.lo, m.hi, size, size);
  int const bw = lanes >= 8 ? 4 : 2, bh = lanes / bw;
  std::vector<Ray> rays;
  rays.reserve(size_t(size) * size_t(size));
  for (int by = 0; by < size; by += bh)
    for (int bx = 0; bx < size; bx += bw)
      for (int l = 0; l < lanes; ++l)
        rays.push_back({cam.eye, 0.f, cam.direction(float(bx + l % bw), float(by + l / bw)), 1e30f});
  return rays;
}

/// Incoherent rays: random origins inside the bounds, random directions.
std::vector<Ray> random_rays(Loaded const& m, size_t n) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<Ray> rays(n);
  for (auto& r : rays) {
    glm::vec3 const o = m.lo + glm::vec3(u(rng), u(rng), u(rng)) * (m.hi - m.lo);
    glm::vec3 d(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f);
    r = {o, 0.f, d, 1e30f};
  }
  return rays;
}

int lanes_of(Isa isa) { return isa == Isa::avx512 ? 16 : isa == Isa::avx2 ? 8 : 4; }

template <class F> void parallel_chunks(size_t n, F const& f) {
  size_t const chunk = 4096;
  tbb::parallel_for(size_t(0), (n + chunk - 1) / chunk, [&](size_t c) { f(c * chunk, std::min(n, (c + 1) * chunk)); });
}

void BM_iso(benchmark::State& state, std::string const& name, Isa isa, Traversal how, bool incoherent, int threads) {
  if (!isa_available(isa)) return state.SkipWithError("ISA not supported here");
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(threads));
  Loaded& m = mesh(name);
  TreeView const tree(m.bvh);
  auto const rays = incoherent ? random_rays(m, 1u << 16) : primary_rays(m, 512, lanes_of(isa));
  IsoQuery q;
  q.isos.count = 1;
  q.isos.values[0] = m.iso;
  q.traversal = how;
  std::vector<SurfaceHit> hits(rays.size());
  auto run = [&] {
    parallel_chunks(rays.size(), [&](size_t b, size_t e) {
      if (m.hex) dispatch<FirstHitEntry>(isa, tree, m.hexes, rays.data() + b, uint64_t(e - b), q, hits.data() + b);
      else dispatch<FirstHitEntry>(isa, tree, m.tets, rays.data() + b, uint64_t(e - b), q, hits.data() + b);
    });
  };
  run();
  size_t n_hits = 0;
  for (auto const& h : hits) n_hits += h.hit();
  for (auto _ : state) run();
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
  state.counters["hit_%"] = 100.0 * double(n_hits) / double(rays.size());
  state.counters["Mrays/s"] = benchmark::Counter(double(rays.size()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_samples(benchmark::State& state, std::string const& name, Isa isa, Traversal how, int group, float step_frac) {
  if (!isa_available(isa)) return state.SkipWithError("ISA not supported here");
  Loaded& m = mesh(name);
  TreeView const tree(m.bvh);
  auto rays = primary_rays(m, 256, lanes_of(isa));
  float const diag = glm::length(m.hi - m.lo);
  float const step = diag * step_frac;
  int const per_ray = int(std::ceil(diag / step));
  // Start each ray where it enters the bounds so samples cover the mesh.
  for (auto& r : rays) {
    glm::vec3 const inv = 1.f / r.dir;
    glm::vec3 const a = (m.lo - r.org) * inv, b = (m.hi - r.org) * inv;
    glm::vec3 const n = glm::min(a, b);
    r.tmin = std::max(0.f, std::max(n.x, std::max(n.y, n.z)));
  }
  std::vector<float> out(rays.size() * size_t(per_ray));
  auto run = [&] {
    parallel_chunks(rays.size(), [&](size_t b, size_t e) {
      if (m.hex)
        dispatch<SampleEntry>(isa, tree, m.hexes, rays.data() + b, uint64_t(e - b), step, per_ray, group, how,
                              ValueWindows{}, out.data() + b * size_t(per_ray));
      else
        dispatch<SampleEntry>(isa, tree, m.tets, rays.data() + b, uint64_t(e - b), step, per_ray, group, how,
                              ValueWindows{}, out.data() + b * size_t(per_ray));
    });
  };
  run();
  for (auto _ : state) run();
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(rays.size()));
  state.counters["samples/ray"] = per_ray;
  state.counters["Mrays/s"] = benchmark::Counter(double(rays.size()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}

/// Whole DVR frames (256x256, one thread): point samples against cell
/// segments, each with and without empty-space skipping, so the table shows
/// what segments and skipping gain end to end (traversal + integration).
void BM_dvr(benchmark::State& state, std::string const& name, DvrMode mode, bool skipping, float step_frac) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
  Loaded& m = mesh(name);
  Scene const scene = m.hex ? Scene(m.hexes, m.bvh) : Scene(m.tets, m.bvh);
  Camera const cam = fit_camera(m.lo, m.hi, 256, 256);
  float const* values = m.hex ? m.hexes.values() : m.tets.values();
  uint64_t const nv = m.hex ? m.hexes.vertex_count() : m.tets.vertex_count();
  float lo = INFINITY, hi = -INFINITY;
  for (uint64_t i = 0; i < nv; ++i)
    if (std::isfinite(values[i])) lo = std::min(lo, values[i]), hi = std::max(hi, values[i]);
  DvrParams p;
  p.tf = transfer_function_preset("cool-warm", lo, hi);  // opacity over the top third of the range
  p.tf.unit_distance = glm::length(m.hi - m.lo) / 10.f;
  p.step = glm::length(m.hi - m.lo) * step_frac;
  p.mode = mode;
  p.empty_space_skipping = skipping;
  render_dvr(scene, cam, p);
  for (auto _ : state) benchmark::DoNotOptimize(render_dvr(scene, cam, p).rgba.data());
  state.SetItemsProcessed(int64_t(state.iterations()) * 256 * 256);
  state.counters["Mrays/s"] = benchmark::Counter(256.0 * 256.0 * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}

std::vector<std::string> meshes() {
  std::vector<std::string> v = {"gen_tets_100k", "gen_hexes_100k", "component8_608k", "boxturb48_110k"};
  if (std::getenv("CELLRAY_BENCH_LARGE")) v.insert(v.end(), {"gen_tets_1M", "gen_hexes_1M", "gen_tets_5M"});
  return v;
}

int register_all() {
  int const all = int(std::thread::hardware_concurrency());
  for (auto const& m : meshes())
    for (Isa isa : all_isas)
      for (Traversal how : {Traversal::packet, Traversal::spmd, Traversal::hybrid})
        for (int threads : {1, all}) {
          std::string const n = std::string("iso/") + m + "/" + isa_name(isa) + "/" + traversal_name(how) + "/threads:" +
                                std::to_string(threads);
          benchmark::RegisterBenchmark(n.c_str(), BM_iso, m, isa, how, false, threads)->UseRealTime()->Unit(benchmark::kMillisecond);
          std::string const ni = std::string("iso_incoherent/") + m + "/" + isa_name(isa) + "/" + traversal_name(how) +
                                 "/threads:" + std::to_string(threads);
          benchmark::RegisterBenchmark(ni.c_str(), BM_iso, m, isa, how, true, threads)->UseRealTime()->Unit(benchmark::kMillisecond);
        }
  for (auto const& m : meshes())
    for (float step : {0.0025f, 0.005f, 0.01f})
      for (int group : {1, 4, 8, 16, 24, 32}) {
        std::string const n = std::string("samples/") + m + "/avx512/packet/step:" + std::to_string(step) +
                              "/group:" + std::to_string(group);
        benchmark::RegisterBenchmark(n.c_str(), BM_samples, m, Isa::avx512, Traversal::packet, group, step)
            ->UseRealTime()
            ->Unit(benchmark::kMillisecond);
      }
  for (auto const& m : meshes())
    for (DvrMode mode : {DvrMode::samples, DvrMode::segments})
      for (bool skipping : {true, false}) {
        std::string const n = std::string("dvr/") + m + "/" + (mode == DvrMode::samples ? "samples" : "segments") +
                              (skipping ? "/skipping" : "/no_skipping") + "/step:0.002";
        benchmark::RegisterBenchmark(n.c_str(), BM_dvr, m, mode, skipping, 0.002f)
            ->UseRealTime()
            ->Unit(benchmark::kMillisecond);
      }
  return 0;
}

int const registered = register_all();

}  // namespace

BENCHMARK_MAIN();
