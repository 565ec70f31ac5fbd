#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/bvh/refit.hpp>
#include <cellray/mesh/cell_boxes.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/render.hpp>

#include "support/adversarial.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_limits_indices {

// Index arithmetic beyond 2^31 and 2^32, on views whose index values and
// counts are that large without allocating that much: the arrays are
// anonymous MAP_NORESERVE mappings (tens of GB of address space, zero pages
// until written); a test writes only the few cells and vertices it uses, so
// it commits a few pages. The oracle is the same cells read from a small
// array (brute-force boxes, or the same mesh with small ids).

using namespace cellray;

namespace {

using test::Reservation;

constexpr uint64_t two31 = uint64_t(1) << 31, two32 = uint64_t(1) << 32;

std::vector<Isa> isas_here() {
  std::vector<Isa> out;
  for (Isa i : all_isas)
    if (isa_available(i)) out.push_back(i);
  return out;
}

/// Boxes of cells `cells` of `mesh`, computed directly (the oracle).
template <int N> ItemBox brute_box(CellMesh<N> const& mesh, uint64_t c) {
  ItemBox b{glm::vec3(INFINITY), INFINITY, glm::vec3(-INFINITY), -INFINITY};
  for (int k = 0; k < N; ++k) {
    uint64_t const v = mesh.vertex(c, k);
    b.lo = glm::min(b.lo, mesh.position(v));
    b.hi = glm::max(b.hi, mesh.position(v));
    b.vmin = std::min(b.vmin, mesh.value(v));
    b.vmax = std::max(b.vmax, mesh.value(v));
  }
  return b;
}

/// Fraction of pixels with a channel more than 2/255 from the reference.
double fraction_off(Image const& a, Image const& b) {
  REQUIRE(a.rgba.size() == b.rgba.size());
  size_t off = 0;
  for (size_t i = 0; i < a.rgba.size(); i += 4) {
    bool bad = false;
    for (int k = 0; k < 4; ++k) bad = bad || std::fabs(a.rgba[i + size_t(k)] - b.rgba[i + size_t(k)]) > 2.f / 255.f;
    off += bad;
  }
  return double(off) / double(a.rgba.size() / 4);
}

bool same(ItemBox const& a, ItemBox const& b) { return std::memcmp(&a, &b, sizeof(ItemBox)) == 0; }

/// Cells [c - 3, c + 5) around each boundary where cell id or cell id x
/// corners crosses 2^31 or 2^32.
template <int N> std::vector<uint64_t> boundary_cells() {
  std::vector<uint64_t> out;
  for (uint64_t edge : {two31 / N, two32 / N, two31, two32}) out.push_back(edge - 3);
  return out;
}

template <int N> void check_cell_boxes_at_huge_cell_ids(Reservation const& ids) {
  constexpr uint64_t cells = two32 + 16;
  auto* idx = ids.as<uint32_t>();
  // A small vertex set (a 3x3x3 lattice, values = id) that every test cell uses.
  std::vector<float> xyz, val;
  for (int v = 0; v < 27; ++v) {
    xyz.insert(xyz.end(), {float(v % 3), float(v / 3 % 3) * 1.5f, float(v / 9) * 0.75f});
    val.push_back(float(v) * 0.25f);
  }
  CellMesh<N> const mesh{view(xyz), Span<uint32_t>(idx, cells * N), view(val)};
  REQUIRE(mesh.cell_count() == cells);
  std::vector<uint64_t> const starts = boundary_cells<N>();
  for (uint64_t s : starts)
    for (uint64_t c = s; c < s + 8; ++c)
      for (int k = 0; k < N; ++k) idx[c * N + uint64_t(k)] = uint32_t((c * 7 + uint64_t(k) * 5) % 27);
  for (Isa isa : isas_here())
    for (uint64_t s : starts) {
      INFO(isa_name(isa) << ", cells from " << s);
      ItemBox out[8];
      float vmin[8], vmax[8];
      dispatch<CellBoxes>(isa, mesh, s, s + 8, out);
      dispatch<CellRanges>(isa, mesh, s, s + 8, vmin, vmax);
      for (uint64_t i = 0; i < 8; ++i) {
        ItemBox const ref = brute_box(mesh, s + i);
        CHECK(same(out[i], ref));
        CHECK(vmin[i] == ref.vmin);
        CHECK(vmax[i] == ref.vmax);
      }
    }
}

}  // namespace

TEST_CASE("BVH leaf encoding keeps item-list slots beyond 2^31 and 2^32", "[limits][bvh]") {
  for (uint64_t slot : {two31 - 1, two31, two32 - 1, two32, two32 + 5, (uint64_t(1) << 40) + 3, (uint64_t(1) << 56) - 1})
    for (uint32_t items : {1u, 7u, Node::max_leaf_items}) {
      Node n{};
      n.set_leaf(slot, items);
      CHECK(n.is_leaf());
      CHECK(n.first_item() == slot);
      CHECK(n.item_count() == items);
    }
}

