// The host's door (issue #22, part 1): frames prepared once and rendered
// tile by tile into the host's own buffer (8-bit or float, padded rows),
// depth in (the host's opaque geometry ends the rays) and out (where the
// opacity first reaches a threshold), and DVR of the host's own rays.
// Checked against the full-image renders, the reference renderer with the
// equivalent clip, and the geometry of the hits.

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <thread>
#include <vector>

#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/traverse/queries.hpp>

#include "support/render_fixtures.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_host {

using namespace cellray;

using test::busy_tf;
using test::diagonal;
using test::report;

namespace {

struct Fixture {
  GeneratedMesh<4> g = generate_tets(6 * 8 * 8 * 8, 4);
  TetMesh mesh = g.mesh();
  MinMaxBvh bvh = build_minmax_bvh(mesh);
  TetNeighbours nb = build_tet_neighbours(mesh);
  Scene scene{mesh, bvh, nullptr, &nb};
  // Looking down -z at the cube [-1, 1]^3 from z = 4.
  Camera cam = Camera::look_at({0.2f, 0.3f, 4.f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 35.f, 56, 40);

  IsoParams iso() const {
    IsoParams p;
    p.surfaces = {{0.3f, {0.9f, 0.7f, 0.4f}, 0.5f}, {0.55f, {0.4f, 0.6f, 0.9f}, 1.f}};
    return p;
  }
  DvrParams dvr() const {
    DvrParams p;
    p.tf = busy_tf(0.1f, 0.9f, diagonal(scene) / 8.f);
    p.step = diagonal(scene) / 1000.f;
    return p;
  }
  /// Per pixel, the distance from the eye to the plane z = z0 (the host's
  /// opaque "floor" seen from above), +inf where a ray misses it.
  std::vector<float> plane_depth(float z0) const {
    std::vector<float> d(size_t(cam.width) * size_t(cam.height));
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        glm::vec3 const dir = glm::normalize(cam.direction(float(x), float(y)));
        float const t = (z0 - cam.eye.z) / dir.z;
        d[size_t(y) * size_t(cam.width) + size_t(x)] = t > 0.f ? t : std::numeric_limits<float>::infinity();
      }
    return d;
  }
};

}  // namespace

TEST_CASE("tiles of a prepared frame on host threads into padded 8-bit and float buffers equal the full render",
          "[render][host][isa]") {
  Fixture const f;
  RenderOptions const ro = test::isa_options();
  IsoParams const ip = f.iso();
  DvrParams const dp = f.dvr();
  Image const iso = render_iso(f.scene, f.cam, ip, ro), dvr = render_dvr(f.scene, f.cam, dp, ro);
  IsoFrame const iframe(f.scene, ip);
  DvrFrame const dframe(f.scene, dp);
  int const W = f.cam.width, H = f.cam.height;
  for (auto format : {FrameBuffer::Format::rgba8, FrameBuffer::Format::rgba32f})
    for (bool volume : {false, true}) {
      size_t const pixel = format == FrameBuffer::Format::rgba8 ? 4 : 16, row = pixel * size_t(W) + 24;
      std::vector<unsigned char> buf(row * size_t(H), 0xAB);
      FrameBuffer fb;
      fb.width = W, fb.height = H, fb.rgba = buf.data(), fb.format = format, fb.row_bytes = row;
      // Four host threads, each its own tiles.
      std::vector<std::thread> threads;
      for (int k = 0; k < 4; ++k)
        threads.emplace_back([&, k] {
          for (int ty = 0; ty < H; ty += 16)
            for (int tx = 0; tx < W; tx += 16) {
              if (((tx / 16 + ty / 16) & 3) != k) continue;
              Tile const t{tx, ty, std::min(16, W - tx), std::min(16, H - ty)};
              if (volume) render_tile(dframe, f.cam, t, fb, ro);
              else render_tile(iframe, f.cam, t, fb, ro);
            }
        });
      for (auto& t : threads) t.join();
      Image const& want = volume ? dvr : iso;
      std::vector<uint8_t> const want8 = want.to_rgba8();
      bool same = true, padding_kept = true;
      for (int y = 0; y < H; ++y) {
        unsigned char const* r = buf.data() + size_t(y) * row;
        for (size_t b = pixel * size_t(W); b < row; ++b) padding_kept = padding_kept && r[b] == 0xAB;
        for (int x = 0; x < W; ++x)
          for (int k = 0; k < 4; ++k) {
            size_t const i = (size_t(y) * size_t(W) + size_t(x)) * 4 + size_t(k);
            if (format == FrameBuffer::Format::rgba8) same = same && r[size_t(x) * 4 + size_t(k)] == want8[i];
            else {
              float v;
              std::memcpy(&v, r + size_t(x) * 16 + size_t(k) * 4, 4);
              same = same && v == want.rgba[i];
            }
          }
      }
      CHECK(same);
      CHECK(padding_kept);
    }
}

