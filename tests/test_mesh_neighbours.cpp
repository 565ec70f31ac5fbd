// Face neighbours of tet meshes (mesh/neighbours.hpp) against a brute-force
// map from each face's sorted vertex triple to the cells that have it: the
// cell across face f shares exactly the three vertices other than the
// cell's f-th smallest, boundary faces have none, and so do faces of more
// than two cells and every face of a degenerate cell.

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <tbb/task_arena.h>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/mesh/validate.hpp>

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_mesh_neighbours {

using namespace cellray;

namespace {

using Face = std::array<uint64_t, 3>;

std::array<uint64_t, 4> sorted_ids(TetMesh const& m, uint64_t c) {
  std::array<uint64_t, 4> v{m.vertex(c, 0), m.vertex(c, 1), m.vertex(c, 2), m.vertex(c, 3)};
  std::sort(v.begin(), v.end());
  return v;
}

Face face_of(std::array<uint64_t, 4> const& v, int f) {
  Face out{};
  for (int i = 0, j = 0; i < 4; ++i)
    if (i != f) out[size_t(j++)] = v[size_t(i)];
  return out;
}

bool degenerate(std::array<uint64_t, 4> const& v) { return v[0] == v[1] || v[1] == v[2] || v[2] == v[3]; }

/// The expected neighbour of every (cell, face) by brute force.
std::vector<int32_t> expected(TetMesh const& m) {
  std::map<Face, std::vector<uint64_t>> cells_of;
  for (uint64_t c = 0; c < m.cell_count(); ++c) {
    auto const v = sorted_ids(m, c);
    if (degenerate(v)) continue;
    for (int f = 0; f < 4; ++f) cells_of[face_of(v, f)].push_back(c);
  }
  std::vector<int32_t> out(4 * m.cell_count(), -1);
  for (uint64_t c = 0; c < m.cell_count(); ++c) {
    auto const v = sorted_ids(m, c);
    if (degenerate(v)) continue;
    for (int f = 0; f < 4; ++f) {
      auto const& list = cells_of[face_of(v, f)];
      if (list.size() == 2) out[4 * c + uint64_t(f)] = int32_t(list[0] == c ? list[1] : list[0]);
    }
  }
  return out;
}

void check_against_brute_force(TetMesh const& m) {
  TetNeighbours const nb = build_tet_neighbours(m);
  REQUIRE(nb.cell_count() == m.cell_count());
  CHECK(nb.memory_bytes() == 16 * m.cell_count());
  std::vector<int32_t> const want = expected(m);
  int wrong = 0;
  for (uint64_t c = 0; c < m.cell_count(); ++c)
    for (int f = 0; f < 4; ++f) wrong += nb.across(c, f) != want[4 * c + uint64_t(f)];
  CHECK(wrong == 0);
}

}  // namespace

TEST_CASE("neighbours: a conforming jittered tet mesh", "[mesh][neighbours]") {
  auto const g = generate_tets(6 * 6 * 6 * 6, 2);
  TetMesh const m = g.mesh();
  check_against_brute_force(m);
  // Counted without the brute force: interior faces pair up, the cube's
  // surface (2 triangles per lattice square, 6 sides) has none.
  TetNeighbours const nb = build_tet_neighbours(m);
  uint64_t boundary = 0;
  for (uint64_t c = 0; c < m.cell_count(); ++c)
    for (int f = 0; f < 4; ++f) {
      int32_t const o = nb.across(c, f);
      if (o < 0) {
        ++boundary;
        continue;
      }
      // Symmetric: the neighbour has c across one of its faces, the same one.
      int back = 0;
      for (int k = 0; k < 4; ++k) back += nb.across(uint64_t(o), k) == int32_t(c);
      CHECK(back == 1);
    }
  CHECK(boundary == uint64_t(6 * 2 * g.lattice * g.lattice));
  // Topology only: another array (a time step) keeps them; another mesh not.
  CHECK(nb.fits(m));
  CHECK(nb.fits(m.with_array("field_t1")));
  auto const other = generate_tets(6 * 5 * 5 * 5, 2);
  CHECK_FALSE(nb.fits(other.mesh()));
  std::vector<uint32_t> swapped = g.cells;
  size_t j = 4;  // a vertex id of another cell that cell 0 does not have
  while (std::find(swapped.begin(), swapped.begin() + 4, swapped[j]) != swapped.begin() + 4) ++j;
  std::swap(swapped[0], swapped[j]);  // same counts, other vertex ids in two cells
  CHECK_FALSE(nb.fits(TetMesh{view(g.xyz), view(swapped), view(g.field)}));
}

TEST_CASE("neighbours: any corner order, 64-bit indices, duplicated and degenerate cells", "[mesh][neighbours]") {
  auto const g = generate_tets(6 * 4 * 4 * 4, 4);
  std::vector<uint64_t> cells(g.cells.begin(), g.cells.end());
  // Corner order rotated per cell: faces are named by sorted ids, not by it.
  for (size_t c = 0; c + 4 <= cells.size(); c += 4) std::rotate(cells.begin() + long(c), cells.begin() + long(c + c / 4 % 4), cells.begin() + long(c + 4));
  // A duplicated cell (its faces now belong to three cells or, on the
  // surface, two: the copies) and two degenerate ones.
  cells.insert(cells.end(), cells.begin() + 40, cells.begin() + 44);
  cells.insert(cells.end(), {cells[0], cells[0], cells[1], cells[2]});
  cells.insert(cells.end(), {cells[8], cells[9], cells[9], cells[9]});
  TetMesh const m{view(g.xyz), view(cells), view(g.field)};
  check_against_brute_force(m);
  TetNeighbours const nb = build_tet_neighbours(m);
  for (int f = 0; f < 4; ++f) CHECK(nb.across(m.cell_count() - 1, f) == -1);
}

TEST_CASE("neighbours: empty meshes and bad vertex ids", "[mesh][neighbours]") {
  TetMesh const empty;
  CHECK(build_tet_neighbours(empty).cell_count() == 0);
  std::vector<float> const xyz(12, 0.f);
  std::vector<uint32_t> const bad{0, 1, 2, 7};
  TetMesh const m{view(xyz), view(bad)};
  CHECK_THROWS_WITH(build_tet_neighbours(m), Catch::Contains("cell 0") && Catch::Contains("vertex 7"));
}

TEST_CASE("neighbours: several blocks, shuffled cells, the same on any thread count", "[mesh][neighbours]") {
  // 83k cells: a 4-thread arena splits the counting sort into 4 blocks of
  // cells (mesh/neighbours.hpp), whatever the machine's core count.
  auto const g = generate_tets(6 * 24 * 24 * 24, 5);
  std::vector<uint32_t> cells = g.cells;
  // Cell order not spatially coherent, as in the OpenFOAM meshes: a
  // vertex's cells come from all blocks.
  std::vector<uint64_t> order(cells.size() / 4);
  for (uint64_t c = 0; c < order.size(); ++c) order[c] = c;
  std::shuffle(order.begin(), order.end(), std::mt19937_64(7));
  std::vector<uint32_t> shuffled(cells.size());
  for (uint64_t c = 0; c < order.size(); ++c)
    for (int i = 0; i < 4; ++i) shuffled[4 * c + uint64_t(i)] = cells[4 * order[c] + uint64_t(i)];
  // Copies of a few cells in other blocks (their faces now belong to 3
  // cells, in one bucket) and degenerate cells between them.
  for (uint64_t c : {uint64_t(5), uint64_t(30000), uint64_t(60000)}) {
    shuffled.insert(shuffled.end(), shuffled.begin() + long(4 * c), shuffled.begin() + long(4 * c + 4));
    shuffled.insert(shuffled.end(), {shuffled[4 * c], shuffled[4 * c], shuffled[4 * c + 1], shuffled[4 * c + 2]});
  }
  std::swap_ranges(shuffled.end() - 8, shuffled.end(), shuffled.begin() + 4 * 41000);
  TetMesh const m{view(g.xyz), view(shuffled), view(g.field)};
  REQUIRE(m.cell_count() >= 4 * (uint64_t(1) << 14));
  TetNeighbours one, four;
  tbb::task_arena(1).execute([&] { one = build_tet_neighbours(m); });
  tbb::task_arena(4).execute([&] {
    four = build_tet_neighbours(m);
    check_against_brute_force(m);
  });
  REQUIRE(one.cell_count() == four.cell_count());
  CHECK(std::equal(one.data(), one.data() + 4 * one.cell_count(), four.data()));
  // Bad vertex ids in the second and fourth blocks: the lower cell is named.
  std::vector<uint32_t> bad = shuffled;
  uint64_t const nv = m.vertex_count(), n = m.cell_count();
  bad[4 * (3 * n / 4 + 10) + 2] = uint32_t(nv + 5);
  bad[4 * (n / 4 + 20) + 1] = uint32_t(nv + 9);
  TetMesh const broken{view(g.xyz), view(bad), view(g.field)};
  tbb::task_arena(4).execute([&] {
    CHECK_THROWS_WITH(build_tet_neighbours(broken), Catch::Contains("cell " + std::to_string(n / 4 + 20) + " ") &&
                                                        Catch::Contains("vertex " + std::to_string(nv + 9)));
  });
}

namespace {

constexpr int hex_faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4}, {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};

/// A hex face's distinct vertex ids, ascending.
std::vector<uint64_t> hex_face(HexMesh const& m, uint64_t c, int f) {
  std::vector<uint64_t> v;
  for (int k : hex_faces[f]) v.push_back(m.vertex(c, k));
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

void check_hex_against_brute_force(HexMesh const& m) {
  std::map<std::vector<uint64_t>, std::vector<uint64_t>> cells_of;
  for (uint64_t c = 0; c < m.cell_count(); ++c)
    for (int f = 0; f < 6; ++f)
      if (auto const v = hex_face(m, c, f); v.size() >= 3) cells_of[v].push_back(c);
  HexNeighbours const nb = build_hex_neighbours(m);
  REQUIRE(nb.cell_count() == m.cell_count());
  CHECK(nb.memory_bytes() == 24 * m.cell_count());
  int wrong = 0;
  for (uint64_t c = 0; c < m.cell_count(); ++c)
    for (int f = 0; f < 6; ++f) {
      auto const v = hex_face(m, c, f);
      int32_t want = -1;
      if (v.size() >= 3)  // one cell's face twice (folded flat) is no neighbour
        if (auto const& list = cells_of[v]; list.size() == 2 && list[0] != list[1])
          want = int32_t(list[0] == c ? list[1] : list[0]);
      wrong += nb.across(c, f) != want;
    }
  CHECK(wrong == 0);
}

}  // namespace

TEST_CASE("hex neighbours: hexes, wedges and pyramids as collapsed hexes, duplicated cells", "[mesh][neighbours]") {
  auto const g = generate_hex_family(6 * 6 * 6, 3);
  HexMesh const m = g.mesh();
  check_hex_against_brute_force(m);
  // Counted without the brute force: a wedge's two collapsed faces (an edge
  // each) and a pyramid's top (a point) have no neighbour; the lattice
  // cells' outer faces and the pyramids' sides are the boundary. Every
  // other face pairs up, symmetrically.
  HexNeighbours const nb = build_hex_neighbours(m);
  uint64_t paired = 0;
  for (uint64_t c = 0; c < m.cell_count(); ++c)
    for (int f = 0; f < 6; ++f)
      if (int32_t const o = nb.across(c, f); o >= 0) {
        ++paired;
        int back = 0;
        for (int k = 0; k < 6; ++k) back += nb.across(uint64_t(o), k) == int32_t(c);
        CHECK(back == 1);
      }
  int const n = g.lattice;
  uint64_t const split = uint64_t((n * n + 1) / 2), whole = uint64_t(n * n) - split;  // columns
  // Shared faces: the 3 n^2 (n - 1) interior lattice faces, those between
  // two split cells twice (two triangles), each split cell's diagonal, and
  // each pyramid's base on its hex.
  uint64_t const shared = 3 * uint64_t(n * n) * uint64_t(n - 1) + split * uint64_t(n - 1) + split * uint64_t(n) + whole;
  CHECK(paired == 2 * shared);
  CHECK(nb.fits(m));
  CHECK_FALSE(nb.fits(generate_hex_family(5 * 5 * 5, 3).mesh()));
  // A duplicated hex (its faces belong to three cells, or two on the
  // surface) and a hex collapsed to a flat quad (no face with area).
  std::vector<uint32_t> cells = g.cells;
  cells.insert(cells.end(), g.cells.begin() + 8 * 7, g.cells.begin() + 8 * 8);
  cells.insert(cells.end(), {cells[0], cells[1], cells[2], cells[3], cells[0], cells[1], cells[2], cells[3]});
  HexMesh const dup{view(g.xyz), view(cells), view(g.field)};
  check_hex_against_brute_force(dup);
  // A cell folded flat over a quad no other cell has: its bottom and top
  // are one face, and a cell is never its own neighbour (found by
  // fuzz_validate); a flat wedge's two ends likewise.
  for (std::vector<uint32_t> const& flat : {std::vector<uint32_t>{0, 1, 2, 3, 0, 1, 2, 3},
                                           std::vector<uint32_t>{0, 1, 2, 2, 0, 1, 2, 2}}) {
    HexNeighbours const one = build_hex_neighbours(HexMesh{view(g.xyz), view(flat), view(g.field)});
    for (int f = 0; f < 6; ++f) CHECK(one.across(0, f) == -1);
    check_hex_against_brute_force(HexMesh{view(g.xyz), view(flat), view(g.field)});
  }
  std::vector<uint32_t> bad = g.cells;
  bad[8 * 3 + 5] = uint32_t(g.xyz.size() / 3 + 2);
  CHECK_THROWS_WITH(build_hex_neighbours(HexMesh{view(g.xyz), view(bad), view(g.field)}),
                    Catch::Contains("cell 3 ") && Catch::Contains("corner 5"));
}

// Several blocks of the counting sort (mesh/neighbours.hpp: at least 16k
// cells each, one per thread) over a shuffled mix of every hex-family kind,
// each cell's corners relabelled by a symmetry of the cube, so a face
// reaches its bucket from any corner slot: hexes, wedges and pyramids
// (generate_hex_family), hexes cut into six tets folded as 0 1 2 2 3 3 3 3,
// duplicated cells, pyramids over interior faces (faces of three cells)
// fanning around vertex 0 (a bucket of over 16 faces: the hashed path; one
// of them duplicated twice, so faces of three cells meet there too), a
// triangle over three corners of a quad (no match: quads meet quads), and
// cells with collapsed faces only.
TEST_CASE("hex neighbours: a shuffled mix in several blocks, the same on any thread count", "[mesh][neighbours]") {
  auto const g = generate_hex_family(32 * 32 * 32, 9);
  std::vector<uint32_t> const& src = g.cells;
  uint64_t const lattice_cells = src.size() / 8;
  std::vector<std::array<uint32_t, 8>> cells;
  std::mt19937_64 rng(11);
  for (uint64_t c = 0; c < lattice_cells; ++c) {
    std::array<uint32_t, 8> cell;
    std::copy(src.begin() + long(8 * c), src.begin() + long(8 * c + 8), cell.begin());
    bool const hex = cell[2] != cell[3] && cell[4] != cell[5] && cell[6] != cell[7];
    if (hex && rng() % 50 == 0) {
      // Six tets around the 0-6 diagonal, each folded into a hex.
      int const tets[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6}, {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
      for (auto const& t : tets)
        cells.push_back({cell[t[0]], cell[t[1]], cell[t[2]], cell[t[2]], cell[t[3]], cell[t[3]], cell[t[3]], cell[t[3]]});
      continue;
    }
    cells.push_back(cell);
  }
  std::vector<uint64_t> quads;  // cells whose bottom face is an interior quad of the lattice
  for (uint64_t c = 0; c < cells.size() && quads.size() < 40; c += 97)
    if (std::set<uint32_t>(cells[c].begin(), cells[c].begin() + 4).size() == 4 && cells[c][0] > 40 * 40) quads.push_back(c);
  REQUIRE(quads.size() == 40);
  for (uint64_t q : quads) {
    auto const b = cells[q];
    cells.push_back({b[0], b[1], b[2], b[3], 0, 0, 0, 0});  // a third cell on the face
  }
  auto const fan_pyramid = cells.back();
  cells.insert(cells.end(), 2, fan_pyramid);  // its sides: triangles of three cells in vertex 0's bucket
  for (uint64_t c : {uint64_t(17), uint64_t(20000), uint64_t(45000)}) cells.push_back(cells[c]);  // duplicated
  auto const t = cells[quads[0]];
  cells.push_back({t[0], t[1], t[2], t[2], 1, 1, 1, 1});   // a triangle over three corners of a quad
  cells.push_back({t[0], t[1], t[2], t[3], t[0], t[1], t[2], t[3]});  // flat: its bottom and top are one face
  cells.push_back({5, 5, 5, 5, 6, 6, 6, 6});                          // no face with area
  std::shuffle(cells.begin(), cells.end(), rng);
  // Corner relabellings that keep a hexahedron (and its collapsed kinds):
  // a quarter turn about the 0-4 axis direction, and top and bottom swapped.
  for (auto& c : cells) {
    for (uint64_t turns = rng() % 4; turns > 0; --turns)
      c = {c[1], c[2], c[3], c[0], c[5], c[6], c[7], c[4]};
    if (rng() % 2) c = {c[4], c[5], c[6], c[7], c[0], c[1], c[2], c[3]};
  }
  std::vector<uint32_t> flat(8 * cells.size());
  for (uint64_t c = 0; c < cells.size(); ++c) std::copy(cells[c].begin(), cells[c].end(), flat.begin() + long(8 * c));
  HexMesh const m{view(g.xyz), view(flat), view(g.field)};
  REQUIRE(m.cell_count() >= 3 * (uint64_t(1) << 14));
  HexNeighbours one, two, four;
  tbb::task_arena(1).execute([&] { one = build_hex_neighbours(m); });
  tbb::task_arena(2).execute([&] {
    two = build_hex_neighbours(m);
    check_hex_against_brute_force(m);
  });
  tbb::task_arena(4).execute([&] { four = build_hex_neighbours(m); });
  REQUIRE(one.cell_count() == m.cell_count());
  CHECK(std::equal(one.data(), one.data() + 6 * m.cell_count(), two.data()));
  CHECK(std::equal(one.data(), one.data() + 6 * m.cell_count(), four.data()));
  // The same with 64-bit indices.
  std::vector<uint64_t> const wide(flat.begin(), flat.end());
  HexNeighbours const from_wide = build_hex_neighbours(HexMesh{view(g.xyz), view(wide), view(g.field)});
  CHECK(std::equal(one.data(), one.data() + 6 * m.cell_count(), from_wide.data()));
  // Bad vertex ids in the second and third blocks: the lower cell is named.
  uint64_t const n = m.cell_count(), nv = m.vertex_count();
  std::vector<uint32_t> bad = flat;
  bad[8 * (2 * n / 3 + 10) + 6] = uint32_t(nv + 5);
  bad[8 * (n / 3 + 20) + 1] = uint32_t(nv + 9);
  HexMesh const broken{view(g.xyz), view(bad), view(g.field)};
  tbb::task_arena(4).execute([&] {
    CHECK_THROWS_WITH(build_hex_neighbours(broken), Catch::Contains("cell " + std::to_string(n / 3 + 20) + " ") &&
                                                        Catch::Contains("corner 1") &&
                                                        Catch::Contains("vertex " + std::to_string(nv + 9)));
  });
}

// The wedge-only and pyramid-only generators (per-type accuracy rows,
// bench_accuracy): conforming (every interior face paired, counted from the
// lattice), positively oriented and not flat.
TEST_CASE("hex neighbours: generate_wedges and generate_pyramids conform", "[mesh][neighbours]") {
  auto paired_faces = [](HexMesh const& m) {
    HexNeighbours const nb = build_hex_neighbours(m);
    check_hex_against_brute_force(m);
    uint64_t paired = 0;
    for (uint64_t c = 0; c < m.cell_count(); ++c)
      for (int f = 0; f < 6; ++f) paired += nb.across(c, f) >= 0;
    return paired;
  };
  auto const w = generate_wedges(2 * 5 * 5 * 5, 2);
  uint64_t const n = uint64_t(w.lattice);
  CHECK(w.cells.size() / 8 == 2 * n * n * n);
  // Shared faces: the 3 n^2 (n - 1) interior lattice faces, those between
  // stacked cells twice (two triangles: every cell is split alike), and
  // each cell's diagonal quad.
  uint64_t const interior = 3 * n * n * (n - 1);
  uint64_t const stacked = n * n * (n - 1);  // of the interior faces: between stacked cells
  CHECK(paired_faces(w.mesh()) == 2 * (interior + stacked + n * n * n));
  auto const p = generate_pyramids(6 * 4 * 4 * 4, 2);
  uint64_t const m = uint64_t(p.lattice);
  CHECK(p.cells.size() / 8 == 6 * m * m * m);
  // Each pyramid's base on the next cell's pyramid, and its four sides on
  // the neighbouring pyramids of its own cell (12 per cell).
  CHECK(paired_faces(p.mesh()) == 2 * (3 * m * m * (m - 1) + 12 * m * m * m));
  for (auto const* g : {&w, &p}) {
    ValidationReport const r = validate(g->mesh());
    INFO(r.message());
    CHECK(r.ok());
    CHECK_FALSE(r.inverted);
    CHECK_FALSE(r.zero_volume);
  }
}

// A mixed mesh's two parts (mesh/neighbours.hpp, link_face_neighbours): a
// triangle on one tet and one hex-family cell (a wedge's end, a pyramid's
// side) links them, -2 - (the other part's cell) on both sides; faces within
// a part keep their neighbours; a triangle of more cells (a tet duplicated
// at the interface) links nothing. Against a brute-force map over both parts.
TEST_CASE("linked neighbours: tets and hexahedra of a mixed mesh across their shared triangles", "[mesh][neighbours]") {
  for (char const* file : {"mixed22.msh", "sphere_bl_small.msh"}) {
    UnstructuredGrid g = read_mesh(std::string(CELLRAY_TEST_DATA) + "/gmsh/" + file);
    std::vector<float> const field(g.vertex_count(), 1.f);
    for (bool duplicate : {false, true}) {
      std::vector<uint32_t> tet_ids(g.tets.begin(), g.tets.end());
      HexMesh const hm = g.hex_mesh().with_values(view(field));
      if (duplicate) {  // copies of the tets with a face on a hexahedron's triangle
        std::set<std::vector<uint64_t>> hex_triangles;
        for (uint64_t c = 0; c < hm.cell_count(); ++c)
          for (int f = 0; f < 6; ++f)
            if (auto const v = hex_face(hm, c, f); v.size() == 3) hex_triangles.insert(v);
        for (size_t c = 0, n = tet_ids.size() / 4; c < n; c += 3) {
          std::array<uint64_t, 4> v{tet_ids[4 * c], tet_ids[4 * c + 1], tet_ids[4 * c + 2], tet_ids[4 * c + 3]};
          std::sort(v.begin(), v.end());
          bool on = false;
          for (int f = 0; f < 4; ++f) {
            Face const t = face_of(v, f);
            on = on || hex_triangles.count({t[0], t[1], t[2]});
          }
          if (on) tet_ids.insert(tet_ids.end(), tet_ids.begin() + long(4 * c), tet_ids.begin() + long(4 * c + 4));
        }
      }
      TetMesh const tm = TetMesh(view(g.xyz), view(tet_ids)).with_values(view(field));
      INFO(file << (duplicate ? ", tets duplicated at the interface" : ""));
      // Brute force: every face with area of both parts by its distinct ids.
      std::map<std::vector<uint64_t>, std::vector<uint64_t>> tets_of, hexes_of;
      for (uint64_t c = 0; c < tm.cell_count(); ++c)
        if (auto const v = sorted_ids(tm, c); !degenerate(v))
          for (int f = 0; f < 4; ++f) {
            Face const t = face_of(v, f);
            tets_of[{t[0], t[1], t[2]}].push_back(c);
          }
      for (uint64_t c = 0; c < hm.cell_count(); ++c)
        for (int f = 0; f < 6; ++f)
          if (auto const v = hex_face(hm, c, f); v.size() >= 3) hexes_of[v].push_back(c);
      auto want = [&](std::vector<uint64_t> const& face, uint64_t self, bool self_hex) -> int32_t {
        auto const& same = self_hex ? hexes_of[face] : tets_of[face];
        auto const& other = self_hex ? tets_of[face] : hexes_of[face];
        // Pairs within a part stay as built, whatever the other part has there.
        if (same.size() == 2) return same[0] == same[1] ? -1 : int32_t(same[0] == self ? same[1] : same[0]);
        if (same.size() == 1 && other.size() == 1) return -2 - int32_t(other[0]);
        return -1;
      };
      TetNeighbours tn = build_tet_neighbours(tm);
      HexNeighbours hn = build_hex_neighbours(hm);
      CHECK_FALSE(tn.linked_to(hm));
      for (int round = 0; round < 2; ++round) {  // linking again changes nothing
        link_face_neighbours(tm, tn, hm, hn);
        CHECK(tn.linked_to(hm));
        CHECK(hn.linked_to(tm));
        CHECK(tn.fits(tm));
        int wrong = 0, links = 0;
        for (uint64_t c = 0; c < tm.cell_count(); ++c) {
          auto const v = sorted_ids(tm, c);
          for (int f = 0; f < 4; ++f) {
            Face const t = face_of(v, f);
            int32_t const w = degenerate(v) ? -1 : want({t[0], t[1], t[2]}, c, false);
            wrong += tn.across(c, f) != w;
            links += w <= -2;
          }
        }
        for (uint64_t c = 0; c < hm.cell_count(); ++c)
          for (int f = 0; f < 6; ++f) {
            auto const v = hex_face(hm, c, f);
            int32_t const w = v.size() >= 3 ? want(v, c, true) : -1;
            wrong += hn.across(c, f) != w;
            links += w <= -2;
          }
        CHECK(wrong == 0);
        if (!duplicate) CHECK(links > 20);  // both files have an interface of triangles
      }
    }
  }
  // Parts over different vertex arrays, and neighbours of another mesh, are refused.
  auto const a = generate_tets(6 * 3 * 3 * 3, 1);
  auto const b = generate_hex_family(3 * 3 * 3, 1);
  TetNeighbours tn = build_tet_neighbours(a.mesh());
  HexNeighbours hn = build_hex_neighbours(b.mesh());
  CHECK_THROWS_WITH(link_face_neighbours(a.mesh(), tn, b.mesh(), hn), Catch::Contains("one vertex array"));
  auto const c = generate_tets(6 * 4 * 4 * 4, 1);
  CHECK_THROWS_WITH(link_face_neighbours(c.mesh(), tn, b.mesh(), hn), Catch::Contains("another mesh"));
}

}  // namespace test_mesh_neighbours
