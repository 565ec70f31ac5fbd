// Weak-scaling inputs for distributed rendering (issue #22, README "More
// than one machine"): one region out of k of a large generated tet mesh,
// measured alone on one thread, as one MPI rank of cellray-mpi-render would
// do it: partition, keep the region's cells, BVH, face neighbours, then DVR
// (cell segments, marching) and 3 isosurfaces (2 transparent) with rays
// clipped to the region's box, camera framing the whole mesh.
//
//   bench_partition [CELLS=8000000] [SIZE=1024] [K...=8 64 512]
//
// For each k it measures the region at the mesh's centre and prints per
// region: cells, build, neighbours, render times (ms) and the rays that
// reach the region's box. Not a Google Benchmark (one-shot phases).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include <tbb/global_control.h>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/mesh/partition.hpp>
#include <cellray/render/render.hpp>
#include <cellray/render/transfer_function.hpp>

using namespace cellray;
using Clock = std::chrono::steady_clock;

static double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

int main(int argc, char** argv) {
  uint64_t const cells = argc > 1 ? std::strtoull(argv[1], nullptr, 10) : 8000000;
  int const size = argc > 2 ? std::atoi(argv[2]) : 1024;
  std::vector<int> ks;
  for (int i = 3; i < argc; ++i) ks.push_back(std::atoi(argv[i]));
  if (ks.empty()) ks = {8, 64, 512};

  auto t0 = Clock::now();
  auto const g = generate_tets(cells);
  TetMesh const mesh = g.mesh();
  std::printf("mesh: %llu tets, generated in %.0f ms\n", (unsigned long long)mesh.cell_count(), ms_since(t0));
  glm::vec3 const lo(-1.f), hi(1.f);
  Camera const cam = fit_camera(lo, hi, size, size);
  float const diag = glm::length(hi - lo);
  DvrParams dp;
  dp.tf = transfer_function_preset("cool-warm", 0.1f, 0.75f, 0.8f);
  for (size_t i = 0; i < dp.tf.values.size(); ++i)  // cellray-render's linear opacity ramp
    dp.tf.rgba[i].a = 0.8f * (dp.tf.values[i] - 0.1f) / 0.65f;
  dp.tf.unit_distance = diag / 10.f;
  dp.step = default_dvr_step(dp.mode, diag);
  dp.background = {0.f, 0.f, 0.f, 0.f};
  IsoParams ip;
  ip.surfaces = {{0.3f, {0.31f, 0.57f, 0.85f}, 0.4f}, {0.45f, {0.96f, 0.62f, 0.25f}, 0.4f},
                 {0.6f, {0.85f, 0.33f, 0.35f}, 1.f}};
  ip.background = {0.f, 0.f, 0.f, 0.f};

  for (int k : ks) {
    t0 = Clock::now();
    KdPartition const part = partition_kd(mesh, k);  // all cores: every rank does this once
    double const part_ms = ms_since(t0);
    size_t r = 0;  // the region at the centre, where the field's blobs are
    glm::vec3 const c(0.01f, 0.02f, 0.03f);
    for (size_t i = 0; i < part.regions.size(); ++i)
      if (glm::all(glm::lessThanEqual(part.regions[i].lo, c)) && glm::all(glm::lessThanEqual(c, part.regions[i].hi))) r = i;
    KdRegion const& reg = part.regions[r];
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    t0 = Clock::now();
    CellSubset<4> const sub = subset_cells(mesh, reg.cells);
    TetMesh const m = sub.mesh();
    MinMaxBvh const bvh = build_minmax_bvh(m);
    double const build_ms = ms_since(t0);
    t0 = Clock::now();
    TetNeighbours const nb = build_tet_neighbours(m);
    double const nb_ms = ms_since(t0);
    Scene const scene(m, bvh, nullptr, &nb);
    dp.clip.planes = ip.clip.planes = clip_box(reg.lo, reg.hi);
    double best_dvr = 1e30, best_iso = 1e30;
    Image img;
    for (int rep = 0; rep < 3; ++rep) {
      t0 = Clock::now();
      img = render_dvr(scene, cam, dp);
      best_dvr = std::min(best_dvr, ms_since(t0));
      t0 = Clock::now();
      render_iso(scene, cam, ip);
      best_iso = std::min(best_iso, ms_since(t0));
    }
    // Pixels the region's box covers on screen (its rays that do any work).
    uint64_t covered = 0;
    for (int y = 0; y < size; ++y)
      for (int x = 0; x < size; ++x) {
        glm::vec3 const d = cam.direction(x, y), o = cam.eye;
        float t0b = 0.f, t1b = 1e30f;
        for (int a = 0; a < 3; ++a) {
          float const inv = 1.f / d[a];
          float ta = (reg.lo[a] - o[a]) * inv, tb = (reg.hi[a] - o[a]) * inv;
          if (ta > tb) std::swap(ta, tb);
          t0b = std::max(t0b, ta), t1b = std::min(t1b, tb);
        }
        covered += t0b <= t1b;
      }
    std::printf("k %4d: partition %.0f ms (all cores); region %zu: %zu cells (%.2fx n/k), box covers %.1f%% of %dx%d; "
                "1 thread: subset+BVH %.1f ms, neighbours %.1f ms, DVR %.1f ms, 3 iso %.1f ms\n",
                k, part_ms, r, reg.cells.size(), double(reg.cells.size()) * k / double(mesh.cell_count()),
                100.0 * double(covered) / (double(size) * size), size, size, build_ms, nb_ms, best_dvr, best_iso);
    std::fflush(stdout);
  }
}