TEST_CASE("depth in: the host's geometry ends the rays, as a clip plane does in the reference", "[render][host][isa]") {
  Fixture const f;
  RenderOptions const ro = test::isa_options();
  std::vector<float> const depth = f.plane_depth(0.1f);
  // The reference's equivalent: keep z >= 0.1 (the normal points into what is cut away).
  Clip keep_front;
  keep_front.planes = {{{0.f, 0.f, 0.1f}, {0.f, 0.f, -1.f}}};
  IsoParams ip = f.iso();
  DvrParams dp = f.dvr();
  for (bool volume : {false, true}) {
    Image img(f.cam.width, f.cam.height);
    FrameBuffer fb = FrameBuffer::of(img);
    fb.depth_in = depth.data();
    if (volume) render(f.scene, f.cam, dp, fb, ro);
    else render(f.scene, f.cam, ip, fb, ro);
    IsoParams ipc = ip;
    DvrParams dpc = dp;
    ipc.clip = keep_front, dpc.clip = keep_front;
    Image const ref = volume ? render_dvr_reference(f.scene, f.cam, dpc) : render_iso_reference(f.scene, f.cam, ipc);
    ImageDiff const d = compare_images(img, ref, 2.0);
    report(std::string(volume ? "DVR" : "iso") + " with a depth buffer vs the reference clipped there", d);
    CHECK(d.nonfinite == 0);
    CHECK(d.frac_over <= 0.005);
    // Everything in front of the camera hidden: nothing drawn.
    std::vector<float> const zero(depth.size(), 0.f);
    fb.depth_in = zero.data();
    if (volume) render(f.scene, f.cam, dp, fb, ro);
    else render(f.scene, f.cam, ip, fb, ro);
    glm::vec4 const bg = volume ? dp.background : ip.background;
    bool all_background = true;
    for (size_t i = 0; i < img.rgba.size(); i += 4)
      for (int k = 0; k < 4; ++k) all_background = all_background && img.rgba[i + size_t(k)] == bg[k];
    CHECK(all_background);
  }
}

TEST_CASE("depth out: opaque isosurface hits lie on the surface -- volume depth grows with the threshold",
          "[render][host][isa]") {
  Fixture const f;
  RenderOptions const ro = test::isa_options();
  IsoParams ip;
  ip.surfaces = {{0.45f, {0.9f, 0.7f, 0.4f}, 1.f}};
  ip.background = {0.f, 0.f, 0.f, 0.f};
  Image img(f.cam.width, f.cam.height);
  std::vector<float> depth(size_t(f.cam.width) * size_t(f.cam.height));
  FrameBuffer fb = FrameBuffer::of(img);
  fb.depth_out = depth.data();
  render(f.scene, f.cam, ip, fb, ro);
  std::vector<float> xyz;
  int hits = 0;
  for (int y = 0; y < f.cam.height; ++y)
    for (int x = 0; x < f.cam.width; ++x) {
      float const d = depth[size_t(y) * size_t(f.cam.width) + size_t(x)];
      bool const drawn = img.pixel(x, y)[3] > 0.f;
      CHECK(drawn == std::isfinite(d));
      if (!drawn) continue;
      glm::vec3 const p = f.cam.eye + d * glm::normalize(f.cam.direction(float(x), float(y)));
      xyz.insert(xyz.end(), {p.x, p.y, p.z});
      ++hits;
    }
  REQUIRE(hits > 100);
  std::vector<float> const v = sample_points(TreeView(f.bvh, f.bvh.ranges()), f.mesh, xyz, test::isa());
  int on = 0;
  for (float s : v) on += std::abs(s - 0.45f) < 1e-3f;
  CHECK(on >= hits - hits / 100);  // the field at the depth is the isovalue (1%: points just outside the mesh)

  DvrParams dp = f.dvr();
  dp.background = {0.f, 0.f, 0.f, 0.f};
  std::vector<float> d30(depth.size()), d60(depth.size());
  fb.depth_out = d30.data(), fb.depth_opacity = 0.3f;
  render(f.scene, f.cam, dp, fb, ro);
  fb.depth_out = d60.data(), fb.depth_opacity = 0.6f;
  render(f.scene, f.cam, dp, fb, ro);
  int both = 0;
  for (size_t i = 0; i < d30.size(); ++i) {
    float const a = img.rgba[4 * i + 3];
    CHECK(std::isfinite(d30[i]) == (a >= 0.3f));
    CHECK(std::isfinite(d60[i]) == (a >= 0.6f));
    if (std::isfinite(d60[i])) {
      CHECK(d30[i] <= d60[i]);
      ++both;
    }
  }
  CHECK(both > 100);
}

