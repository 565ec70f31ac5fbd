// Point probes (issue #23): sample_points on random points in a mesh's
// bounds, the old path (each point a zero-length ray through the ray-packet
// sample query, as sample_points did before) against the new one (Morton
// order + point-location traversal), with each lever alone, on 1 and 2
// threads. Points per second of wall time.
//
//   ./build/bench/bench_probe --benchmark_repetitions=3 --benchmark_enable_random_interleaving=true
//
// Meshes: component8_608k ($CELLRAY_DATA_DIR/openfoam/component8_heat_608k.vtk,
// array T) and a generated 512k-hex lattice with jittered (non-planar) faces,
// twisted by 1.5 rad over its height and bent (curved). 2M uniform random
// points in the BVH root's box (CELLRAY_PROBE_POINTS overrides the count).
// Before the timed loop each variant's values are compared with the old
// path's on the first 200k points: counters `differ` (NaN-ness or value
// apart by more than 1e-5 of the range) and `inside` (fraction found).

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cellray/bvh/build.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/render.hpp>
#include <cellray/traverse/queries.hpp>

#include "bench_data.hpp"

using namespace cellray;

namespace {

struct Loaded {
  std::unique_ptr<UnstructuredGrid> grid;
  GeneratedMesh<8> gh;
  bool hex = false;
  TetMesh tets;
  HexMesh hexes;
  MinMaxBvh bvh;
  Scene scene;
  std::vector<float> xyz;
  float range = 1.f;
};

uint64_t point_count() {
  char const* e = std::getenv("CELLRAY_PROBE_POINTS");
  return e && *e ? uint64_t(std::atoll(e)) : uint64_t(2000000);
}

Loaded& mesh(std::string const& name) {
  static std::map<std::string, std::unique_ptr<Loaded>> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return *it->second;
  auto m = std::make_unique<Loaded>();
  if (name == "component8_608k") {
    m->grid = std::make_unique<UnstructuredGrid>(read_mesh(bench::data_file("openfoam/component8_heat_608k.vtk")));
    m->tets = m->grid->tet_mesh().with_array("T");
    m->bvh = build_minmax_bvh(m->tets);
    m->scene = Scene(m->tets, m->bvh);
  } else {
    m->gh = generate_hexes(80 * 80 * 80, 3, 0.3f);
    for (size_t v = 0; v < m->gh.xyz.size(); v += 3) {
      float const x = m->gh.xyz[v], y = m->gh.xyz[v + 1], z = m->gh.xyz[v + 2];
      float const a = 0.75f * (z + 1.f);
      m->gh.xyz[v] = std::cos(a) * x - std::sin(a) * y + 0.15f * std::sin(2.f * y);
      m->gh.xyz[v + 1] = std::sin(a) * x + std::cos(a) * y;
    }
    m->hex = true;
    m->hexes = m->gh.mesh();
    m->bvh = build_minmax_bvh(m->hexes);
    m->scene = Scene(m->hexes, m->bvh);
  }
  float lo = 1e30f, hi = -1e30f;
  float const* val = m->hex ? m->hexes.values() : m->tets.values();
  uint64_t const nv = m->hex ? m->hexes.vertex_count() : m->tets.vertex_count();
  for (uint64_t v = 0; v < nv; ++v) lo = std::min(lo, val[v]), hi = std::max(hi, val[v]);
  m->range = hi - lo;
  Node const& root = m->bvh.root();
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  uint64_t const n = point_count();
  m->xyz.resize(3 * n);
  for (uint64_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) m->xyz[3 * i + uint64_t(a)] = root.lo[a] + u(rng) * (root.hi[a] - root.lo[a]);
  return *cache.emplace(name, std::move(m)).first->second;
}

enum Variant { old_rays, old_rays_sorted, new_unsorted, new_sorted };
char const* const variant_names[] = {"old_rays", "old_rays_sorted", "new_unsorted", "new"};

/// sample_points as it was before issue #23: each point a zero-length ray
/// through SampleEntry (ray packets), chunks of 1024 points on TBB.
void old_sample_points(PreparedScene const& s, float const* xyz, uint64_t n, float* out, Isa isa) {
  constexpr uint64_t chunk = 1024;
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, (n + chunk - 1) / chunk), [&](tbb::blocked_range<uint64_t> const& r) {
    std::vector<Ray> rays(chunk);
    std::vector<float> v(chunk);
    for (uint64_t c = r.begin(); c < r.end(); ++c) {
      uint64_t const b = c * chunk, m = std::min(chunk, n - b);
      for (uint64_t i = 0; i < m; ++i) {
        out[b + i] = std::nanf("");
        rays[i] = Ray{{xyz[3 * (b + i)], xyz[3 * (b + i) + 1], xyz[3 * (b + i) + 2]}, 0.f, {1.f, 0.f, 0.f}, 0.f};
      }
      for (PreparedPart const& part : s.parts) {
        dispatch<SampleEntry>(isa, part.tree, part.mesh(), rays.data(), m, 0.f, 1, 1, Traversal::packet, ValueWindows{},
                              v.data());
        for (uint64_t i = 0; i < m; ++i)
          if (!(out[b + i] == out[b + i])) out[b + i] = v[i];
      }
    }
  });
}

