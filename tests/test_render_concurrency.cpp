#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <memory>
#include <cstring>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <cellray/bvh/build.hpp>
#include <cellray/bvh/refit.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/render.hpp>

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_concurrency {

// Renders share everything read-only (render.hpp: "any number of renders may
// run at once on the same parts"). The oracle is the same render run alone:
// each pixel's computation does not depend on which thread runs its tile, so
// concurrent images must equal sequential ones bit for bit. The ThreadSanitizer
// build (scripts/tsan.sh) runs this file to catch races the images miss.

using namespace cellray;

namespace {

/// One shared scene: tets and hexes, each with the BVH's own ranges (time
/// step 0) and a refit for "field_t1" (time step 1; the tets also with their
/// face neighbours there: DVR segments and AO rays march). Built once.
struct SharedScene {
  GeneratedMesh<4> tets = generate_tets(12000, 7);
  GeneratedMesh<8> hexes = generate_hexes(2000, 7);
  TetMesh tm0 = tets.mesh(), tm1 = tm0.with_array("field_t1");
  HexMesh hm0 = hexes.mesh(), hm1 = hm0.with_array("field_t1");
  MinMaxBvh tbvh = build_minmax_bvh(tm0), hbvh = build_minmax_bvh(hm0);
  ValueRanges t1 = refit_ranges(tbvh, tm1), h1 = refit_ranges(hbvh, hm1);
  TetNeighbours tnb = build_tet_neighbours(tm0);

  Scene scene(bool hex, int step) const {
    if (hex) return step == 0 ? Scene(hm0, hbvh) : Scene(hm1, hbvh, &h1);
    return step == 0 ? Scene(tm0, tbvh) : Scene(tm1, tbvh, &t1, &tnb);
  }
};

/// scripts/tsan.sh sets CELLRAY_TEST_TBB_THREADS=1: TSan cannot see the
/// ordering TBB's uninstrumented scheduler gives a parallel_for's tasks, so
/// there each render runs on its own host thread only.
std::unique_ptr<tbb::global_control> tbb_limit() {
  char const* env = std::getenv("CELLRAY_TEST_TBB_THREADS");
  if (!env || !*env) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               size_t(std::max(1, std::atoi(env))));
}

SharedScene const& shared_scene() {
  static SharedScene const s;
  return s;
}

/// A render job: everything that varies between concurrent renders.
struct Job {
  bool hex;
  int step;
  bool dvr;
  int view;      // camera direction index
  float iso;     // first isovalue
  DvrMode mode;
  Traversal traversal;
  std::string name() const {
    return std::string(hex ? "hex" : "tet") + " t" + std::to_string(step) + (dvr ? " dvr" : " iso") + " view " +
           std::to_string(view) + " iso " + std::to_string(iso) + (mode == DvrMode::segments ? " segments " : " ") +
           traversal_name(traversal);
  }
};

Camera camera_for(int view) {
  glm::vec3 const eyes[] = {{0.4f, 0.3f, 3.2f}, {-3.f, 0.5f, 0.6f}, {1.1f, 2.8f, -1.2f}, {0.f, 0.f, 0.5f}};
  float const fovs[] = {35.f, 50.f, 28.f, 90.f};  // view 3: the eye is inside the mesh
  glm::vec3 const eye = eyes[view % 4];
  glm::vec3 const at = view % 4 == 3 ? glm::vec3(0.f, 0.f, -1.f) : glm::vec3(0.f);
  return Camera::look_at(eye, at, {0.f, 1.f, 0.f}, fovs[view % 4], 61, 47);  // odd sizes: partial tiles
}

Image render(Job const& j) {
  SharedScene const& s = shared_scene();
  Scene const scene = s.scene(j.hex, j.step);
  RenderOptions o;
  o.traversal = j.traversal;
  o.tile_size = 16;
  Camera const cam = camera_for(j.view);
  if (j.dvr) {
    DvrParams p;
    p.tf = transfer_function_preset(j.view % 2 ? "viridis" : "cool-warm", 0.1f, 0.8f);
    p.tf.unit_distance = 0.3f;
    p.mode = j.mode;
    return render_dvr(scene, cam, p, o);
  }
  IsoParams p;
  p.surfaces = {{j.iso, {0.9f, 0.5f, 0.2f}, 0.5f}, {j.iso + 0.2f, {0.2f, 0.6f, 0.9f}, 1.f}};
  p.shadows = j.view % 2 == 1;
  p.ao_samples = j.view % 2 == 1 ? 2 : 0;
  return render_iso(scene, cam, p, o);
}

std::vector<Job> jobs() {
  std::vector<Job> out;
  Traversal const tr[] = {Traversal::packet, Traversal::spmd, Traversal::hybrid};
  int k = 0;
  for (bool hex : {false, true})
    for (int step : {0, 1})
      for (bool dvr : {false, true}) {
        out.push_back({hex, step, dvr, k % 4, 0.25f + 0.05f * float(k % 3),
                       k % 2 ? DvrMode::segments : DvrMode::samples, tr[k % 3]});
        ++k;
      }
  return out;
}

bool same_bits(Image const& a, Image const& b) {
  return a.width == b.width && a.height == b.height && a.rgba.size() == b.rgba.size() &&
         std::memcmp(a.rgba.data(), b.rgba.data(), a.rgba.size() * sizeof(float)) == 0;
}

/// Runs f(i) for i in [0, n) on n host threads started together.
void run_together(size_t n, std::function<void(size_t)> const& f) {
  std::atomic<size_t> ready{0};
  std::vector<std::thread> threads;
  for (size_t i = 0; i < n; ++i)
    threads.emplace_back([&, i] {
      ++ready;
      while (ready.load() < n) std::this_thread::yield();
      f(i);
    });
  for (auto& t : threads) t.join();
}

}  // namespace