TEST_CASE("DVR of host rays: camera rays give the image -- an interval ends them as a depth buffer does",
          "[render][host][isa]") {
  Fixture const f;
  RenderOptions const ro = test::isa_options();
  DvrParams dp = f.dvr();
  dp.background = {0.f, 0.f, 0.f, 0.f};  // the image then holds the volume's premultiplied contribution
  std::vector<float> const depth = f.plane_depth(-0.2f);
  Image img(f.cam.width, f.cam.height);
  FrameBuffer fb = FrameBuffer::of(img);
  fb.depth_in = depth.data();
  render(f.scene, f.cam, dp, fb, ro);
  std::vector<Ray> rays;
  for (int y = 0; y < f.cam.height; ++y)
    for (int x = 0; x < f.cam.width; ++x)
      rays.push_back(Ray{f.cam.eye, 0.f, glm::normalize(f.cam.direction(float(x), float(y))),
                         depth[size_t(y) * size_t(f.cam.width) + size_t(x)]});
  DvrFrame const frame(f.scene, dp);
  std::vector<float> rgba(4 * rays.size()), ray_depth(rays.size());
  integrate_rays(frame, rays.data(), rays.size(), rgba.data(), ray_depth.data(), 0.5f, ro);
  Image host(f.cam.width, f.cam.height);
  host.rgba = rgba;
  ImageDiff const d = compare_images(host, img, 1.0);
  report("host rays vs the image with the same depth buffer", d);
  CHECK(d.rmse < 0.05);
  CHECK(d.frac_over <= 0.002);
  // A ray starting inside at tmin = t and one ending there split the volume:
  // front over back is the whole ray.
  std::vector<Ray> front, back;
  for (Ray const& r : rays) {
    front.push_back(Ray{r.org, 0.f, r.dir, 3.5f});
    back.push_back(Ray{r.org, 3.5f, r.dir, r.tmax});
  }
  std::vector<float> a(4 * rays.size()), b(4 * rays.size());
  integrate_rays(frame, front.data(), front.size(), a.data(), nullptr, 0.5f, ro);
  integrate_rays(frame, back.data(), back.size(), b.data(), nullptr, 0.5f, ro);
  double worst = 0;
  for (size_t i = 0; i < rays.size(); ++i)
    for (int k = 0; k < 4; ++k) {
      double const over = a[4 * i + size_t(k)] + (1.0 - a[4 * i + 3]) * b[4 * i + size_t(k)];
      worst = std::max(worst, std::abs(over - rgba[4 * i + size_t(k)]));
    }
  INFO("front over back vs the whole ray, worst channel " << worst);
  CHECK(worst < 2.0 / 255);
}

