// gmsh MSH files (io/gmsh.hpp): one small mesh written by hand in MSH 2.2
// and in MSH 4.1 -- a hexahedron, a prism, a pyramid and a 10-node
// tetrahedron around sparse node tags, with boundary elements, node and
// element data -- must read back cell for cell, with the prism turned into
// VTK's wedge order; broken files name their line; the repository's
// component8 mesh must read as the same mesh as its VTK twin.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/validate.hpp>

#include "support/test_data.hpp"

namespace test_io_gmsh {

using namespace cellray;

namespace {

// Nodes by tag: a unit cube 10-17 (hexahedron), 20 and 21 (the prism beside
// it at x in [1, 2]), 30 (the pyramid's apex above the cube), 40 (the
// tetrahedron's fourth corner at x = -1) and the tetrahedron's six mid-edge
// nodes 50-54 and 900001 (a tag far past the others: the sparse lookup).
char const* const nodes22 = R"($Nodes
18
10 0 0 0
11 1 0 0
12 1 1 0
13 0 1 0
14 0 0 1
15 1 0 1
16 1 1 1
17 0 1 1
20 2 0 0
21 2 0 1
30 0.5 0.5 1.5
40 -1 0 0
50 -0.5 0 0
51 -0.5 0.5 0
52 0 0.5 0
53 -0.5 0 0.5
54 0 0.5 0.5
900001 0 0 0.5
$EndNodes
)";

// Node data: T = 100 + tag at every node but 900001; U (3 components) at
// node 10 only; a second time step of T (ignored). Element data p on the
// four volume cells and a boundary triangle (dropped with it).
char const* const data = R"($NodeData
1
"T"
1
0.0
3
0
1
17
10 110
11 111
12 112
13 113
14 114
15 115
16 116
17 117
20 120
21 121
30 130
40 140
50 150
51 151
52 152
53 153
54 154
$EndNodeData
$NodeData
1
"U"
1
0.0
3
0
3
1
10 3 4 0
$EndNodeData
$NodeData
1
"T"
1
1.0
3
1
1
1
10 -1
$EndNodeData
$ElementData
1
"p"
1
0.0
3
0
1
5
3 4.5
7 1.5
8 2.5
9 3.5
100 9.9
$EndElementData
)";

std::string msh22() {
  return std::string("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"solid\"\n$EndPhysicalNames\n") + nodes22 +
         R"($Elements
7
3 11 2 1 5 40 10 13 14 50 51 52 53 54 900001
7 5 2 1 5 10 11 12 13 14 15 16 17
8 6 2 2 6 11 20 12 15 21 16
9 7 2 2 7 14 15 16 17 30
100 2 2 9 9 10 11 12
101 15 1 9 10
102 1 2 9 9 10 11
$EndElements
)" + data;
}

// The same mesh in MSH 4.1: nodes in two entity blocks (the second with
// parametric coordinates to skip), one block per element.
std::string msh41() {
  return std::string(R"($MeshFormat
4.1 0 8
$EndMeshFormat
$Entities
0 0 0 1
5 -1 -1 -1 2 2 2 0 0
$EndEntities
$Nodes
2 18 10 900001
3 5 0 16
10
11
12
13
14
15
16
17
20
21
30
40
50
51
52
53
0 0 0
1 0 0
1 1 0
0 1 0
0 0 1
1 0 1
1 1 1
0 1 1
2 0 0
2 0 1
0.5 0.5 1.5
-1 0 0
-0.5 0 0
-0.5 0.5 0
0 0.5 0
-0.5 0 0.5
1 7 1 2
54
900001
0 0.5 0.5 0.25
0 0 0.5 0.75
$EndNodes
$Elements
7 7 3 102
3 5 11 1
3 40 10 13 14 50 51 52 53 54 900001
3 5 5 1
7 10 11 12 13 14 15 16 17
3 6 6 1
8 11 20 12 15 21 16
3 7 7 1
9 14 15 16 17 30
2 9 2 1
100 10 11 12
0 9 15 1
101 10
1 9 1 1
102 10 11
$EndElements
)") + data;
}

bool nan(float v) { return v != v; }

