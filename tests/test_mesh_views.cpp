#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <map>
#include <array>
#include <algorithm>
#include <set>
#include <variant>
#include <vector>

#include <sys/mman.h>

#include <cellray/mesh/cell_types.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/mesh/vtk_cells.hpp>

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_mesh_views {

using namespace cellray;

TEST_CASE("mesh views point at the host arrays and check sizes", "[mesh]") {
  std::vector<float> xyz = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<uint64_t> idx = {0, 1, 2, 3};
  std::vector<float> a = {1, 2, 3, 4}, b = {5, 6, 7, 8};
  TetMesh m{view(xyz), view(idx), view(a), "a"};
  m.add_array("b", view(b));
  CHECK(m.positions() == xyz.data());
  CHECK(m.indices64() == idx.data());
  CHECK_FALSE(m.has_32bit_indices());
  CHECK(m.values() == a.data());
  CHECK(m.with_array("b").values() == b.data());
  CHECK(m.vertex(0, 3) == 3);
  CHECK(m.viewed_bytes() == xyz.size() * 4 + idx.size() * 8 + 8 * 4);
  CHECK_THROWS_WITH(m.with_array("c"), Catch::Contains("no scalar array 'c'") && Catch::Contains("a, b"));
  std::vector<float> short_values = {1, 2};
  CHECK_THROWS_AS(m.add_array("s", view(short_values)), InvalidMesh);
  std::vector<uint32_t> ragged = {0, 1, 2};
  CHECK_THROWS_WITH((TetMesh{view(xyz), view(ragged)}), Catch::Contains("not a multiple of 4"));
}

TEST_CASE("64-bit offsets: a cell past 2^31 entries addresses the right entry", "[mesh]") {
  // 2^31 + 48 index entries reserved as virtual memory only (MAP_NORESERVE):
  // just the page written below is ever backed by RAM.
  uint64_t const cell = (uint64_t(1) << 31) / 8 + 5;
  size_t const bytes = size_t(cell + 1) * 8 * sizeof(uint32_t);
  void* mem = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  REQUIRE(mem != MAP_FAILED);
  auto* idx = static_cast<uint32_t*>(mem);
  for (int k = 0; k < 8; ++k) idx[cell * 8 + uint64_t(k)] = uint32_t(11 + k);
  HexMesh m{Span<float>(), Span<uint32_t>(idx, (cell + 1) * 8)};
  CHECK(m.cell_count() == cell + 1);
  CHECK(m.vertex(cell, 7) == 18);
  CHECK(m.vertex(cell, 0) == 11);
  munmap(mem, bytes);
}

TEST_CASE("generated meshes are conforming, positively oriented and carry the analytic field", "[mesh]") {
  auto tets = generate_tets(6000, 3);
  auto hexes = generate_hexes(1000, 3);
  CHECK(tets.mesh().cell_count() == 6u * 10 * 10 * 10);
  CHECK(hexes.mesh().cell_count() == 1000u);
  for (auto const& rep : {validate(tets.mesh()), validate(hexes.mesh())}) {
    INFO(rep.message());
    CHECK(rep.ok());
    CHECK_FALSE(rep.has_warnings());
    CHECK(rep.value_min > 0.0f);
    CHECK(rep.value_max < 1.2f);
    CHECK(rep.value_max - rep.value_min > 0.6f);  // structure, not a constant
  }
  // Conforming: every interior triangle is shared by exactly two tets,
  // boundary triangles (on the cube faces) by one.
  auto m = tets.mesh();
  std::map<std::array<uint64_t, 3>, int> faces;
  for (uint64_t c = 0; c < m.cell_count(); ++c)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<uint64_t, 3> f{};
      int n = 0;
      for (int k = 0; k < 4; ++k)
        if (k != skip) f[size_t(n++)] = m.vertex(c, k);
      std::sort(f.begin(), f.end());
      ++faces[f];
    }
  int boundary = 0;
  for (auto const& [f, count] : faces) {
    REQUIRE(count <= 2);
    if (count == 1) {
      ++boundary;
      bool on_cube_face = false;
      for (int axis = 0; axis < 3; ++axis) {
        float const c0 = tets.xyz[3 * f[0] + axis];
        on_cube_face |= std::fabs(std::fabs(c0) - 1.f) < 1e-6f && c0 == tets.xyz[3 * f[1] + axis] &&
                        c0 == tets.xyz[3 * f[2] + axis];
      }
      CHECK(on_cube_face);
    }
  }
  CHECK(boundary == 6 * 10 * 10 * 2);
  // Interior vertices are jittered, values are the analytic field.
  CHECK(hexes.xyz[3 * (11 * 11 + 11 + 1)] != Approx(-0.8f).margin(1e-6));
  for (size_t v = 0; v < hexes.field.size(); v += 97)
    CHECK(hexes.field[v] == analytic_field({hexes.xyz[3 * v], hexes.xyz[3 * v + 1], hexes.xyz[3 * v + 2]}, 0.f));
}