TEST_CASE("scene-level first hits and point samples over several parts, on TBB", "[render][host][isa]") {
  auto const t = generate_tets(6 * 6 * 6 * 6, 1);
  auto h = generate_hexes(6 * 6 * 6, 1);
  for (size_t v = 0; v < h.xyz.size(); v += 3) h.xyz[v] += 3.f;  // hexes in [2, 4] x [-1, 1]^2
  TetMesh const tm = t.mesh();
  HexMesh const hm = h.mesh();
  MinMaxBvh const tb = build_minmax_bvh(tm), hb = build_minmax_bvh(hm);
  Scene scene(tm, tb);
  scene.hexes.push_back({hm, &hb, nullptr});
  RenderOptions const ro = test::isa_options();
  std::vector<float> xyz;
  for (int i = 0; i < 2000; ++i) {
    float const u = float(i) / 2000.f;
    xyz.insert(xyz.end(), {-1.5f + 7.f * u, 0.9f * std::sin(37.f * u), 0.9f * std::cos(53.f * u)});
  }
  std::vector<float> const both = sample_points(scene, xyz, ro);
  std::vector<float> const in_t = sample_points(TreeView(tb, tb.ranges()), tm, xyz, test::isa());
  std::vector<float> const in_h = sample_points(TreeView(hb, hb.ranges()), hm, xyz, test::isa());
  int inside = 0;
  for (size_t i = 0; i < both.size(); ++i) {
    float const want = in_t[i] == in_t[i] ? in_t[i] : in_h[i];
    CHECK(((both[i] == want) || (both[i] != both[i] && want != want)));
    inside += both[i] == both[i];
  }
  CHECK(inside > 1000);

  IsoParams ip;
  ip.surfaces = {{0.4f}, {0.6f}};
  std::vector<Ray> rays;
  for (int i = 0; i < 500; ++i) {
    float const y = -0.9f + 1.8f * float(i % 25) / 24.f, z = -0.9f + 1.8f * float(i / 25) / 19.f;
    float const x0 = i % 2 ? -3.f : 1.5f;  // odd rays cross the tets first, even ones start between the meshes
    rays.push_back(Ray{{x0, y, z}, 0.f, {1.f, 0.f, 0.f}, 100.f});
  }
  std::vector<SurfaceHit> const hits = first_hits(scene, rays, ip, ro);
  IsoQuery q;
  q.isos.count = 2, q.isos.values[0] = 0.4f, q.isos.values[1] = 0.6f;
  std::vector<SurfaceHit> const ht = first_hits(TreeView(tb, tb.ranges()), tm, rays, q, test::isa());
  std::vector<SurfaceHit> const hh = first_hits(TreeView(hb, hb.ranges()), hm, rays, q, test::isa());
  int from_hexes = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    bool const tets_first = ht[i].t <= hh[i].t;
    SurfaceHit const& want = tets_first ? ht[i] : hh[i];
    CHECK(hits[i].t == want.t);
    if (hits[i].hit()) CHECK(hits[i].piece == (tets_first ? 0u : 1u));
    from_hexes += hits[i].hit() && !tets_first;
  }
  CHECK(from_hexes > 50);
}

TEST_CASE("bad frame buffers are refused", "[render][host]") {
  Fixture const f;
  IsoParams const ip = f.iso();
  IsoFrame const frame(f.scene, ip);
  Image small(8, 8);
  CHECK_THROWS_WITH(render_tile(frame, f.cam, {0, 0, 8, 8}, FrameBuffer::of(small)), Catch::Contains("frame buffer 8x8"));
  FrameBuffer fb;
  fb.width = f.cam.width, fb.height = f.cam.height;
  CHECK_THROWS_WITH(render_tile(frame, f.cam, {0, 0, 8, 8}, fb), Catch::Contains("without an RGBA buffer"));
  std::vector<float> px(4 * size_t(f.cam.width) * size_t(f.cam.height));
  fb.rgba = px.data(), fb.row_bytes = 8;
  CHECK_THROWS_WITH(render_tile(frame, f.cam, {0, 0, 8, 8}, fb), Catch::Contains("hold fewer than"));
  fb.row_bytes = 0;
  CHECK_THROWS_AS(render_tile(frame, f.cam, {50, 0, 16, 8}, fb), InvalidArgument);
}

}  // namespace test_render_host