/// What both versions must give: VTK types, corners (the prism in VTK's
/// wedge order, then as a collapsed hexahedron), values by node tag.
void check_common(UnstructuredGrid const& g) {
  REQUIRE(g.vertex_count() == 18);
  CHECK(g.report.cells_read.at(10) == 1);
  CHECK(g.report.cells_read.at(12) == 1);
  CHECK(g.report.cells_read.at(13) == 1);
  CHECK(g.report.cells_read.at(14) == 1);
  CHECK(g.report.reduced_to_linear == 1);  // the 10-node tetrahedron
  REQUIRE(g.tets == std::vector<uint32_t>{11, 0, 3, 4});
  // Node indices: tags 10-17 -> 0-7, 20 -> 8, 21 -> 9, 30 -> 10.
  std::vector<uint32_t> const hexes = {0, 1, 2, 3, 4, 5, 6, 7,  // the hexahedron
                                       // gmsh prism 11 20 12 / 15 21 16 -> VTK wedge 11 12 20 / 15 16 21 -> hex corners
                                       1, 8, 2, 2, 5, 9, 6, 6,
                                       4, 5, 6, 7, 10, 10, 10, 10};  // the pyramid
  CHECK(g.hexes == hexes);
  // gmsh's prisms and pyramids are positive in gmsh: so must they be as VTK cells.
  ValidationReport const vh = validate(g.hex_mesh().with_array("T"));
  CHECK(!vh.inverted);
  CHECK(!vh.zero_volume);
  CHECK(!validate(g.tet_mesh().with_array("T")).inverted);

  PointArray const* t = g.point_array("T");
  REQUIRE(t);
  CHECK(t->values[0] == 110.f);
  CHECK(t->values[8] == 120.f);
  CHECK(t->values[10] == 130.f);
  CHECK(nan(t->values[17]));  // node 900001 has no value: NaN
  PointArray const* u = g.point_array("U");
  REQUIRE(u);
  CHECK(u->components == 3);
  CHECK(u->values[0] == 5.f);  // |(3, 4, 0)|
  CHECK(nan(u->values[1]));
  CellArray const* p = g.cell_array("p");
  REQUIRE(p);
  CHECK(p->tet_values == std::vector<float>{4.5f});
  CHECK(p->hex_values == std::vector<float>{1.5f, 2.5f, 3.5f});
  CellArray const* geom = g.cell_array("gmsh:geometrical");
  REQUIRE(geom);
  CHECK(geom->tet_values == std::vector<float>{5.f});
  CHECK(geom->hex_values == std::vector<float>{5.f, 6.f, 7.f});

  auto ignored = [&](char const* what) {
    return std::any_of(g.report.other_ignored.begin(), g.report.other_ignored.end(),
                       [&](std::string const& s) { return s.find(what) != std::string::npos; });
  };
  CHECK(ignored("1 triangle elements (gmsh type 2)"));
  CHECK(ignored("1 point elements (gmsh type 15)"));
  CHECK(ignored("1 line elements (gmsh type 1)"));
  CHECK(ignored("point 'T' at time step 1"));
  CHECK(g.report.skipped_count() == 0);
}

}  // namespace

TEST_CASE("gmsh MSH 2.2: every volume type, sparse tags, node and element data", "[io][gmsh]") {
  UnstructuredGrid const g = read_gmsh_from_memory(msh22(), "hand.msh");
  CHECK(g.report.format == "gmsh MSH 2.2 ASCII");
  check_common(g);
  CellArray const* phys = g.cell_array("gmsh:physical");
  REQUIRE(phys);
  CHECK(phys->tet_values == std::vector<float>{1.f});
  CHECK(phys->hex_values == std::vector<float>{1.f, 2.f, 2.f});
}

TEST_CASE("gmsh MSH 4.1: entity blocks and parametric nodes give the grid MSH 2.2 gives", "[io][gmsh]") {
  UnstructuredGrid const g = read_mesh_from_memory(msh41(), "hand.msh");
  CHECK(g.report.format == "gmsh MSH 4.1 ASCII");
  check_common(g);
  CHECK(!g.cell_array("gmsh:physical"));  // MSH 4 keeps physical groups in $Entities, not read
  UnstructuredGrid const g22 = read_gmsh_from_memory(msh22(), "hand.msh");
  CHECK(g.xyz == g22.xyz);
}

