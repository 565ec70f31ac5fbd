// Memory accounting of a render (not a Google Benchmark; not run in CI):
// builds and renders a generated tet mesh and reports the process's resident
// memory against what the scene needs: input arrays + BVH + framebuffer.
//
//   bench_memory [cells = 5000000] [width = 1920] [height = 1080]
//
// Peak RSS per phase comes from the kernel's high-water mark (VmHWM in
// /proc/self/status), reset before each phase through /proc/self/clear_refs
// (Linux >= 4.0), after malloc_trim(0) so memory glibc keeps from an
// earlier phase does not hide a later one's; getrusage's ru_maxrss is the
// whole-run peak (the BVH build's transient boxes).
// Figures: docs/reliability.md.

#include <malloc.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include <cellray/bvh/build.hpp>
#include <cellray/bvh/refit.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/render.hpp>

namespace {

double mib(double bytes) { return bytes / (1024.0 * 1024.0); }

/// A field of /proc/self/status in bytes (VmRSS, VmHWM), or -1.
double status_bytes(char const* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) return std::atof(line.c_str() + std::string(key).size() + 1) * 1024.0;
  return -1;
}

/// Resets the high-water mark to the current RSS; false when not allowed.
bool reset_peak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  return bool(out.flush());
}

struct Phase {
  double rss_before = 0;
  bool reset = false;
  void begin() {
    malloc_trim(0);  // hand freed heap back first, so a phase cannot hide in an earlier phase's leftovers
    rss_before = status_bytes("VmRSS:");
    reset = reset_peak();
  }
  /// Peak during the phase above the RSS it started at (or -1 without a reset).
  double peak_growth() const { return reset ? status_bytes("VmHWM:") - rss_before : -1; }
};

}  // namespace

int main(int argc, char** argv) {
  uint64_t const cells = argc > 1 ? std::strtoull(argv[1], nullptr, 10) : 5000000;
  int const width = argc > 2 ? std::atoi(argv[2]) : 1920;
  int const height = argc > 3 ? std::atoi(argv[3]) : 1080;
  double const rss_start = status_bytes("VmRSS:");

  Phase gen;
  gen.begin();
  auto const g = cellray::generate_tets(cells, 1);
  cellray::TetMesh const mesh = g.mesh();
  double const input = double(mesh.viewed_bytes());
  double const gen_peak = gen.peak_growth();

  Phase build;
  build.begin();
  cellray::MinMaxBvh const bvh = cellray::build_minmax_bvh(mesh);
  double const build_peak = build.peak_growth();
  double const bvh_bytes = double(bvh.memory_bytes());
  malloc_trim(0);
  double const rss_scene = status_bytes("VmRSS:");

  Phase refit;
  refit.begin();
  cellray::ValueRanges const t1 = cellray::refit_ranges(bvh, mesh.with_array("field_t1"));
  double const refit_peak = refit.peak_growth();

  glm::vec3 lo, hi;
  cellray::Scene const scene(mesh, bvh);
  scene.bounds(lo, hi);
  cellray::Camera const cam = cellray::fit_camera(lo, hi, width, height);
  double const framebuffer = double(width) * double(height) * 4 * sizeof(float);

  cellray::IsoParams iso;
  iso.surfaces = {{0.3f, {0.3f, 0.5f, 0.9f}, 0.4f}, {0.6f, {0.9f, 0.3f, 0.2f}, 1.f}};
  Phase render_iso;
  render_iso.begin();
  auto t0 = std::chrono::steady_clock::now();
  double iso_checksum = 0;
  {
    cellray::Image const img = cellray::render_iso(scene, cam, iso);
    for (size_t i = 0; i < img.rgba.size(); i += 97) iso_checksum += img.rgba[i];
  }
  double const iso_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  double const iso_peak = render_iso.peak_growth();

  cellray::DvrParams dvr;
  dvr.tf = cellray::transfer_function_preset("viridis", 0.1f, 0.8f);
  dvr.tf.unit_distance = 0.3f;
  Phase render_dvr;
  render_dvr.begin();
  t0 = std::chrono::steady_clock::now();
  double dvr_checksum = 0;
  {
    cellray::Image const img = cellray::render_dvr(cellray::Scene(mesh.with_array("field_t1"), bvh, &t1), cam, dvr);
    for (size_t i = 0; i < img.rgba.size(); i += 97) dvr_checksum += img.rgba[i];
  }
  double const dvr_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  double const dvr_peak = render_dvr.peak_growth();

  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  std::printf("mesh: %llu tets, %llu vertices (generate_tets(%llu)); image %dx%d\n",
              (unsigned long long)mesh.cell_count(), (unsigned long long)mesh.vertex_count(),
              (unsigned long long)cells, width, height);
  std::printf("peak-RSS reset via /proc/self/clear_refs: %s\n", gen.reset ? "yes" : "NO (phase peaks unavailable)");
  std::printf("%-44s %10s %10s\n", "", "MiB", "B/cell");
  auto row = [&](char const* what, double bytes) {
    std::printf("%-44s %10.1f %10.2f\n", what, mib(bytes), bytes / double(mesh.cell_count()));
  };
  row("input arrays (xyz, cells, field, field_t1)", input);
  row("BVH (nodes + item ids + ranges)", bvh_bytes);
  row("  refit ranges for field_t1", double(t1.bytes()));
  row("framebuffer (RGBA float)", framebuffer);
  row("process RSS at start", rss_start);
  row("RSS with mesh + BVH built", rss_scene);
  row("peak growth: generating the mesh", gen_peak);
  row("peak growth: BVH build (transient boxes)", build_peak);
  row("peak growth: refit", refit_peak);
  row("peak growth: render_iso", iso_peak);
  row("  of which not the framebuffer", iso_peak - framebuffer);
  row("peak growth: render_dvr", dvr_peak);
  row("  of which not the framebuffer", dvr_peak - framebuffer);
  row("whole-run peak (getrusage ru_maxrss)", double(ru.ru_maxrss) * 1024.0);
  row("  minus start + inputs + BVH + ranges + fb", double(ru.ru_maxrss) * 1024.0 - rss_start - input - bvh_bytes -
                                                       double(t1.bytes()) - framebuffer);
  std::printf("render_iso %.2f s, render_dvr %.2f s (checksums %.3f %.3f)\n", iso_s, dvr_s, iso_checksum, dvr_checksum);
  return 0;
}