TEST_CASE("concurrent renders on one shared scene equal the same renders run one by one", "[render][concurrency]") {
  auto const limit = tbb_limit();
  std::vector<Job> const js = jobs();
  std::vector<Image> sequential;
  for (Job const& j : js) sequential.push_back(render(j));

  // Each job twice, all at once, every host thread also using TBB inside.
  size_t const n = js.size() * 2;
  std::vector<Image> concurrent(n);
  run_together(n, [&](size_t i) { concurrent[i] = render(js[i % js.size()]); });
  for (size_t i = 0; i < n; ++i) {
    INFO(js[i % js.size()].name());
    CHECK(same_bits(concurrent[i], sequential[i % js.size()]));
  }
}

TEST_CASE("render_tile from host threads into one image equals render_iso", "[render][concurrency]") {
  auto const limit = tbb_limit();
  SharedScene const& s = shared_scene();
  Scene const scene = s.scene(false, 1);
  Camera const cam = camera_for(0);
  IsoParams p;
  p.surfaces = {{0.3f, {0.9f, 0.5f, 0.2f}, 0.6f}, {0.5f, {0.2f, 0.6f, 0.9f}, 1.f}};
  RenderOptions o;
  o.tile_size = 16;  // the same tiles as render_iso cuts
  Image const whole = render_iso(scene, cam, p, o);

  std::vector<Tile> tiles;
  for (int y = 0; y < cam.height; y += 16)
    for (int x = 0; x < cam.width; x += 16) tiles.push_back({x, y, std::min(16, cam.width - x), std::min(16, cam.height - y)});
  Image img(cam.width, cam.height);
  size_t const threads = 6;
  run_together(threads, [&](size_t t) {
    for (size_t i = t; i < tiles.size(); i += threads) render_tile(scene, cam, p, tiles[i], img, o);
  });
  CHECK(same_bits(img, whole));
}

TEST_CASE("renders inside separate TBB arenas and one-thread arenas give the same image", "[render][concurrency]") {
  auto const limit = tbb_limit();
  Job const j{true, 1, true, 1, 0.3f, DvrMode::samples, Traversal::hybrid};
  Image const ref = render(j);
  std::vector<Image> out(4);
  run_together(out.size(), [&](size_t i) {
    tbb::task_arena arena(int(i % 2) + 1);  // 1 or 2 worker slots
    arena.execute([&] { out[i] = render(j); });
  });
  for (auto const& img : out) CHECK(same_bits(img, ref));
}

}  // namespace test_render_concurrency
