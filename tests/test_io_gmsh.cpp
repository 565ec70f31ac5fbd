// gmsh MSH files (io/gmsh.hpp): one small mesh written by hand in MSH 2.2
// and in MSH 4.1 -- a hexahedron, a prism, a pyramid and a 10-node
// tetrahedron around sparse node tags, with boundary elements, node and
// element data -- must read back cell for cell, with the prism turned into
// VTK's wedge order, and so must its binary twins (written here from the
// text, in both byte orders); broken files name their line (binary ones
// their byte and section), every truncation of a binary file is an IoError;
// gmsh's own binary files read as its ASCII ones; the repository's
// component8 mesh must read as the same mesh as its VTK twin.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>
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
  // Validation names cells by their element tags, which gmsh shows.
  CHECK(g.tet_file_cells == std::vector<uint32_t>{3});
  CHECK(g.hex_file_cells == std::vector<uint32_t>{7, 8, 9});
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


/// Binary MSH bytes in either byte order, as gmsh writes them.
struct Bin {
  bool big = false;
  std::string s;
  template <class T> Bin& put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big) std::reverse(b, b + sizeof(T));  // the tests run on little-endian hosts
    s.append(b, sizeof(T));
    return *this;
  }
  Bin& i32(int64_t v) { return put(int32_t(v)); }
  Bin& u64(uint64_t v) { return put(v); }
  Bin& f64(double v) { return put(v); }
  Bin& text(std::string const& t) { return s += t, *this; }
};

std::vector<std::string> lines_of(std::string const& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}
std::vector<double> numbers(std::string const& l) {
  std::istringstream in(l);
  std::vector<double> out;
  for (double v; in >> v;) out.push_back(v);
  return out;
}

