// VTU loading (issue #23): read_vtu on the flange (11 MB of inline base64,
// 10,750 polyhedra) and two zlib files; bytes = file bytes, so output reads
// MB/s of file. For a before/after, build this bench at both commits (the
// reader before the parallel base64 decode is 234e888's). In one process
// the allocator reuses warm pages: cellray-render --stats' load_ms in fresh
// processes is the figure users see (PROFILE.md).
//
// PNG encoding (io/image_write.hpp) of 1024x768 rendered frames: the
// component8 isosurface cellray-render draws by default (opaque) and a DVR
// of it on a transparent background (partial alpha, gradients). Items =
// pixels, so output reads pixels/s; counters give the file size. Each image
// is decoded by stb_image and compared byte for byte with
// Image::to_straight_rgba8 before timing.

#include <benchmark/benchmark.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include <cellray/bvh/build.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/io/vtu.hpp>
#include <cellray/render/camera.hpp>
#include <cellray/render/render.hpp>
#include <cellray/render/transfer_function.hpp>

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#include <stb/stb_image.h>

#include "bench_data.hpp"

using namespace cellray;

namespace {

constexpr int width = 1024, height = 768;

struct Frames {
  Image iso, dvr;
  Frames() {
    UnstructuredGrid const grid = read_mesh(bench::data_file("openfoam/component8_heat_608k.vtk"));
    TetMesh const mesh = grid.tet_mesh().with_array("T");
    MinMaxBvh const bvh = build_minmax_bvh(mesh);
    glm::vec3 const lo(bvh.root().lo[0], bvh.root().lo[1], bvh.root().lo[2]);
    glm::vec3 const hi(bvh.root().hi[0], bvh.root().hi[1], bvh.root().hi[2]);
    Scene const scene(mesh, bvh);
    Camera const cam = fit_camera(lo, hi, width, height);
    IsoParams ip;
    ip.surfaces = {IsoSurface{423.f, {0.85f, 0.85f, 0.85f}, 1.f}};
    iso = render_iso(scene, cam, ip);
    float vmin = INFINITY, vmax = -INFINITY;
    for (uint64_t i = 0; i < mesh.vertex_count(); ++i)
      if (std::isfinite(mesh.values()[i])) vmin = std::min(vmin, mesh.values()[i]), vmax = std::max(vmax, mesh.values()[i]);
    DvrParams dp;
    dp.tf = transfer_function_preset("cool-warm", vmin, vmax);
    dp.tf.unit_distance = glm::length(hi - lo) / 10.f;
    dp.background = glm::vec4(0.f);
    dvr = render_dvr(scene, cam, dp);
  }
};

Frames const& frames() {
  static Frames const f;
  return f;
}

/// Exits when `png` does not decode to img's straight-alpha bytes.
void check(std::string const& png, Image const& img, char const* name) {
  int w = 0, h = 0, c = 0;
  unsigned char* px = stbi_load_from_memory(reinterpret_cast<unsigned char const*>(png.data()), int(png.size()), &w, &h, &c, 4);
  auto const want = img.to_straight_rgba8();
  bool const ok = px && w == img.width && h == img.height && std::memcmp(px, want.data(), want.size()) == 0;
  stbi_image_free(px);
  if (!ok) {
    std::fprintf(stderr, "error: the %s PNG does not decode to the image's bytes\n", name);
    std::exit(1);
  }
}

void BM_encode_png(benchmark::State& state, bool dvr) {
  Image const& img = dvr ? frames().dvr : frames().iso;
  std::string png = encode_png(img);
  check(png, img, dvr ? "dvr" : "iso");
  for (auto _ : state) {
    png = encode_png(img);
    benchmark::DoNotOptimize(png.data());
  }
  state.SetItemsProcessed(int64_t(state.iterations()) * width * height);
  state.counters["png_bytes"] = double(png.size());
  state.counters["bits/pixel"] = 8.0 * double(png.size()) / double(width * height);
}

/// encode_png plus write_file_replacing: what cellray-render pays at the end.
void BM_write_png(benchmark::State& state) {
  Image const& img = frames().iso;
  std::string const path = "/tmp/cellray_bench_io_" + std::to_string(::getpid()) + ".png";
  for (auto _ : state) write_png(path, img);
  std::remove(path.c_str());
  state.SetItemsProcessed(int64_t(state.iterations()) * width * height);
}

void BM_load_vtu(benchmark::State& state, char const* rel) {
  std::string const path = bench::data_file(rel);
  uint64_t const bytes = io::FileBytes(path).bytes().size();
  for (auto _ : state) {
    UnstructuredGrid g = read_vtu(path);
    benchmark::DoNotOptimize(g.xyz.data());
  }
  state.SetBytesProcessed(int64_t(state.iterations() * bytes));
  state.counters["MB/s"] = benchmark::Counter(double(state.iterations() * bytes) / 1e6, benchmark::Counter::kIsRate);
}

}  // namespace

BENCHMARK_CAPTURE(BM_load_vtu, flange_snappy_89k, "openfoam/flange_snappy_89k.vtu")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_load_vtu, kiefer_zlib_base64, "vtk-data/kiefer_dataset.vtu")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_load_vtu, disk_out_ref_zlib_raw, "vtk-data/disk_out_ref.vtu")->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_encode_png, iso_component8_1024x768, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_encode_png, dvr_component8_1024x768, true)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_write_png)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
