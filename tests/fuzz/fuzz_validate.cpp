// libFuzzer harness: validate() on small meshes decoded from the input
// (tets or hexes, 32- or 64-bit indices, positions and values drawn from a
// palette that includes NaN, infinities, huge, tiny and denormal numbers,
// out-of-range vertex ids), checked against a brute-force count; then the
// promise validate() makes: when it reports ok, the BVH builds and iso and
// DVR renders (every ISA the CPU has) finish with finite pixels in [0, 1];
// when it does not, the build throws InvalidMesh.

#include <cfloat>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/render/render.hpp>

#include "fuzz_common.hpp"

namespace {

using cellray::fuzz::require;

/// Reads the input front to back; past the end it yields zeros, so every
/// input decodes to some mesh.
struct Bytes {
  uint8_t const* p;
  size_t n;
  uint8_t next() {
    if (n == 0) return 0;
    --n;
    return *p++;
  }
  float raw_float() {
    uint8_t b[4] = {next(), next(), next(), next()};
    float f;
    std::memcpy(&f, b, 4);
    return f;
  }
};

constexpr float nan_f = std::numeric_limits<float>::quiet_NaN();
constexpr float inf_f = std::numeric_limits<float>::infinity();

float special(uint8_t k) {
  static constexpr float table[16] = {nan_f, inf_f, -inf_f, 0.f,   1e30f, -1e30f, FLT_MAX, 1e-30f,
                                      -0.f,  1e7f,  1e-7f,  1.f,   -1.f,  0.5f,   1e-40f,  2.f};
  return table[k % 16];
}

/// Mostly points of a jittered 8^3 lattice over [-2, 2]^3 (so cells are often
/// valid), sometimes a special value or 4 raw bytes.
float coordinate(Bytes& in) {
  uint8_t const c = in.next();
  if (c < 224) return (float(c % 8) - 3.5f) * 0.5f + float(c / 8) * 0.01f;
  if (c < 240) return special(c);
  return in.raw_float();
}

float scalar(Bytes& in) {
  uint8_t const c = in.next();
  if (c < 240) return float(c) / 240.f * 1.2f - 0.1f;
  if (c < 250) return special(c);
  return in.raw_float();
}

uint64_t vertex_id(Bytes& in, uint64_t nv) {
  uint8_t const c = in.next();
  switch (c) {
    case 250: return nv;  // one past the end
    case 251: return nv + 1000;
    case 252: return 0xFFFFFFFFull;
    case 253: return 1ull << 32;
    case 254: return ~0ull;
    default: return c % nv;
  }
}

void check_image(cellray::Image const& img, int w, int h) {
  require(img.width == w && img.height == h && img.rgba.size() == size_t(w) * size_t(h) * 4, "image size");
  for (size_t i = 0; i < img.rgba.size(); ++i)
    if (!(std::isfinite(img.rgba[i]) && img.rgba[i] >= 0.f && img.rgba[i] <= 1.f)) {
      std::fprintf(stderr, "pixel %zu channel %zu = %.9g\n", i / 4, i % 4, double(img.rgba[i]));
      cellray::fuzz::fail("pixel not finite or outside [0, 1]");
    }
}

template <int N, class Index>
void run(Bytes& in, uint8_t flags, uint8_t tuning, uint64_t nv, uint64_t nc, float iso_value, cellray::Isa isa) {
  int const frame = (flags >> 4) & 3;
  float const scale = frame == 2 ? 1e-7f : frame == 3 ? 1e3f : 1.f;
  float const offset = frame == 1 ? 1e7f : 0.f;
  std::vector<float> xyz(nv * 3), values(nv);
  std::vector<Index> cells(nc * N);
  for (float& x : xyz) x = coordinate(in) * scale + offset;
  for (auto& v : cells) v = Index(vertex_id(in, nv));
  for (float& v : values) v = scalar(in);
  cellray::CellMesh<N> const mesh{cellray::view(xyz), cellray::view(cells), cellray::view(values), "f"};

  cellray::ValidationReport const rep = cellray::validate(mesh);
  uint64_t bad_cells = 0, bad_positions = 0, unused_bad_positions = 0, bad_values = 0;  // brute-force oracle
  uint64_t last_bad_cell = 0;
  std::vector<bool> used(nv, false);
  for (uint64_t c = 0; c < nc; ++c) {
    bool bad = false;
    for (int k = 0; k < N; ++k) {
      uint64_t const v = uint64_t(cells[c * N + uint64_t(k)]);
      bad = bad || v >= nv;
      if (v < nv) used[v] = true;
    }
    bad_cells += bad;
    if (bad) last_bad_cell = c;
  }
  for (uint64_t v = 0; v < nv; ++v) {
    bool const finite = std::isfinite(xyz[3 * v]) && std::isfinite(xyz[3 * v + 1]) && std::isfinite(xyz[3 * v + 2]);
    (used[v] ? bad_positions : unused_bad_positions) += !finite;
    bad_values += used[v] && !std::isfinite(values[v]);  // values no cell reads are not counted
  }
  require(rep.cells == nc && rep.vertices == nv, "report counts");
  require(rep.bad_index.count == bad_cells, "bad index count differs from brute force");
  require(rep.nonfinite_position.count == bad_positions, "non-finite position count differs from brute force");
  require(rep.unused_nonfinite_position.count == unused_bad_positions,
          "unused non-finite position count differs from brute force");
  require(rep.nonfinite_value.count == bad_values, "non-finite value count differs from brute force");
  require(rep.ok() == (bad_cells == 0 && bad_positions == 0), "ok() differs from brute force");
  // Each cell with ids in range is of one kind and at most one of flat,
  // inverted or distorted.
  require(rep.kinds.total() == (N == 8 ? nc - bad_cells : 0), "cell kinds do not add up to the cells with ids in range");
  require(rep.inverted_kinds.total() == (N == 8 ? rep.inverted.count : 0) &&
              rep.distorted_kinds.total() == rep.distorted.count &&
              rep.zero_volume_kinds.total() == (N == 8 ? rep.zero_volume.count : 0),
          "findings by kind do not add up");
  require(rep.zero_volume.count + rep.inverted.count + rep.distorted.count <= nc - bad_cells,
          "a cell counted under two shape findings");
  require(N == 8 || !rep.distorted, "a tetrahedron reported distorted");
  (void)rep.message();
  // Named by cell ids given in reverse (a reader's file ids, a rank's global
  // ones): the same counts, and "first" the smallest id among the findings.
  std::vector<uint64_t> reversed(nc);
  for (uint64_t c = 0; c < nc; ++c) reversed[c] = 1000 + (nc - 1 - c);
  cellray::ValidationReport const named = cellray::validate(mesh, cellray::view(reversed));
  auto same = [&](cellray::Finding const& a, cellray::Finding const& b) {
    return a.count == b.count && (!a || (b.first >= 1000 && b.first < 1000 + nc));
  };
  require(same(rep.bad_index, named.bad_index) && same(rep.zero_volume, named.zero_volume) &&
              same(rep.inverted, named.inverted) && same(rep.distorted, named.distorted),
          "findings named by cell ids differ from those named by index");
  require(!bad_cells || named.bad_index.first == 1000 + (nc - 1 - last_bad_cell),
          "the first bad cell by id is not the last by index");
  require(named.nonfinite_position.first == rep.nonfinite_position.first, "vertex ids changed with cell ids");

  cellray::BuildOptions bo;
  bo.isa = isa;
  bo.max_leaf_size = 1 + tuning % 8;
  bo.builder = cellray::BvhBuilder((tuning >> 3) % 3);
  if (!rep.ok()) {
    bool threw = false;
    try {
      (void)cellray::build_minmax_bvh(mesh, bo);
    } catch (cellray::InvalidMesh const&) {
      threw = true;
    }
    // A non-finite vertex no cell uses does not stop the build.
    require(threw || bad_cells == 0, "build accepted a mesh with a bad vertex id");
    return;
  }
  cellray::MinMaxBvh const bvh = cellray::build_minmax_bvh(mesh, bo);
  require(bvh.item_count() == nc, "BVH item count");

  cellray::Scene const scene(mesh, bvh);
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  int const w = 7, h = 5;  // not a multiple of any SIMD width
  cellray::Camera cam;
  cam.width = w, cam.height = h;
  try {
    cam = cellray::fit_camera(lo, hi, w, h);
  } catch (cellray::InvalidArgument const&) {  // empty or one-point bounds: keep the default camera
  }
  cellray::RenderOptions ro;
  ro.isa = isa;
  ro.traversal = cellray::Traversal((tuning >> 5) % 3);
  cellray::IsoParams ip;
  ip.surfaces = {{iso_value, {0.8f, 0.8f, 0.8f}, 0.7f}, {0.5f, {0.2f, 0.5f, 0.9f}, 1.f}};
  ip.shadows = (flags & 0x40) != 0;
  check_image(cellray::render_iso(scene, cam, ip, ro), w, h);
  cellray::DvrParams dp;
  dp.tf = cellray::transfer_function_preset("viridis", 0.f, 1.f);
  dp.mode = (flags & 0x80) ? cellray::DvrMode::segments : cellray::DvrMode::samples;
  check_image(cellray::render_dvr(scene, cam, dp, ro), w, h);
  if constexpr (N == 4) {
    // Face neighbours of whatever the input made (duplicated, overlapping,
    // degenerate cells): DVR segments and AO rays march through them.
    cellray::TetNeighbours const nb = cellray::build_tet_neighbours(mesh);
    require(nb.cell_count() == nc, "face neighbours cell count");
    for (uint64_t c = 0; c < nc; ++c)
      for (int f = 0; f < 4; ++f) {
        int32_t const o = nb.across(c, f);
        require(o >= -1 && o < int32_t(nc) && o != int32_t(c), "face neighbour out of range or the cell itself");
      }
    cellray::Scene const marched(mesh, bvh, nullptr, &nb);
    ip.ao_samples = 2;
    check_image(cellray::render_iso(marched, cam, ip, ro), w, h);
    dp.mode = cellray::DvrMode::segments;
    check_image(cellray::render_dvr(marched, cam, dp, ro), w, h);
  } else {
    // A mixed scene over the same vertices: tets made of each cell's
    // corners 0 1 3 4 (overlapping the hexahedra, sharing whatever
    // triangles the input's repeated ids make), both parts' neighbours
    // linked (link_face_neighbours), DVR segments marching across them.
    std::vector<Index> tet_ids;
    for (uint64_t c = 0; c < nc; ++c)
      for (int k : {0, 1, 3, 4}) tet_ids.push_back(cells[c * N + uint64_t(k)]);
    cellray::TetMesh const tets{cellray::view(xyz), cellray::view(tet_ids), cellray::view(values), "f"};
    cellray::MinMaxBvh const tet_bvh = cellray::build_minmax_bvh(tets, bo);
    cellray::TetNeighbours tn = cellray::build_tet_neighbours(tets);
    cellray::HexNeighbours hn = cellray::build_hex_neighbours(mesh);
    cellray::link_face_neighbours(tets, tn, mesh, hn);
    for (uint64_t c = 0; c < nc; ++c) {
      for (int f = 0; f < 4; ++f) {
        int32_t const o = tn.across(c, f);
        require(o != int32_t(c) && o < int32_t(nc) && o >= -1 - int32_t(nc), "linked tet neighbour out of range");
      }
      for (int f = 0; f < 6; ++f) {
        int32_t const o = hn.across(c, f);
        require(o != int32_t(c) && o < int32_t(nc) && o >= -1 - int32_t(nc), "linked hex neighbour out of range");
      }
    }
    cellray::Scene mixed;
    mixed.tets.push_back({tets, &tet_bvh, nullptr, &tn});
    mixed.hexes.push_back({mesh, &bvh, nullptr, nullptr, &hn});
    dp.mode = cellray::DvrMode::segments;
    check_image(cellray::render_dvr(mixed, cam, dp, ro), w, h);
    ip.ao_samples = 2;  // AO rays march across the linked parts
    check_image(cellray::render_iso(mixed, cam, ip, ro), w, h);
    // The hexahedra alone with their own (unlinked) neighbours: AO rays
    // march through them.
    cellray::HexNeighbours const own = cellray::build_hex_neighbours(mesh);
    check_image(cellray::render_iso(cellray::Scene(mesh, bvh, nullptr, &own), cam, ip, ro), w, h);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(uint8_t const* data, size_t size) {
  Bytes in{data, size};
  uint8_t const flags = in.next();
  uint64_t const nv = 1 + in.next() % 48;
  uint64_t const nc = in.next() % 24;
  float const iso_value = scalar(in);
  uint8_t const tuning = in.next();  // leaf size, builder, traversal
  if (!std::isfinite(iso_value)) return 0;  // render_iso rejects it (documented); not this harness's subject
  cellray::Isa isa = cellray::Isa((flags >> 2) & 3);
  if ((int(isa) > 2) || !cellray::isa_available(isa)) isa = cellray::best_isa();
  bool const hex = flags & 1, wide = flags & 2;
  if (hex && wide) run<8, uint64_t>(in, flags, tuning, nv, nc, iso_value, isa);
  else if (hex) run<8, uint32_t>(in, flags, tuning, nv, nc, iso_value, isa);
  else if (wide) run<4, uint64_t>(in, flags, tuning, nv, nc, iso_value, isa);
  else run<4, uint32_t>(in, flags, tuning, nv, nc, iso_value, isa);
  return 0;
}