/// The binary twin of an ASCII MSH 2.2 or 4.1 file written by msh22() or
/// msh41() (gmsh's layout: 2.2 elements in groups of one, as gmsh 4.8
/// writes them; 4.1 counts and tags as 8-byte size_t; data headers as text).
std::string to_binary(std::string const& ascii, bool big) {
  std::vector<std::string> const l = lines_of(ascii);
  Bin b{big, {}};
  bool v4 = false;
  size_t i = 0;
  auto next = [&] { return numbers(l.at(i++)); };
  while (i < l.size()) {
    std::string const section = l[i++];
    b.text(section + "\n");
    if (section == "$MeshFormat") {
      v4 = l[i++][0] == '4';
      b.text(v4 ? "4.1 1 8\n" : "2.2 1 8\n").i32(1).text("\n");
    } else if (section == "$Entities") {
      std::vector<double> const n = next();
      for (double c : n) b.u64(uint64_t(c));
      for (int dim = 0; dim < 4; ++dim)
        for (int e = 0; e < int(n[size_t(dim)]); ++e) {
          std::vector<double> const v = next();  // tag, box, physicals, bounding entities
          REQUIRE(dim == 3);
          b.i32(int64_t(v[0]));
          for (int k = 1; k <= 6; ++k) b.f64(v[size_t(k)]);
          size_t k = 7;
          for (int part = 0; part < 2; ++part) {
            uint64_t const m = uint64_t(v[k++]);
            b.u64(m);
            for (uint64_t j = 0; j < m; ++j) b.i32(int64_t(v[k++]));
          }
        }
    } else if (section == "$Nodes" && !v4) {
      uint64_t const n = uint64_t(next()[0]);
      b.text(std::to_string(n) + "\n");
      for (uint64_t k = 0; k < n; ++k) {
        std::vector<double> const v = next();
        b.i32(int64_t(v[0])).f64(v[1]).f64(v[2]).f64(v[3]);
      }
    } else if (section == "$Nodes") {
      std::vector<double> const h = next();
      for (double c : h) b.u64(uint64_t(c));
      for (uint64_t blk = 0; blk < uint64_t(h[0]); ++blk) {
        std::vector<double> const bh = next();
        b.i32(int64_t(bh[0])).i32(int64_t(bh[1])).i32(int64_t(bh[2])).u64(uint64_t(bh[3]));
        for (uint64_t k = 0; k < uint64_t(bh[3]); ++k) b.u64(uint64_t(next()[0]));
        for (uint64_t k = 0; k < uint64_t(bh[3]); ++k)
          for (double c : next()) b.f64(c);
      }
    } else if (section == "$Elements" && !v4) {
      uint64_t const n = uint64_t(next()[0]);
      b.text(std::to_string(n) + "\n");
      for (uint64_t k = 0; k < n; ++k) {
        std::vector<double> const v = next();  // number, type, tag count, tags, nodes
        b.i32(int64_t(v[1])).i32(1).i32(int64_t(v[2])).i32(int64_t(v[0]));
        for (size_t j = 3; j < v.size(); ++j) b.i32(int64_t(v[j]));
      }
    } else if (section == "$Elements") {
      std::vector<double> const h = next();
      for (double c : h) b.u64(uint64_t(c));
      for (uint64_t blk = 0; blk < uint64_t(h[0]); ++blk) {
        std::vector<double> const bh = next();
        b.i32(int64_t(bh[0])).i32(int64_t(bh[1])).i32(int64_t(bh[2])).u64(uint64_t(bh[3]));
        for (uint64_t k = 0; k < uint64_t(bh[3]); ++k)
          for (double t : next()) b.u64(uint64_t(t));
      }
    } else if (section == "$NodeData" || section == "$ElementData") {
      std::vector<double> ints;
      for (int part = 0; part < 3; ++part) {  // string, real and integer tags: text
        uint64_t const m = uint64_t(std::stoul(l.at(i)));
        for (uint64_t k = 0; k <= m; ++k) b.text(l.at(i + k) + "\n");
        if (part == 2)
          for (uint64_t k = 1; k <= m; ++k) ints.push_back(numbers(l.at(i + k))[0]);
        i += m + 1;
      }
      for (uint64_t k = 0; k < uint64_t(ints[2]); ++k) {
        std::vector<double> const v = next();
        b.i32(int64_t(v[0]));
        for (size_t j = 1; j < v.size(); ++j) b.f64(v[j]);
      }
    } else {
      while (l.at(i)[0] != '$') b.text(l[i++] + "\n");
    }
    // Binary data ends with a newline before the section's $End line.
    bool const binary = section != "$MeshFormat" && section != "$PhysicalNames";
    REQUIRE(l.at(i).rfind("$End", 0) == 0);
    b.text((binary ? "\n" : "") + l[i++] + "\n");
  }
  return b.s;
}