TEST_CASE("validate names bad indices, non-finite data, flat and inverted cells", "[mesh]") {
  float const nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> xyz = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 0, nan, 0, 0, 0, nan, 0};
  std::vector<float> val = {0, 1, 2, nan, 4, 5, nan};  // vertex 6's NaN: no cell uses it, so no finding
  std::vector<uint32_t> idx = {
      0, 1, 2, 3,  // fine
      0, 2, 1, 3,  // inverted
      0, 1, 2, 4,  // flat (4 lies in the plane of 0, 1, 2)
      0, 1, 2, 9,  // index out of range
      0, 1, 2, 9,  // again (count 2, first 3)
      0, 1, 3, 5,  // uses vertex 5, whose position is NaN (vertex 6's is too, but no cell uses it)
  };
  TetMesh m{view(xyz), view(idx), view(val)};
  auto rep = validate(m);
  CHECK_FALSE(rep.ok());
  CHECK(rep.bad_index.count == 2);
  CHECK(rep.bad_index.first == 3);
  CHECK(rep.nonfinite_position.count == 1);
  CHECK(rep.nonfinite_position.first == 5);
  CHECK(rep.unused_nonfinite_position.count == 1);
  CHECK(rep.unused_nonfinite_position.first == 6);
  CHECK(rep.nonfinite_value.count == 1);
  CHECK(rep.nonfinite_value.first == 3);
  CHECK(rep.inverted.count == 1);
  CHECK(rep.inverted.first == 1);
  CHECK(rep.zero_volume.count == 2);  // cell 2, and cell 5 (its NaN corner has no volume)
  CHECK(rep.zero_volume.first == 2);
  CHECK(rep.value_min == 0.f);
  CHECK(rep.value_max == 5.f);
  CHECK_THAT(rep.message(), Catch::Contains("2 cells with a vertex index out of range (first cell 3)"));
  CHECK_THROWS_AS(require_valid(rep), InvalidMesh);

  // A hexahedron with its top face folded through the bottom one is inverted;
  // one squashed to a plane is flat.
  std::vector<float> hx = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
  std::vector<uint32_t> hi = {0, 1, 2, 3, 4, 5, 6, 7, 4, 5, 6, 7, 0, 1, 2, 3};
  std::vector<float> flat = hx;
  for (size_t i = 2; i < flat.size(); i += 3) flat[i] = 0;
  auto hrep = validate(HexMesh{view(hx), view(hi)});
  CHECK(hrep.ok());
  CHECK(hrep.inverted.count == 1);
  CHECK(hrep.inverted.first == 1);
  CHECK(validate(HexMesh{view(flat), view(hi)}).zero_volume.count == 2);
}