TEST_CASE("cell boxes and ranges are right for cell ids and index offsets beyond 2^31 and 2^32", "[limits][mesh]") {
  // (2^32 + 16) hexahedra of 32-bit ids: 128 GiB of address space, a few pages used.
  Reservation const ids((two32 + 16) * 8 * sizeof(uint32_t));
  if (!ids) {
    WARN("cannot reserve 128 GiB of address space here (overcommit policy); test skipped");
    return;
  }
  SECTION("tetrahedra") { check_cell_boxes_at_huge_cell_ids<4>(ids); }
  SECTION("hexahedra") { check_cell_boxes_at_huge_cell_ids<8>(ids); }
}

TEST_CASE("vertex ids beyond 2^31 and 2^32 build the same tree and render the same images", "[limits][render]") {
  // 64-bit vertex ids into position and value arrays of 2^32 + 2^20 vertices
  // (48 + 16 GiB of address space); the mesh's own vertices sit at `base`.
  constexpr uint64_t nv_total = two32 + (uint64_t(1) << 20);
  Reservation const xyz_space(nv_total * 3 * sizeof(float)), val_space(nv_total * sizeof(float));
  if (!xyz_space || !val_space) {
    WARN("cannot reserve 64 GiB of address space here (overcommit policy); test skipped");
    return;
  }
  auto const small = generate_tets(3000, 5);
  uint64_t const nv = small.field.size();
  std::vector<uint64_t> small_ids(small.cells.begin(), small.cells.end());
  TetMesh const ref{view(small.xyz), view(small_ids), view(small.field)};
  MinMaxBvh const ref_bvh = build_minmax_bvh(ref);
  Camera const cam = Camera::look_at({0.5f, 0.8f, 3.f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 40.f, 40, 30);
  IsoParams iso;
  iso.surfaces = {{0.3f, {0.9f, 0.5f, 0.2f}, 0.5f}, {0.5f, {0.2f, 0.6f, 0.9f}, 1.f}};
  DvrParams dvr;
  dvr.tf = transfer_function_preset("viridis", 0.1f, 0.8f);

  for (uint64_t base : {two31 - nv / 2, two32 - nv / 2, two32 + 12345}) {
    INFO("vertex ids from " << base);
    float* xyz = xyz_space.as<float>();
    float* val = val_space.as<float>();
    std::memcpy(xyz + 3 * base, small.xyz.data(), small.xyz.size() * sizeof(float));
    std::memcpy(val + base, small.field.data(), small.field.size() * sizeof(float));
    std::vector<uint64_t> ids(small_ids);
    for (auto& v : ids) v += base;
    TetMesh const big{Span<float>(xyz, nv_total * 3), view(ids), Span<float>(val, nv_total)};
    REQUIRE(big.vertex_count() == nv_total);
    for (Isa isa : isas_here()) {
      INFO(isa_name(isa));
      BuildOptions bo;
      bo.isa = isa;
      MinMaxBvh const bvh = build_minmax_bvh(big, bo);
      REQUIRE(bvh.node_count() == ref_bvh.node_count());
      CHECK(std::memcmp(bvh.nodes(), ref_bvh.nodes(), bvh.node_count() * sizeof(Node)) == 0);
      CHECK(refit_ranges(bvh, big, isa) == ref_bvh.ranges());
      RenderOptions o;
      o.isa = isa;
      Image const a = render_iso(Scene(big, bvh), cam, iso, o), b = render_dvr(Scene(big, bvh), cam, dvr, o);
      Image const ra = render_iso(Scene(ref, ref_bvh), cam, iso, o), rb = render_dvr(Scene(ref, ref_bvh), cam, dvr, o);
      // The kernels order a tet's corners by the low 31 bits of their vertex
      // ids (a watertightness tie-break, cells/corners.hpp). Ids that do not
      // cross a multiple of 2^31 keep the small mesh's order: bit-identical
      // images. Ids that cross it reorder some corners: the same surfaces up
      // to float rounding, so at most 1% of pixels may differ by over 2/255.
      bool const same_order = (base >> 31) == ((base + nv) >> 31);
      if (same_order) {
        CHECK(a.rgba == ra.rgba);
        CHECK(b.rgba == rb.rgba);
      } else {
        CHECK(fraction_off(a, ra) <= 0.01);
        CHECK(fraction_off(b, rb) <= 0.01);
      }
    }
  }
}

TEST_CASE("a BVH with 64-bit item ids renders the same images as one with 32-bit ids", "[limits][render]") {
  auto const g = generate_hexes(3000, 3);
  HexMesh const m = g.mesh();
  BuildOptions wide;
  wide.wide_items = true;
  MinMaxBvh const narrow_bvh = build_minmax_bvh(m), wide_bvh = build_minmax_bvh(m, wide);
  REQUIRE(wide_bvh.wide_items());
  REQUIRE_FALSE(narrow_bvh.wide_items());
  Camera const cam = Camera::look_at({2.5f, 1.f, 2.f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 40.f, 37, 29);
  IsoParams iso;
  iso.surfaces = {{0.4f}};
  DvrParams dvr;
  dvr.tf = transfer_function_preset("inferno", 0.1f, 0.8f);
  dvr.mode = DvrMode::segments;
  CHECK(render_iso(Scene(m, wide_bvh), cam, iso).rgba == render_iso(Scene(m, narrow_bvh), cam, iso).rgba);
  CHECK(render_dvr(Scene(m, wide_bvh), cam, dvr).rgba == render_dvr(Scene(m, narrow_bvh), cam, dvr).rgba);
}

}  // namespace test_limits_indices