bool same_bits(std::vector<float> const& a, std::vector<float> const& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

/// Everything a reader gives but the format string: bit for bit.
void check_same_grid(UnstructuredGrid const& a, UnstructuredGrid const& b) {
  CHECK(same_bits(a.xyz, b.xyz));
  CHECK(a.tets == b.tets);
  CHECK(a.hexes == b.hexes);
  CHECK(a.tet_file_cells == b.tet_file_cells);
  CHECK(a.hex_file_cells == b.hex_file_cells);
  REQUIRE(a.point_arrays.size() == b.point_arrays.size());
  for (size_t k = 0; k < a.point_arrays.size(); ++k) {
    CHECK(a.point_arrays[k].name == b.point_arrays[k].name);
    CHECK(a.point_arrays[k].components == b.point_arrays[k].components);
    CHECK(same_bits(a.point_arrays[k].values, b.point_arrays[k].values));
  }
  REQUIRE(a.cell_arrays.size() == b.cell_arrays.size());
  for (size_t k = 0; k < a.cell_arrays.size(); ++k) {
    CHECK(a.cell_arrays[k].name == b.cell_arrays[k].name);
    CHECK(a.cell_arrays[k].components == b.cell_arrays[k].components);
    CHECK(same_bits(a.cell_arrays[k].tet_values, b.cell_arrays[k].tet_values));
    CHECK(same_bits(a.cell_arrays[k].hex_values, b.cell_arrays[k].hex_values));
  }
  CHECK(a.report.cells_read == b.report.cells_read);
  CHECK(a.report.cells_skipped == b.report.cells_skipped);
  CHECK(a.report.reduced_to_linear == b.report.reduced_to_linear);
  CHECK(a.report.arrays_read == b.report.arrays_read);
  CHECK(a.report.arrays_ignored == b.report.arrays_ignored);
  CHECK(a.report.other_ignored == b.report.other_ignored);
  CHECK(a.report.other_cells_skipped == b.report.other_cells_skipped);
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
      {"$MeshFormat\n3.0 0 8\n$EndMeshFormat\n", "hand.msh:2: MSH version '3.0' is not read"},
      {"$MeshFormat\n2.2 2 8\n$EndMeshFormat\n", "hand.msh:2: file type 2 (0: ASCII, 1: binary)"},
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
                        Pair{"layer22_order2.msh", "layer.vtk", 0, 52}, Pair{"layer40.msh", "layer.vtk", 0, 52},
                        Pair{"mixed22_bin.msh", "mixed.vtk", 429, 27 + 54}, Pair{"mixed41_bin.msh", "mixed.vtk", 429, 27 + 54},
                        Pair{"layer22_order2_bin.msh", "layer.vtk", 0, 52}}) {
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

TEST_CASE("binary MSH 2.2 and 4.1, either byte order, give the grid their ASCII text gives", "[io][gmsh][binary]") {
  for (bool big : {false, true}) {
    INFO((big ? "big-endian" : "little-endian"));
    UnstructuredGrid const a22 = read_gmsh_from_memory(msh22(), "hand.msh");
    UnstructuredGrid const b22 = read_gmsh_from_memory(to_binary(msh22(), big), "hand.msh");
    CHECK(b22.report.format == "gmsh MSH 2.2 binary");
    check_common(b22);
    check_same_grid(a22, b22);
    UnstructuredGrid const a41 = read_gmsh_from_memory(msh41(), "hand.msh");
    UnstructuredGrid const b41 = read_mesh_from_memory(to_binary(msh41(), big), "hand.msh");
    CHECK(b41.report.format == "gmsh MSH 4.1 binary");
    check_common(b41);
    check_same_grid(a41, b41);
  }
}

TEST_CASE("every truncation of a binary MSH file, and every byte inverted, is an IoError or a grid",
          "[io][gmsh][binary][broken]") {
  for (std::string const& text : {msh22(), msh41()}) {
    std::string const bin = to_binary(text, false);
    // Every prefix fails, naming the file, unless it ends with a whole
    // section (a file without its last views is still a file).
    for (size_t n = 0; n < bin.size(); ++n) {
      std::string_view cut = std::string_view(bin).substr(0, n);
      try {
        read_gmsh_from_memory(cut, "cut.msh");
        if (!cut.empty() && cut.back() == '\n') cut.remove_suffix(1);
        size_t const last_line = cut.rfind('\n');
        if (last_line == std::string_view::npos || cut.substr(last_line + 1, 4) != "$End") FAIL("a prefix of " << n << " bytes read");
      } catch (IoError const& e) {
        if (std::string(e.what()).rfind("cut.msh", 0) != 0) FAIL(e.what());
      }
    }
    // A damaged byte anywhere: a clean error or a grid, never a crash or
    // a read past the end (the sanitizer build watches).
    for (size_t k = 0; k < bin.size(); ++k) {
      std::string bad = bin;
      bad[k] = char(~bad[k]);
      try {
        read_gmsh_from_memory(bad, "bad.msh");
      } catch (IoError const&) {
      }
    }
  }
}

TEST_CASE("broken binary MSH files raise IoError naming file, byte and section", "[io][gmsh][binary][broken]") {
  auto head = [](char const* version) {
    return Bin{false, {}}.text(std::string("$MeshFormat\n") + version + " 1 8\n").i32(1).text("\n$EndMeshFormat\n");
  };
  std::string const h22 = head("2.2").s, h41 = head("4.1").s;
  // A 2.2 tetrahedron's nodes, for the element cases.
  Bin nodes = Bin{false, {}}.text("$Nodes\n4\n");
  for (int k = 1; k <= 4; ++k) nodes.i32(k).f64(k == 2).f64(k == 3).f64(k == 4);
  nodes.text("\n$EndNodes\n");
  std::string const n22 = h22 + nodes.s;
  auto group = [](int type, int follow, int ntags) { return Bin{false, {}}.i32(type).i32(follow).i32(ntags).s; };
  struct Case {
    std::string bytes, message;
  };
  std::vector<Case> const cases = {
      {"$MeshFormat\n2.2 1 4\n", "hand.msh:2: binary MSH with data size 4 is not read"},
      {"$MeshFormat\n4 1 8\n", "hand.msh:2: binary MSH 4.0 is not read (write MSH 4.1"},
      {"$MeshFormat\n2.2 1 8\n", "hand.msh: byte 20: $MeshFormat: the file ends where the byte order check"},
      {Bin{false, {}}.text("$MeshFormat\n2.2 1 8\n").i32(7).text("\n$EndMeshFormat\n").s,
       "hand.msh: byte 20: $MeshFormat: the byte order check reads 7, not the int 1"},
      {h22 + "$Nodes\n2\n" + Bin{false, {}}.i32(1).f64(0).f64(0).s,
       "hand.msh: byte 49: $Nodes: the node count 2 does not fit in the 20 bytes left (28 bytes each at least)"},
      {h41 + "$Nodes\n" + Bin{false, {}}.u64(0).u64(0).u64(1).s,
       "hand.msh: byte 71: $Nodes: the file ends inside the largest node tag (8 bytes needed, 0 left)"},
      {h22 + "$Nodes\n1\n" + Bin{false, {}}.i32(-3).f64(0).f64(0).f64(0).s + "\n$EndNodes\n",
       "hand.msh: byte 49: $Nodes: node tag -3 is not positive"},
      {n22 + "$Elements\n1\n" + group(4, 5, 0) + Bin{false, {}}.i32(1).i32(1).i32(2).i32(3).i32(4).s,
       "$Elements: an element group of 5 elements, 1 of the announced 1 being left"},
      {n22 + "$Elements\n1\n" + group(4, 1, 0) + Bin{false, {}}.i32(1).i32(1).i32(2).i32(3).s,
       "$Elements: an element group's count 1 does not fit in the 16 bytes left (20 bytes each at least)"},
      {n22 + "$Elements\n1\n" + group(4, 1, 0) + Bin{false, {}}.i32(1).i32(1).i32(2).i32(3).i32(9).s + "\n$EndElements\n",
       "$Elements: element 1 names node 9, which $Nodes does not list"},
      {n22 + "$Elements\n1\n" + group(135, 1, 0) + Bin{false, {}}.i32(1).i32(1).i32(2).i32(3).i32(4).s,
       "$Elements: element 1 has gmsh element type 135, which cellray does not read"},
      {n22 + "$Elements\n1\n" + group(4, 1, 0) + Bin{false, {}}.i32(1).i32(1).i32(2).i32(3).i32(4).s + "\n$EndElements\n" +
           "$NodeData\n1\n\"T\"\n0\n3\n0\n1\n1000000\n" + Bin{false, {}}.i32(1).f64(1).s,
       "$NodeData: view 'T' claims 1000000 values, more than the 12 bytes left hold"},
      // MSH 4.1: counts far beyond the file refused before any allocation.
      {h41 + "$Nodes\n" + Bin{false, {}}.u64(1).u64(uint64_t(1) << 40).u64(1).u64(1).s,
       "$Nodes: the node count 1099511627776 does not fit"},
      {h41 + "$Nodes\n" + Bin{false, {}}.u64(~uint64_t(0)).s,
       "$Nodes: the entity block count 18446744073709551615 is not a count"},
      {h41 + "$Nodes\n" +
           Bin{false, {}}
               .u64(1)
               .u64(1)
               .u64(1)
               .u64(1)
               .i32(3)
               .i32(1)
               .i32(0)
               .u64(2)
               .u64(1)
               .u64(2)
               .f64(0)
               .f64(0)
               .f64(0)
               .f64(0)
               .f64(0)
               .f64(0)
               .s,
       "$Nodes: node block 1 holds 2 nodes, more than $Nodes announces"},
      {h41 + "$Entities\n" + Bin{false, {}}.u64(0).u64(0).u64(0).u64(1).i32(1).f64(0).f64(0).f64(0).f64(0).s,
       "$Entities: the file ends inside entity 1 of dimension 3"},
      {h41 + "$Nodes\n" + Bin{false, {}}.u64(1).u64(1).u64(1).u64(1).i32(3).i32(1).i32(0).u64(1).u64(1).f64(0).f64(0).f64(0).s +
           "\n$EndNodes\n$Elements\n" + Bin{false, {}}.u64(1).u64(1).u64(1).u64(1).i32(3).i32(1).i32(4).u64(uint64_t(1) << 50).s,
       "$Elements: the block's element count 1125899906842624 does not fit"},
  };
  for (Case const& c : cases) {
    INFO(c.bytes);
    CHECK_THROWS_WITH(read_gmsh_from_memory(c.bytes, "hand.msh"), Catch::Contains(c.message));
  }
  // An element type cellray cannot size cannot be skipped in binary.
  ReadOptions skip;
  skip.skip_unsupported_cells = true;
  CHECK_THROWS_WITH(
      read_gmsh_from_memory(n22 + "$Elements\n1\n" + group(135, 1, 0) + Bin{false, {}}.i32(1).i32(1).i32(2).i32(3).i32(4).s,
                            "hand.msh", skip),
      Catch::Contains("element type 135 is not one cellray knows: its node count"));
}

TEST_CASE("gmsh's binary files read as its ASCII files of the same mesh: MSH 2.2, 4.1, second order, node and element views",
          "[io][gmsh][binary]") {
  auto file = [](char const* name) { return std::string(CELLRAY_TEST_DATA) + "/gmsh/" + name; };
  for (auto const& [ascii, binary] : {std::pair{"mixed22.msh", "mixed22_bin.msh"}, std::pair{"mixed41.msh", "mixed41_bin.msh"},
                                      std::pair{"layer22_order2.msh", "layer22_order2_bin.msh"},
                                      std::pair{"views22.msh", "views22_bin.msh"}, std::pair{"views41.msh", "views41_bin.msh"}}) {
    INFO(binary);
    UnstructuredGrid const a = read_mesh(file(ascii)), b = read_mesh(file(binary));
    CHECK(b.report.format.find(" binary") != std::string::npos);
    CHECK(a.report.format.find(" ASCII") != std::string::npos);
    check_same_grid(a, b);
  }
  // The views: T = x + 10y + 100z at every node, q on every prism.
  for (char const* name : {"views22_bin.msh", "views41_bin.msh"}) {
    INFO(name);
    UnstructuredGrid const g = read_mesh(file(name));
    PointArray const* t = g.point_array("T");
    REQUIRE(t);
    REQUIRE(t->values.size() == g.vertex_count());
    for (uint64_t v = 0; v < g.vertex_count(); ++v)
      CHECK(t->values[v] == Approx(g.xyz[3 * v] + 10 * g.xyz[3 * v + 1] + 100 * g.xyz[3 * v + 2]).margin(1e-4));
    CellArray const* q = g.cell_array("q");
    REQUIRE(q);
    CHECK(q->hex_values.size() == 52);
    CHECK(std::none_of(q->hex_values.begin(), q->hex_values.end(), [](float v) { return v != v || v <= 0; }));
  }
  // MSH 4.0 (gmsh -format msh40): the mesh MSH 4.1 gives.
  UnstructuredGrid const g40 = read_mesh(file("layer40.msh")), g41 = read_mesh(file("views41.msh"));
  CHECK(g40.report.format == "gmsh MSH 4.0 ASCII");
  CHECK(same_bits(g40.xyz, g41.xyz));
  CHECK(g40.hexes == g41.hexes);
  REQUIRE(g40.cell_array("gmsh:geometrical"));
  CHECK(same_bits(g40.cell_array("gmsh:geometrical")->hex_values, g41.cell_array("gmsh:geometrical")->hex_values));
}

}  // namespace test_io_gmsh