TEST_CASE("validate tells concave and warped cells from inverted ones, and names the kinds a hexahedral view holds",
          "[mesh]") {
  // A unit cube (cell 0), the cube with corner 6 pushed in past the plane
  // of its three neighbours (cell 1: negative Jacobian at that corner, yet
  // positive volume), the cube listed mirrored (cell 2: inside out), a
  // wedge (3), a pyramid (4), a pyramid with its apex below its base (5)
  // and a tetrahedron (6), the last four stored as the readers store them.
  std::vector<float> xyz = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1,
                            0.3f, 0.3f, 0.3f,  // 8: the dent
                            0.5f, 0.5f, 1, 0.5f, 0.5f, -1};  // 9, 10: apexes
  auto as_hex = [](std::array<uint32_t, 8> const& ids, std::array<int, 8> const& order) {
    std::array<uint32_t, 8> h{};
    for (int k = 0; k < 8; ++k) h[size_t(k)] = ids[size_t(order[size_t(k)])];
    return h;
  };
  std::vector<std::array<uint32_t, 8>> cells = {
      {0, 1, 2, 3, 4, 5, 6, 7},
      {0, 1, 2, 3, 4, 5, 8, 7},
      {0, 3, 2, 1, 4, 7, 6, 5},
      as_hex({0, 3, 1, 4, 7, 5, 0, 0}, wedge_as_hex),  // VTK: the base's normal points away from the top
      as_hex({0, 1, 2, 3, 9, 0, 0, 0}, pyramid_as_hex),
      as_hex({0, 1, 2, 3, 10, 0, 0, 0}, pyramid_as_hex),
      as_hex({0, 1, 3, 4, 0, 0, 0, 0}, tet_as_hex),
  };
  std::vector<uint32_t> ids;
  for (auto const& c : cells) ids.insert(ids.end(), c.begin(), c.end());
  ValidationReport const rep = validate(HexMesh{view(xyz), view(ids)});
  CHECK(rep.ok());
  CHECK(rep.distorted.count == 1);
  CHECK(rep.distorted.first == 1);
  CHECK(rep.inverted.count == 2);
  CHECK(rep.inverted.first == 2);
  CHECK(!rep.zero_volume);
  // A concave cell is a note, not a warning: real meshes have them.
  std::vector<uint32_t> dented(ids.begin(), ids.begin() + 16);
  ValidationReport const only_dent = validate(HexMesh{view(xyz), view(dented)});
  CHECK(only_dent.distorted.count == 1);
  CHECK(!only_dent.inverted);
  CHECK_FALSE(only_dent.has_warnings());
  CHECK_THAT(only_dent.message(), Catch::Contains("2 hexahedra,") &&
                                      Catch::Contains("note: 1 cells with a negative Jacobian at a corner"));
  CHECK(rep.kinds[CollapsedKind::hexahedron] == 3);
  CHECK(rep.kinds[CollapsedKind::wedge] == 1);
  CHECK(rep.kinds[CollapsedKind::pyramid] == 2);
  CHECK(rep.kinds[CollapsedKind::tetrahedron] == 1);
  CHECK(rep.inverted_kinds[CollapsedKind::hexahedron] == 1);
  CHECK(rep.inverted_kinds[CollapsedKind::pyramid] == 1);
  CHECK(rep.distorted_kinds[CollapsedKind::hexahedron] == 1);
  CHECK_THAT(rep.message(),
             Catch::Contains("7 cells (3 hexahedra, 1 wedge, 2 pyramids, 1 tetrahedron)") &&
                 Catch::Contains("2 inverted cells (negative volume) (1 hexahedron, 1 pyramid; first cell 2)") &&
                 Catch::Contains("corner (positive volume: concave or warped) (1 hexahedron; first cell 1)"));
  // Kinds come from the faces' shapes, not the count of distinct ids: a
  // pyramid listed with its apex below (4 4 4 4 0 1 2 3) is one, a wedge
  // with one collapsed edge (OpenFOAM's tet-wedge: 5 ids) is not, nor is a
  // hexahedron with a collapsed edge (7 ids).
  auto kind = [](std::array<uint64_t, 8> const& a) {
    uint64_t v[8];
    for (int k = 0; k < 8; ++k) v[k] = a[size_t(k)];
    return collapsed_kind(v);
  };
  CHECK(kind({9, 9, 9, 9, 0, 1, 2, 3}) == CollapsedKind::pyramid);
  CHECK(kind({0, 2, 1, 1, 3, 3, 4, 4}) == CollapsedKind::other);
  CHECK(kind({0, 1, 2, 3, 4, 4, 6, 7}) == CollapsedKind::other);
  CHECK(kind({0, 1, 1, 0, 2, 3, 3, 2}) == CollapsedKind::other);  // 4 ids, two edges: no tetrahedron
  CHECK(kind({0, 1, 1, 0, 2, 2, 2, 2}) == CollapsedKind::fewer);
  CHECK(kind({0, 1, 2, 3, 4, 5, 6, 7}) == CollapsedKind::hexahedron);
  // The inverted pyramid alone is named as one.
  std::vector<uint32_t> below(ids.begin() + 5 * 8, ids.begin() + 6 * 8);
  CHECK_THAT(validate(HexMesh{view(xyz), view(below)}).message(),
             Catch::Contains("1 cells (1 pyramid)") && Catch::Contains("(1 pyramid; first cell 0)"));
}

TEST_CASE("The cell-type list: AnyCellMesh visits each view as its own type", "[mesh][types]") {
  std::vector<int> listed;
  for_each_cell_type([&](auto n) { listed.push_back(n()); });
  CHECK(listed == std::vector<int>{4, 8});
  CHECK(std::variant_size_v<PerCellType<CellMesh>> == listed.size());
  static_assert(is_cell_type<4> && is_cell_type<8> && !is_cell_type<6>);
  GeneratedMesh<4> const t = generate_tets(300, 3);
  GeneratedMesh<8> const h = generate_hexes(200, 3);
  TetMesh const tm = t.mesh();
  HexMesh const hm = h.mesh();
  for (AnyCellMesh const any : {AnyCellMesh(tm), AnyCellMesh(hm)}) {
    int const corners = any.visit([](auto const& m) { return std::decay_t<decltype(m)>::corners; });
    uint64_t const cells = corners == 4 ? tm.cell_count() : hm.cell_count();
    uint64_t const verts = corners == 4 ? tm.vertex_count() : hm.vertex_count();
    CHECK(any.cell_count() == cells);
    CHECK(any.vertex_count() == verts);
    // The visit hands over the host's view itself, not a copy.
    void const* seen = any.visit([](auto const& m) { return static_cast<void const*>(&m); });
    CHECK(seen == (corners == 4 ? static_cast<void const*>(&tm) : static_cast<void const*>(&hm)));
  }
}

}  // namespace test_mesh_views
