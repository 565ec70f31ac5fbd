// ParaView .pvtu input (io/pvtu.hpp): real meshes written as k pieces
// (support/write_vtu.hpp) read back cell by cell, bitwise; the index's
// errors name the .pvtu, the piece and the array; merge_grids keeps only the
// arrays every grid has.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <vector>

#include <cellray/io/pvtu.hpp>
#include <cellray/io/read_mesh.hpp>

#include "support/test_data.hpp"
#include "support/write_vtu.hpp"

// One namespace per file: a stage's files compile as one unity TU.
namespace test_io_pvtu {

using namespace cellray;
using test::real_file;

namespace {

/// A fresh folder of its own: ctest runs test cases as parallel processes.
std::string scratch(std::string const& name) {
  std::string const dir = (std::filesystem::temp_directory_path() /
                           ("cellray_pvtu_" + name + "_" + std::to_string(::getpid()))).string();
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

void write_text(std::string const& path, std::string const& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  REQUIRE(out.good());
}

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

/// Cell by cell, corner by corner: positions and every point array equal
/// bitwise; cell arrays too; the same arrays in the same order.
void check_same_cells(UnstructuredGrid const& a, UnstructuredGrid const& b) {
  REQUIRE(a.tet_count() == b.tet_count());
  REQUIRE(a.hex_count() == b.hex_count());
  REQUIRE(a.point_arrays.size() == b.point_arrays.size());
  for (size_t k = 0; k < a.point_arrays.size(); ++k) {
    CHECK(a.point_arrays[k].name == b.point_arrays[k].name);
    REQUIRE(b.point_arrays[k].values.size() == b.vertex_count());
  }
  REQUIRE(a.cell_arrays.size() == b.cell_arrays.size());
  for (size_t k = 0; k < a.cell_arrays.size(); ++k) CHECK(a.cell_arrays[k].name == b.cell_arrays[k].name);
  uint64_t bad = 0;
  auto same_corner = [&](uint32_t va, uint32_t vb) {
    for (int d = 0; d < 3; ++d) bad += bits(a.xyz[3 * uint64_t(va) + uint64_t(d)]) != bits(b.xyz[3 * uint64_t(vb) + uint64_t(d)]);
    for (size_t k = 0; k < a.point_arrays.size(); ++k)
      bad += bits(a.point_arrays[k].values[va]) != bits(b.point_arrays[k].values[vb]);
  };
  for (size_t i = 0; i < a.tets.size(); ++i) same_corner(a.tets[i], b.tets[i]);
  for (size_t i = 0; i < a.hexes.size(); ++i) same_corner(a.hexes[i], b.hexes[i]);
  for (size_t k = 0; k < a.cell_arrays.size(); ++k) {
    auto const& ca = a.cell_arrays[k];
    auto const& cb = b.cell_arrays[k];
    REQUIRE(ca.tet_values.size() == cb.tet_values.size());
    REQUIRE(ca.hex_values.size() == cb.hex_values.size());
    for (size_t i = 0; i < ca.tet_values.size(); ++i) bad += bits(ca.tet_values[i]) != bits(cb.tet_values[i]);
    for (size_t i = 0; i < ca.hex_values.size(); ++i) bad += bits(ca.hex_values[i]) != bits(cb.hex_values[i]);
  }
  CHECK(bad == 0);
}

void round_trip(std::string const& mesh, std::vector<int> const& piece_counts, std::string const& dir_name) {
  UnstructuredGrid const g = read_mesh(real_file(mesh));
  REQUIRE(!g.empty());
  REQUIRE(!g.point_arrays.empty());
  std::vector<bool> is_used(g.vertex_count());
  for (uint32_t v : g.tets) is_used[v] = true;
  for (uint32_t v : g.hexes) is_used[v] = true;
  uint64_t const used = uint64_t(std::count(is_used.begin(), is_used.end(), true));
  std::string const dir = scratch(dir_name);
  for (int k : piece_counts) {
    CAPTURE(mesh, k);
    std::string const stem = dir + "/mesh" + std::to_string(k);
    test::write_pvtu_pieces(g, k, stem);
    PvtuIndex const index = read_pvtu_index(stem + ".pvtu");
    REQUIRE(index.pieces.size() == size_t(k));
    CHECK(index.pieces[0] == dir + "/mesh" + std::to_string(k) + "_0.vtu");
    CHECK(index.point_arrays.size() == g.point_arrays.size());
    CHECK(index.cell_arrays.size() == g.cell_arrays.size());
    UnstructuredGrid const r = read_pvtu(stem + ".pvtu");
    check_same_cells(g, r);
    CHECK(r.report.file == stem + ".pvtu");
    uint64_t counted = 0;
    for (auto const& [type, n] : r.report.cells_read) counted += n;
    CHECK(counted == r.tet_count() + r.hex_count());
    // Each piece holds the points its cells use; border points are written
    // once per piece and not welded.
    if (k == 1) CHECK(r.vertex_count() == used);
    else CHECK(r.vertex_count() > used);
    // The pieces one by one, as a distributed reader takes them.
    uint64_t cells = 0;
    for (size_t i = 0; i < index.pieces.size(); ++i) {
      UnstructuredGrid const p = read_pvtu_piece(index, i);
      cells += p.tet_count() + p.hex_count();
      CHECK(p.point_arrays.size() == g.point_arrays.size());
    }
    CHECK(cells == g.tet_count() + g.hex_count());
  }
  std::filesystem::remove_all(dir);
}

std::string const vtu_piece =
    "<?xml version=\"1.0\"?>\n"
    "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\">\n"
    "<UnstructuredGrid><Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n"
    "<PointData><DataArray type=\"Float32\" Name=\"p\" format=\"ascii\">1 2 3 4</DataArray></PointData>\n"
    "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>\n"
    "<Cells>\n"
    "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>\n"
    "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n"
    "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray>\n"
    "</Cells></Piece></UnstructuredGrid></VTKFile>\n";

std::string pvtu(std::string const& body, std::string const& type = "PUnstructuredGrid") {
  return "<?xml version=\"1.0\"?>\n<VTKFile type=\"" + type + "\" version=\"1.0\">\n" + body + "</VTKFile>\n";
}

std::string message_of(std::string const& path) {
  try {
    (void)read_mesh(path);
  } catch (IoError const& e) {
    return e.what();
  }
  return "no IoError";
}

}  // namespace

TEST_CASE("hexa.vtk as a .pvtu of 1, 3, 4 and more pieces than cells reads back cell by cell", "[io][pvtu]") {
  UnstructuredGrid const g = read_mesh(real_file("vtk-data/hexa.vtk"));
  int const cells = int(g.tet_count() + g.hex_count());
  round_trip("vtk-data/hexa.vtk", {1, 3, 4, cells + 3}, "hexa");
}

TEST_CASE("component8_heat_84k.vtk as a .pvtu of 1, 3 and 4 pieces reads back cell by cell", "[io][pvtu]") {
  round_trip("openfoam/component8_heat_84k.vtk", {1, 3, 4}, "c8");
}

TEST_CASE("read_mesh reads a .pvtu, read_mesh_from_memory refuses one", "[io][pvtu]") {
  std::string const dir = scratch("dispatch");
  write_text(dir + "/a.vtu", vtu_piece);
  write_text(dir + "/b.vtu", vtu_piece);
  std::string const index = pvtu("<PUnstructuredGrid GhostLevel=\"0\">\n"
                                 "<PPointData><PDataArray type=\"Float32\" Name=\"p\"/></PPointData>\n"
                                 "<Piece Source=\"a.vtu\"/>\n<Piece Source=\"" + dir + "/b.vtu\"/>\n"
                                 "</PUnstructuredGrid>\n");
  write_text(dir + "/two.PVTU", index);
  UnstructuredGrid const g = read_mesh(dir + "/two.PVTU");
  CHECK(g.tet_count() == 2);
  CHECK(g.vertex_count() == 8);  // not welded
  CHECK(g.tets == std::vector<uint32_t>{0, 1, 2, 3, 4, 5, 6, 7});
  REQUIRE(g.point_array("p"));
  CHECK(g.point_array("p")->values == std::vector<float>{1, 2, 3, 4, 1, 2, 3, 4});
  CHECK(g.report.cells_read.at(10) == 2);
  CHECK(g.report.format.rfind("VTK XML PUnstructuredGrid, 2 pieces", 0) == 0);
  CHECK_THROWS_WITH(read_mesh_from_memory(index, "two.pvtu"),
                    Catch::StartsWith("two.pvtu: ") && Catch::Contains("must be read from disk"));
  CHECK_THROWS_WITH(read_mesh(dir + "/x.pvtx"), Catch::Contains("(cellray reads .vtk, .vtu, .pvtu and .msh)"));
  // ParaView 5.6 and later put the pieces in a folder named like the .pvtu.
  std::filesystem::create_directories(dir + "/sub");
  write_text(dir + "/sub/c.vtu", vtu_piece);
  write_text(dir + "/sub.pvtu", pvtu("<PUnstructuredGrid>\n<Piece Source=\"sub/c.vtu\"/>\n</PUnstructuredGrid>\n"));
  CHECK(read_pvtu_index(dir + "/sub.pvtu").pieces == std::vector<std::string>{dir + "/sub/c.vtu"});
  CHECK(read_mesh(dir + "/sub.pvtu").tet_count() == 1);
  std::filesystem::remove_all(dir);
}

TEST_CASE("a broken .pvtu raises IoError naming the .pvtu, the place and the problem", "[io][pvtu]") {
  std::string const dir = scratch("broken");
  write_text(dir + "/a.vtu", vtu_piece);
  write_text(dir + "/a.vtk", "# vtk DataFile Version 3.0\n");
  struct Case {
    char const* file;
    std::string text;
    char const* where;
    std::string says;
  } const cases[] = {
      {"not_xml.pvtu", "this is not <xml", ":1: ", "XML error"},
      {"vtu_root.pvtu", pvtu("<UnstructuredGrid/>\n", "UnstructuredGrid"), ":2: ",
       "VTK XML type 'UnstructuredGrid' is not a parallel unstructured grid"},
      {"no_vtkfile.pvtu", "<?xml version=\"1.0\"?>\n<Other/>\n", ":1: ", "no VTKFile element"},
      {"no_pug.pvtu", pvtu("<PPointData/>\n"), ":2: ", "no PUnstructuredGrid element"},
      {"no_piece.pvtu", pvtu("<PUnstructuredGrid>\n<PPointData/>\n</PUnstructuredGrid>\n"), ":3: ", "no Piece element"},
      {"no_source.pvtu", pvtu("<PUnstructuredGrid>\n<Piece Source=\"a.vtu\"/>\n<Piece/>\n</PUnstructuredGrid>\n"), ":5: ",
       "Piece 1 has no Source attribute"},
      {"missing_piece.pvtu", pvtu("<PUnstructuredGrid>\n<Piece Source=\"gone.vtu\"/>\n</PUnstructuredGrid>\n"), ":4: ",
       "piece 0: " + dir + "/gone.vtu does not exist (Source='gone.vtu')"},
  };
  for (auto const& c : cases) {
    std::string const path = dir + "/" + c.file;
    write_text(path, c.text);
    std::string const msg = message_of(path);
    CAPTURE(path, msg);
    CHECK(msg.rfind(path + c.where, 0) == 0);
    CHECK(msg.find(c.says) != std::string::npos);
  }

  // A piece that is not a .vtu, and a piece the .vtu reader refuses: the
  // message starts with the piece and names the .pvtu.
  write_text(dir + "/vtk_piece.pvtu", pvtu("<PUnstructuredGrid>\n<Piece Source=\"a.vtk\"/>\n</PUnstructuredGrid>\n"));
  CHECK_THROWS_WITH(read_mesh(dir + "/vtk_piece.pvtu"),
                    Catch::StartsWith(dir + "/a.vtk (piece 0 of " + dir + "/vtk_piece.pvtu)") &&
                        Catch::Contains("must be a .vtu file"));
  write_text(dir + "/bad.vtu", "<VTKFile type=\"PolyData\"/>\n");
  write_text(dir + "/bad_piece.pvtu",
             pvtu("<PUnstructuredGrid>\n<Piece Source=\"a.vtu\"/><Piece Source=\"bad.vtu\"/>\n</PUnstructuredGrid>\n"));
  CHECK_THROWS_WITH(read_mesh(dir + "/bad_piece.pvtu"),
                    Catch::StartsWith(dir + "/bad.vtu:1: ") && Catch::Contains("'PolyData' is not supported") &&
                        Catch::EndsWith("(piece 1 of " + dir + "/bad_piece.pvtu)"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("a piece lacking an array the .pvtu declares is an error naming piece, .pvtu and array", "[io][pvtu]") {
  std::string const dir = scratch("lacking");
  write_text(dir + "/a.vtu", vtu_piece);
  std::string const path = dir + "/lacking.pvtu";
  write_text(path, pvtu("<PUnstructuredGrid>\n"
                        "<PPointData><PDataArray type=\"Float32\" Name=\"p\"/><PDataArray type=\"Float64\" Name=\"T\"/>"
                        "<PDataArray type=\"String\" Name=\"label\"/></PPointData>\n"
                        "<Piece Source=\"a.vtu\"/>\n</PUnstructuredGrid>\n"));
  PvtuIndex const index = read_pvtu_index(path);
  CHECK(index.point_arrays == std::vector<std::string>{"p", "T"});  // a String array is no array cellray reads
  CHECK(index.cell_arrays.empty());
  std::string const says = dir + "/a.vtu (piece 0 of " + path + ") does not match the .pvtu: no point array 'T' " +
                           "(PPointData declares p, T)";
  CHECK_THROWS_WITH(read_pvtu_piece(index, 0), says);
  CHECK_THROWS_WITH(read_mesh(path), says);
  CHECK_THROWS_AS(read_pvtu_piece(index, 1), InvalidArgument);

  // Cell arrays likewise.
  write_text(path, pvtu("<PUnstructuredGrid>\n<PCellData><PDataArray type=\"Int32\" Name=\"region\"/></PCellData>\n"
                        "<Piece Source=\"a.vtu\"/>\n</PUnstructuredGrid>\n"));
  CHECK_THROWS_WITH(read_mesh(path), Catch::StartsWith(dir + "/a.vtu (piece 0 of " + path + ")") &&
                                         Catch::Contains("no cell array 'region' (PCellData declares region)"));

  // An array the piece has but the .pvtu does not declare is dropped, and said so.
  write_text(path, pvtu("<PUnstructuredGrid>\n<Piece Source=\"a.vtu\"/>\n</PUnstructuredGrid>\n"));
  UnstructuredGrid const g = read_mesh(path);
  CHECK(g.point_arrays.empty());
  REQUIRE(g.report.arrays_ignored.size() == 1);
  CHECK(g.report.arrays_ignored[0] == "point 'p' (not declared in the .pvtu)");
  std::filesystem::remove_all(dir);
}

TEST_CASE("cells vtkGhostType marks as duplicates (GhostLevel > 0) are dropped, not merged twice", "[io][pvtu]") {
  std::string const dir = scratch("ghosts");
  write_text(dir + "/a.vtu", vtu_piece);
  write_text(dir + "/g.vtu",
             "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\">\n"
             "<UnstructuredGrid><Piece NumberOfPoints=\"5\" NumberOfCells=\"2\">\n"
             "<PointData><DataArray type=\"Float32\" Name=\"p\" format=\"ascii\">5 6 7 8 9</DataArray></PointData>\n"
             "<CellData><DataArray type=\"UInt8\" Name=\"vtkGhostType\" format=\"ascii\">0 1</DataArray>\n"
             "<DataArray type=\"Float32\" Name=\"c\" format=\"ascii\">10 11</DataArray></CellData>\n"
             "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">"
             "0 0 0 1 0 0 0 1 0 0 0 1 1 1 1</DataArray></Points>\n<Cells>\n"
             "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">1 2 3 4 0 1 2 3</DataArray>\n"
             "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">4 8</DataArray>\n"
             "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10 10</DataArray>\n"
             "</Cells></Piece></UnstructuredGrid></VTKFile>\n");
  std::string const path = dir + "/ghosts.pvtu";
  write_text(path, pvtu("<PUnstructuredGrid GhostLevel=\"1\">\n"
                        "<PPointData><PDataArray type=\"Float32\" Name=\"p\"/></PPointData>\n"
                        "<Piece Source=\"a.vtu\"/>\n<Piece Source=\"g.vtu\"/>\n</PUnstructuredGrid>\n"));
  UnstructuredGrid const g = read_mesh(path);
  CHECK(g.tet_count() == 2);
  CHECK(g.tets == std::vector<uint32_t>{0, 1, 2, 3, 5, 6, 7, 8});
  CHECK(g.tet_file_cells == std::vector<uint32_t>{0, 1});  // the ghost was cell 2 of the .pvtu's 3
  CHECK(g.cell_arrays.empty());  // the .pvtu declares none
  CHECK(std::count(g.report.arrays_ignored.begin(), g.report.arrays_ignored.end(),
                   "cell 'vtkGhostType' flags 1 duplicate ghost cells: dropped, another piece owns them") == 1);
  std::filesystem::remove_all(dir);
}

TEST_CASE("merge_grids appends vertices and cells and keeps only the arrays every grid has", "[io][pvtu]") {
  auto grid = [](float x0, std::vector<char const*> point_names, std::vector<char const*> cell_names, bool hex) {
    UnstructuredGrid g;
    int const n = hex ? 8 : 4;
    for (int i = 0; i < n; ++i) g.xyz.insert(g.xyz.end(), {x0 + float(i), 0.f, float(i % 2)});
    for (int i = 0; i < n; ++i) (hex ? g.hexes : g.tets).push_back(uint32_t(i));
    for (auto const* name : point_names) g.point_arrays.push_back(PointArray{name, 1, std::vector<float>(size_t(n), x0)});
    for (auto const* name : cell_names) {
      CellArray c{name, 1, {}, {}};
      (hex ? c.hex_values : c.tet_values).push_back(x0);
      g.cell_arrays.push_back(c);
    }
    g.report.file = "g" + std::to_string(int(x0));
    g.report.cells_read[hex ? 12 : 10] = 1;
    g.report.reduced_to_linear = 1;
    g.report.arrays_ignored.push_back("field 'TimeValue' (dataset field data)");
    return g;
  };
  std::vector<UnstructuredGrid> grids;
  grids.push_back(grid(0, {"T", "p", "only0"}, {"c", "region"}, false));
  grids.push_back(grid(10, {"p", "T"}, {"region"}, true));
  grids.push_back(grid(20, {"T", "p", "only2"}, {"region", "c"}, false));
  grids.push_back(UnstructuredGrid{});  // no vertices, no cells: lacks nothing
  UnstructuredGrid const m = merge_grids(std::move(grids));
  CHECK(m.vertex_count() == 16);
  CHECK(m.tets == std::vector<uint32_t>{0, 1, 2, 3, 12, 13, 14, 15});
  CHECK(m.hexes == std::vector<uint32_t>{4, 5, 6, 7, 8, 9, 10, 11});
  // Tets and a hexahedron: each cell's id in the merged file numbering.
  CHECK(m.tet_file_cells == std::vector<uint32_t>{0, 2});
  CHECK(m.hex_file_cells == std::vector<uint32_t>{1});
  CHECK(m.xyz[3 * 4] == 10.f);
  REQUIRE(m.point_arrays.size() == 2);
  CHECK(m.point_arrays[0].name == "T");  // the first grid's order
  CHECK(m.point_arrays[1].name == "p");
  CHECK(m.point_arrays[0].values.size() == 16);
  CHECK(m.point_arrays[1].values[5] == 10.f);
  CHECK(!m.point_array("only0"));
  CHECK(!m.point_array("only2"));
  REQUIRE(m.cell_arrays.size() == 1);
  CHECK(m.cell_arrays[0].name == "region");
  CHECK(m.cell_arrays[0].tet_values == std::vector<float>{0, 20});
  CHECK(m.cell_arrays[0].hex_values == std::vector<float>{10});
  CHECK(m.report.file == "g0");
  CHECK(m.report.cells_read.at(10) == 2);
  CHECK(m.report.cells_read.at(12) == 1);
  CHECK(m.report.reduced_to_linear == 3);
  CHECK(m.report.arrays_read == std::vector<std::string>{"point 'T'", "point 'p'", "cell 'region'"});
  CHECK(m.report.arrays_ignored ==
        std::vector<std::string>{"field 'TimeValue' (dataset field data)", "point 'only0' (not in every merged grid)",
                                 "cell 'c' (not in every merged grid)", "point 'only2' (not in every merged grid)"});
  CHECK(merge_grids({}).empty());
}

}  // namespace test_io_pvtu