TEST_CASE("broken MSH files raise IoError naming file, line and problem", "[io][gmsh][broken]") {
  std::string const head = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
  std::string const two_nodes = "$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n";
  struct Case {
    std::string text, message;
  };
  std::vector<Case> const cases = {
      {"", "empty file"},
      {"$Nodes\n", "hand.msh:1: an MSH file starts with $MeshFormat"},
      {"$MeshFormat\n2.2 1 8\n", "hand.msh:2: binary MSH is not read yet (write ASCII: gmsh -bin 0"},
      {"$MeshFormat\n4 0 8\n$EndMeshFormat\n", "hand.msh:2: MSH version '4' is not read"},
      {head + "$Nodes\n5\n1 0 0 0\n2 1 0 0\n$EndNodes\n", "hand.msh:8: expected a node tag, found '$EndNodes'"},
      {head + "$Nodes\n2\n1 0 0 0\n1 1 0 0\n$EndNodes\n", "node tag 1 appears twice"},
      {head + "$Nodes\n99999999\n1 0 0 0\n", "hand.msh:5: the node count 99999999 does not fit"},
      {head + "$Nodes\n1\n1 0 x 0\n$EndNodes\n", "hand.msh:6: expected a coordinate, found 'x'"},
      {head + two_nodes + "$Elements\n1\n1 4 0 1 2 3 99\n$EndElements\n",
       "hand.msh:13: element 1 names node 99, which $Nodes does not list"},
      {head + two_nodes + "$Elements\n1\n1 4 0 1 2 3\n$EndElements\n",
       "hand.msh:13: element 1 (4-node tetrahedron) lists 3 nodes, needs at least 4"},
      {head + two_nodes + "$Elements\n1\n1 135 0 1 2 3 4\n$EndElements\n",
       "hand.msh:13: element 1 has gmsh element type 135, which cellray does not read"},
      {head + two_nodes + "$Elements\n1\n1 2 0 1 2 3\n$EndElements\n",
       "no volume elements (tetrahedra, hexahedra, prisms or pyramids); the file has 1 triangle"},
      {head + two_nodes + "$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n$NodeData\n1\n\"T\"\n0\n3\n0\n1\n1\n7 1.0\n$EndNodeData\n",
       "hand.msh:23: view 'T' names node 7, which the mesh does not have"},
      {head + two_nodes + "$Elements\n1\n1 4 0 1 2 3 4\n", "expected $EndElements, found the end of the file"},
      {head + "$Comments\nno end\n", "hand.msh:4: section $Comments has no $EndComments"},
  };
  for (Case const& c : cases) {
    INFO(c.text);
    CHECK_THROWS_WITH(read_gmsh_from_memory(c.text, "hand.msh"), Catch::Contains(c.message));
  }
}

TEST_CASE("an element type cellray does not read is a counted skip when asked", "[io][gmsh]") {
  std::string const text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n"
                           "$Elements\n2\n1 135 0 1 2 3 4\n2 4 0 1 2 3 4\n$EndElements\n";
  ReadOptions o;
  o.skip_unsupported_cells = true;
  UnstructuredGrid const g = read_gmsh_from_memory(text, "hand.msh", o);
  CHECK(g.tet_count() == 1);
  CHECK(g.report.skipped_count() == 1);
  CHECK(g.report.summary().find("ignored 1 elements of gmsh type 135 (a type cellray does not read: skipped)") !=
        std::string::npos);
}