void run_variant(Variant var, Loaded const& m, float const* xyz, uint64_t n, float* out) {
  RenderOptions const o;
  PreparedScene const s = render_detail::prepare(m.scene);
  switch (var) {
    case old_rays: old_sample_points(s, xyz, n, out, o.isa); break;
    case old_rays_sorted:
      detail::probe_in_order(xyz, n, out, s.lo, s.hi, true, [&](float const* p, uint64_t k, float* v) {
        old_sample_points(s, p, k, v, o.isa);
      });
      break;
    case new_unsorted:
      detail::probe_in_order(xyz, n, out, s.lo, s.hi, false, [&](float const* p, uint64_t k, float* v) {
        for (PreparedPart const& part : s.parts) dispatch<ProbeEntry>(o.isa, part.tree, part.mesh(), p, k, v);
      });
      break;
    case new_sorted: sample_points(m.scene, xyz, n, out, o); break;
  }
}

void BM_probe(benchmark::State& state, std::string const& name, Variant var, int threads) {
  Loaded& m = mesh(name);
  uint64_t const n = m.xyz.size() / 3;
  std::vector<float> out(n);
  tbb::task_arena arena(threads);
  {
    // The answer first: against the old path on a prefix of the points.
    uint64_t const k = std::min<uint64_t>(n, 200000);
    std::vector<float> a(k), b(k);
    arena.execute([&] {
      run_variant(old_rays, m, m.xyz.data(), k, a.data());
      run_variant(var, m, m.xyz.data(), k, b.data());
    });
    uint64_t differ = 0, inside = 0;
    for (uint64_t i = 0; i < k; ++i) {
      bool const an = a[i] != a[i], bn = b[i] != b[i];
      differ += an != bn || (!an && std::abs(a[i] - b[i]) > 1e-5f * m.range);
      inside += !bn;
    }
    state.counters["differ"] = double(differ);
    state.counters["inside"] = double(inside) / double(k);
  }
  for (auto _ : state) {
    arena.execute([&] { run_variant(var, m, m.xyz.data(), n, out.data()); });
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(n));
}

int register_all() {
  for (std::string const name : {"component8_608k", "twisted_hexes_512k"})
    for (Variant v : {old_rays, old_rays_sorted, new_unsorted, new_sorted})
      for (int t : {1, 2})
        benchmark::RegisterBenchmark(("probe/" + name + "/" + variant_names[v] + "/threads:" + std::to_string(t)).c_str(),
                                     [=](benchmark::State& s) { BM_probe(s, name, v, t); })
            ->Unit(benchmark::kMillisecond)
            ->UseRealTime();
  return 0;
}
int const registered = register_all();

}  // namespace

BENCHMARK_MAIN();
