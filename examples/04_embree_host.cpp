// 04: cellray inside a host renderer. The host ray traces its own opaque
// triangles with Embree 3 (a checkered ground plane under the mesh and a
// pillar standing partly inside it), shades them, and asks cellray for the
// volume along the same camera rays, each ending at Embree's hit: the volume
// stops at the geometry, and the geometry shows through its transparency.
//   DVR (default): integrate_rays over [0, Embree's t], composited "over" the
//     geometry: out = vol + (1 - vol.a) * geom (premultiplied colours).
//   --iso: an opaque isosurface rendered into a FrameBuffer with depth_in =
//     Embree's t (surfaces behind the geometry are hidden) and depth_out;
//     the nearer of the two wins.
//   --layers: also writes OUT.geometry.png (no volume) and OUT.volume.png
//     (the volume alone, its rays not ended: what the geometry hides).
// Usage: 04_embree_host [--iso] [--layers] [mesh.vtk|mesh.vtu] [out.png]
// (no mesh: a generated one of 100k tets).
#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <cellray/bvh/build.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/render/render.hpp>

using glm::vec3;
float const inf = std::numeric_limits<float>::infinity();

int main(int argc, char** argv) try {
  bool iso_mode = false, layers = false;
  std::string mesh_path, out = "04_embree_host.png";
  for (int i = 1; i < argc; ++i) {
    std::string const a = argv[i];
    if (a == "--iso") iso_mode = true;
    else if (a == "--layers") layers = true;
    else if (a.size() > 4 && a.compare(a.size() - 4, 4, ".png") == 0) out = a;
    else mesh_path = a;
  }

  // The volume: a file's tets and hexes (first point array), or generated tets.
  cellray::UnstructuredGrid grid;
  cellray::GeneratedMesh<4> generated;
  cellray::TetMesh tets;
  cellray::HexMesh hexes;
  if (mesh_path.empty()) generated = cellray::generate_tets(100000), tets = generated.mesh();
  else grid = cellray::read_mesh(mesh_path), tets = grid.tet_mesh(), hexes = grid.hex_mesh();
  cellray::MinMaxBvh tet_bvh, hex_bvh;
  cellray::Scene scene;
  float vmin = inf, vmax = -inf;
  auto add_part = [&](auto const& mesh, cellray::MinMaxBvh& bvh, auto& parts) {
    if (mesh.empty()) return;
    auto const rep = cellray::validate(mesh);
    cellray::require_valid(rep);
    vmin = std::min(vmin, rep.value_min), vmax = std::max(vmax, rep.value_max);
    bvh = cellray::build_minmax_bvh(mesh);
    parts.push_back({mesh, &bvh});
  };
  add_part(tets, tet_bvh, scene.tets);
  add_part(hexes, hex_bvh, scene.hexes);
  vec3 lo, hi;
  scene.bounds(lo, hi);
  vec3 const c = 0.5f * (lo + hi), ext = hi - lo;
  float const size = std::max(ext.x, std::max(ext.y, ext.z));

  // The host's geometry (y up, as fit_camera frames it): quads of two
  // triangles, the ground's first.
  std::vector<vec3> verts;
  std::vector<unsigned> tris;
  auto quad = [&](vec3 a, vec3 b, vec3 c2, vec3 d) {
    unsigned const i = unsigned(verts.size());
    verts.insert(verts.end(), {a, b, c2, d});
    tris.insert(tris.end(), {i, i + 1, i + 2, i, i + 2, i + 3});
  };
  float const g = lo.y - 0.05f * size, r = 3.f * size;
  quad({c.x - r, g, c.z - r}, {c.x - r, g, c.z + r}, {c.x + r, g, c.z + r}, {c.x + r, g, c.z - r});
  vec3 const p0{c.x + 0.1f * ext.x, g, c.z + 0.2f * ext.z};  // the pillar: partly inside the mesh
  vec3 const p1{p0.x + 0.12f * size, hi.y + 0.1f * size, p0.z + 0.12f * size};
  vec3 const box[8] = {{p0.x, p0.y, p0.z}, {p1.x, p0.y, p0.z}, {p1.x, p0.y, p1.z}, {p0.x, p0.y, p1.z},
                       {p0.x, p1.y, p0.z}, {p1.x, p1.y, p0.z}, {p1.x, p1.y, p1.z}, {p0.x, p1.y, p1.z}};
  for (int s = 0; s < 4; ++s) quad(box[s], box[(s + 1) % 4], box[4 + (s + 1) % 4], box[4 + s]);
  quad(box[4], box[5], box[6], box[7]);

  RTCDevice device = rtcNewDevice(nullptr);
  if (!device) throw std::runtime_error("Embree: no device");
  RTCScene rtc = rtcNewScene(device);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  std::copy(verts.begin(), verts.end(), static_cast<vec3*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, sizeof(vec3), verts.size())));
  std::copy(tris.begin(), tris.end(), static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), tris.size() / 3)));
  rtcCommitGeometry(geom);
  rtcAttachGeometry(rtc, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(rtc);

  // One camera ray per pixel centre, unit direction: Embree's t is then the
  // distance cellray's depth_in and Ray::tmax mean.
  int const W = 640, H = 480;
  cellray::Camera const cam = cellray::fit_camera(lo, hi, W, H);
  std::vector<cellray::Ray> rays(size_t(W) * H);
  std::vector<float> depth(rays.size());  // Embree's hit distance, +inf on a miss
  cellray::Image geometry(W, H);          // Lambert-shaded triangles over the sky, alpha 1
  vec3 const light = glm::normalize(vec3(0.4f, 1.f, 0.6f)), sky{0.33f, 0.37f, 0.43f};
  tbb::parallel_for(0, H, [&](int y) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (int x = 0; x < W; ++x) {
      size_t const i = size_t(y) * W + x;
      vec3 const d = glm::normalize(cam.direction(x + 0.f, y + 0.f));
      RTCRayHit rh{};
      rh.ray.org_x = cam.eye.x, rh.ray.org_y = cam.eye.y, rh.ray.org_z = cam.eye.z;
      rh.ray.dir_x = d.x, rh.ray.dir_y = d.y, rh.ray.dir_z = d.z;
      rh.ray.tfar = inf, rh.ray.mask = ~0u;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(rtc, &ctx, &rh);
      depth[i] = rh.ray.tfar;  // untouched (+inf) on a miss
      rays[i] = {cam.eye, 0.f, d, depth[i]};
      vec3 colour = sky;
      if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
        vec3 const p = cam.eye + depth[i] * d, n = glm::normalize(vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z));
        float const square = 0.2f * size;  // of the checkerboard
        bool const dark = (int(std::floor((p.x - c.x) / square)) + int(std::floor((p.z - c.z) / square))) & 1;
        vec3 const base = rh.hit.primID < 2 ? (dark ? vec3(0.35f) : vec3(0.7f)) : vec3(0.3f, 0.55f, 0.8f);
        colour = base * (0.3f + 0.7f * std::abs(glm::dot(n, light)));
      }
      float* px = geometry.pixel(x, y);
      px[0] = colour.r, px[1] = colour.g, px[2] = colour.b, px[3] = 1.f;
    }
  });
  rtcReleaseScene(rtc);
  rtcReleaseDevice(device);

  cellray::Image composite(W, H), volume(W, H);  // `volume`: the layer alone, premultiplied
  if (!iso_mode) {
    // DVR of the host's rays, each over [0, Embree's t]: premultiplied RGBA, no background.
    cellray::DvrParams dvr;
    dvr.tf = cellray::transfer_function_preset("inferno", vmin, vmax);
    dvr.tf.unit_distance = glm::length(ext) / 40.f;
    cellray::DvrFrame const frame(scene, dvr);  // prepared once, for every call below
    std::vector<float> vol(rays.size() * 4);
    cellray::integrate_rays(frame, rays.data(), rays.size(), vol.data());
    for (size_t k = 0; k < vol.size(); ++k)
      composite.rgba[k] = vol[k] + (1.f - vol[k | 3]) * geometry.rgba[k];  // "over"; k | 3: its alpha
    if (layers) {
      for (auto& ray : rays) ray.tmax = inf;
      cellray::integrate_rays(frame, rays.data(), rays.size(), volume.rgba.data());
    }
  } else {
    // An opaque isosurface into a FrameBuffer: rays end at depth_in, depth_out
    // is each pixel's surface distance (+inf: none); the nearer one wins.
    cellray::IsoParams iso;
    iso.surfaces = {{0.5f * (vmin + vmax), {0.95f, 0.6f, 0.25f}, 1.f}};
    iso.background = {0.f, 0.f, 0.f, 0.f};
    cellray::Image surface(W, H);
    std::vector<float> surface_t(rays.size());
    cellray::FrameBuffer fb = cellray::FrameBuffer::of(surface);
    fb.depth_in = depth.data();
    fb.depth_out = surface_t.data();
    cellray::render(scene, cam, iso, fb);
    for (size_t i = 0; i < rays.size(); ++i)
      for (size_t k = 0; k < 4; ++k)
        composite.rgba[4 * i + k] = (surface_t[i] < depth[i] ? surface : geometry).rgba[4 * i + k];
    if (layers) cellray::render(scene, cam, iso, cellray::FrameBuffer::of(volume));
  }
  cellray::write_image(out, composite);
  if (layers) {
    std::string const stem = out.substr(0, out.rfind('.'));
    cellray::write_image(stem + ".geometry.png", geometry);
    cellray::write_image(stem + ".volume.png", volume);
  }
  return 0;
} catch (std::exception const& e) {
  std::cerr << "04_embree_host: " << e.what() << "\n";
  return 1;
}