TEST_CASE("meshes gmsh wrote read as gmsh's own VTK export of them: every type, MSH 2.2, 4.1, second order",
          "[io][gmsh]") {
  auto file = [](char const* name) { return std::string(CELLRAY_TEST_DATA) + "/gmsh/" + name; };
  ReadOptions skip;  // gmsh's .vtk holds the boundary points, lines and quads too
  skip.skip_unsupported_cells = true;
  // Corner positions cell by cell: the node numbering of a second-order
  // file differs, the corners may not.
  auto same_cells = [](UnstructuredGrid const& a, UnstructuredGrid const& b) {
    auto same = [&](std::vector<uint32_t> const& x, std::vector<uint32_t> const& y) {
      if (x.size() != y.size()) return false;
      for (size_t i = 0; i < x.size(); ++i)
        for (uint64_t k = 0; k < 3; ++k)
          if (a.xyz[3 * uint64_t(x[i]) + k] != b.xyz[3 * uint64_t(y[i]) + k]) return false;
      return true;
    };
    return same(a.tets, b.tets) && same(a.hexes, b.hexes);
  };
  struct Pair {
    char const* msh;
    char const* vtk;
    uint64_t tets, hexes;
  };
  for (Pair const& p : {Pair{"mixed22.msh", "mixed.vtk", 429, 27 + 54}, Pair{"mixed41.msh", "mixed.vtk", 429, 27 + 54},
                        Pair{"mixed22_order2.msh", "mixed.vtk", 429, 27 + 54}, Pair{"layer22.msh", "layer.vtk", 0, 52},
                        Pair{"layer22_order2.msh", "layer.vtk", 0, 52}}) {
    INFO(p.msh);
    UnstructuredGrid const m = read_mesh(file(p.msh)), v = read_mesh(file(p.vtk), skip);
    CHECK(m.tet_count() == p.tets);
    CHECK(m.hex_count() == p.hexes);
    CHECK(same_cells(m, v));
    CHECK(!validate(m.hex_mesh()).inverted);
    CHECK(!validate(m.tet_mesh()).inverted);
    CHECK(m.report.skipped_count() == 0);
  }
  CHECK(read_mesh(file("layer22.msh")).report.cells_read.at(13) == 52);        // prisms
  CHECK(read_mesh(file("mixed22.msh")).report.cells_read.at(14) == 54);        // pyramids
  CHECK(read_mesh(file("mixed22_order2.msh")).report.reduced_to_linear == 510);  // tet10, hex27, pyr14
}

TEST_CASE("gmsh/component8_84k.msh is the mesh of openfoam/component8_heat_84k.vtk", "[io][gmsh][data]") {
  auto const msh = test::shared_data_file("gmsh/component8_84k.msh");
  auto const vtk = test::shared_data_file("openfoam/component8_heat_84k.vtk");
  if (!msh || !vtk) return;
  UnstructuredGrid const a = read_mesh(*msh), b = read_mesh(*vtk);
  CHECK(a.tet_count() == 84438);
  CHECK(a.tet_count() == b.tet_count());
  CHECK(a.vertex_count() == b.vertex_count());
  CHECK(a.hex_count() == 0);
  // The node order may differ: compare what does not depend on it.
  auto bounds_and_volume = [](UnstructuredGrid const& g, glm::dvec3& lo, glm::dvec3& hi) {
    lo = glm::dvec3(1e300), hi = glm::dvec3(-1e300);
    for (uint64_t v = 0; v < g.vertex_count(); ++v) {
      glm::dvec3 const p(g.xyz[3 * v], g.xyz[3 * v + 1], g.xyz[3 * v + 2]);
      lo = glm::min(lo, p), hi = glm::max(hi, p);
    }
    double volume = 0;
    for (uint64_t c = 0; c < g.tet_count(); ++c) {
      glm::dvec3 p[4];
      for (int k = 0; k < 4; ++k) {
        uint32_t const v = g.tets[4 * c + uint64_t(k)];
        p[k] = glm::dvec3(g.xyz[3 * v], g.xyz[3 * v + 1], g.xyz[3 * v + 2]);
      }
      volume += glm::dot(p[1] - p[0], glm::cross(p[2] - p[0], p[3] - p[0])) / 6.0;
    }
    return volume;
  };
  glm::dvec3 alo, ahi, blo, bhi;
  double const va = bounds_and_volume(a, alo, ahi), vb = bounds_and_volume(b, blo, bhi);
  CHECK(alo == blo);
  CHECK(ahi == bhi);
  CHECK(va > 0);
  CHECK(std::fabs(va - vb) <= 1e-9 * std::fabs(vb));
  TetMesh const m = a.tet_mesh();
  CHECK(!validate(m).inverted);
  CHECK(a.report.other_ignored.front() == "15976 triangle elements (gmsh type 2): not volume cells");
}

}  // namespace test_io_gmsh
