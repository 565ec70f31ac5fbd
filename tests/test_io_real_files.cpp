// Every real mesh in ../shared/data loads, and its counts and ranges match
// the README there (read back with VTK 9.1, an independent implementation).
// The small ones are read from the repository's copies (tests/data/real),
// the others from $CELLRAY_DATA_DIR, skipped when missing there.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/validate.hpp>

#include "support/test_data.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_io_real_files {

using namespace cellray;
using test::real_file;

namespace {

std::pair<float, float> range(std::vector<float> const& a, std::vector<float> const& b = {}) {
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  for (auto const* v : {&a, &b})
    for (float x : *v) lo = std::min(lo, x), hi = std::max(hi, x);
  return {lo, hi};
}

/// The README prints 6 significant digits: a half unit in the 6th digit is
/// at most 5e-6 relative, plus float rounding (6e-8). Zero needs a margin.
bool readme_equal(float got, double printed, double rel = 6e-6) {
  return std::abs(double(got) - printed) <= rel * std::abs(printed) + 1e-30;
}

void check_point(UnstructuredGrid const& g, char const* name, double lo, double hi) {
  CAPTURE(name);
  PointArray const* a = g.point_array(name);
  REQUIRE(a);
  REQUIRE(a->values.size() == g.vertex_count());
  auto const [l, h] = range(a->values);
  CHECK(readme_equal(l, lo));
  CHECK(readme_equal(h, hi));
}

void check_cell(UnstructuredGrid const& g, char const* name, double lo, double hi) {
  CAPTURE(name);
  CellArray const* a = g.cell_array(name);
  REQUIRE(a);
  REQUIRE(a->tet_values.size() == g.tet_count());
  REQUIRE(a->hex_values.size() == g.hex_count());
  auto const [l, h] = range(a->tet_values, a->hex_values);
  CHECK(readme_equal(l, lo));
  CHECK(readme_equal(h, hi));
}

/// validate() (mesh/) agrees that the views are sound: every index in range,
/// every position finite.
void check_views(UnstructuredGrid const& g) {
  if (g.tet_count()) CHECK(validate(g.tet_mesh()).ok());
  if (g.hex_count()) CHECK(validate(g.hex_mesh()).ok());
}

}  // namespace

TEST_CASE("vtk-data/Tetrahedron.vtu (appended raw, UInt64, Int64 connectivity)", "[io][data]") {
  UnstructuredGrid const g = read_mesh(real_file("vtk-data/Tetrahedron.vtu"));
  CHECK(g.tet_count() == 96);
  CHECK(g.hex_count() == 0);
  CHECK(g.vertex_count() == 35);
  CHECK(g.point_arrays.size() == 2);
  check_point(g, "DistanceToCenter", 0, 1.73205);
  check_point(g, "Polynomial", 1, 7);
  check_views(g);
}

TEST_CASE("vtk-data/tetraMesh.vtk (legacy 2.0 ASCII, int scalars, empty CELL_DATA)", "[io][data]") {
  UnstructuredGrid const g = read_mesh(real_file("vtk-data/tetraMesh.vtk"));
  CHECK(g.tet_count() == 160);
  CHECK(g.vertex_count() == 55);
  check_point(g, "scalars", 0, 4);
  CHECK(g.cell_arrays.empty());
  check_views(g);
}

TEST_CASE("vtk-data/notch_stress_fixed.vtk (5.1 BINARY, hexes + 4 wedges)", "[io][data]") {
  auto const file = test::shared_data_file("vtk-data/notch_stress_fixed.vtk");
  if (!file) return;
  std::string const& path = *file;
  UnstructuredGrid const g = read_mesh(path);
  CHECK(g.report.format == "legacy VTK 5.1 BINARY");
  CHECK(g.hex_count() == 2188 + 4);  // the wedges as collapsed hexahedra
  CHECK(g.tet_count() == 0);
  CHECK(g.report.cells_read.at(12) == 2188);
  CHECK(g.report.cells_read.at(13) == 4);
  CHECK(g.report.skipped_count() == 0);
  CHECK(g.vertex_count() == 3537);
  check_point(g, "Nodal Stress-0", -1.45362e5, 8.10777e6);
  check_point(g, "Nodal Stress-normed", 3206.61, 8.1098e6);
  REQUIRE(g.point_array("Nodal Stress"));
  CHECK(g.point_array("Nodal Stress")->components == 6);
  check_views(g);
}

TEST_CASE("vtk-data/can.vtu (appended raw, vector point data only)", "[io][data]") {
  auto const path = test::shared_data_file("vtk-data/can.vtu");
  if (!path) return;
  UnstructuredGrid const g = read_mesh(*path);
  CHECK(g.hex_count() == 4800);
  CHECK(g.vertex_count() == 6724);
  check_cell(g, "EQPS", 0.0215831, 2.89394);
  for (char const* v : {"DISPL", "VEL", "ACCL"}) {
    REQUIRE(g.point_array(v));
    CHECK(g.point_array(v)->components == 3);
  }
  // The README prints |DISPL| to 4 digits: [2.46, 18.59].
  auto const [lo, hi] = range(g.point_array("DISPL")->values);
  CHECK(std::abs(lo - 2.46) <= 0.005);
  CHECK(std::abs(hi - 18.59) <= 0.005);
  CHECK(g.point_array("GlobalNodeId"));
  CHECK(g.point_array("PedigreeNodeId"));
  check_views(g);
}

TEST_CASE("vtk-data/disk_out_ref.vtu (appended raw, zlib, float64 arrays)", "[io][data]") {
  UnstructuredGrid const g = read_mesh(real_file("vtk-data/disk_out_ref.vtu"));
  CHECK(g.hex_count() == 7472);
  CHECK(g.vertex_count() == 8499);
  CHECK(g.point_arrays.size() == 6);
  check_point(g, "Temp", 293.15, 913.15);
  check_point(g, "Pres", 0.00678552, 0.0288185);
  check_point(g, "AsH3", 0.0804768, 0.184839);
  check_point(g, "GaMe3", 0.000222844, 0.00721393);
  check_point(g, "CH4", 0, 0.00117024);
  check_point(g, "H2", 0.807613, 0.917688);
  check_views(g);
}

TEST_CASE("vtk-data/post.vtk (3.0 BINARY, FIELD point data)", "[io][data]") {
  UnstructuredGrid const g = read_mesh(real_file("vtk-data/post.vtk"));
  CHECK(g.tet_count() == 8750);
  CHECK(g.vertex_count() == 2288);
  check_point(g, "Pressure", 0.355368, 1.64124);
  check_views(g);
}

TEST_CASE("vtk-data/hexa.vtk (1.0 ASCII)", "[io][data]") {
  UnstructuredGrid const g = read_mesh(real_file("vtk-data/hexa.vtk"));
  CHECK(g.report.format == "legacy VTK 1.0 ASCII");
  CHECK(g.hex_count() == 10648);
  CHECK(g.vertex_count() == 12167);
  check_point(g, "scalars", 0.753065, 17.3205);
  check_views(g);
}

TEST_CASE("vtk-data/kiefer_dataset.vtu (base64 zlib, tetra10, cell data only)", "[io][data]") {
  auto const path = test::shared_data_file("vtk-data/kiefer_dataset.vtu");
  if (!path) return;
  UnstructuredGrid g = read_mesh(*path);
  CHECK(g.tet_count() == 56786);
  CHECK(g.vertex_count() == 102578);
  CHECK(g.report.cells_read.at(24) == 56786);
  CHECK(g.report.reduced_to_linear == 56786);
  CHECK(g.point_arrays.empty());
  char const* const name = "Equivalent (von-Mises) Stress (psi)";
  check_cell(g, name, 0.014035, 23.269);
  g.cell_to_point(name);
  PointArray const* p = g.point_array(name);
  REQUIRE(p);
  // Brute-force oracle on a sample of vertices: scan every tet for the vertex.
  std::vector<float> const& cv = g.cell_array(name)->tet_values;
  uint64_t used = 0;
  for (uint32_t v : g.tets) used = std::max<uint64_t>(used, v);
  for (uint64_t v = 0; v < g.vertex_count(); v += 997) {
    double sum = 0;
    int n = 0;
    for (uint64_t c = 0; c < g.tet_count(); ++c)
      for (int k = 0; k < 4; ++k)
        if (g.tets[4 * c + uint64_t(k)] == v) sum += cv[c], ++n;
    CAPTURE(v, n);
    if (n == 0) CHECK(std::isnan(p->values[v]));  // mid-edge nodes of the tetra10: no linear tet uses them
    else CHECK(p->values[v] == Approx(sum / n).epsilon(1e-6));  // float result of a double mean
  }
  TetMesh const m = g.tet_mesh();
  CHECK(m.active_array() == name);
  check_views(g);
}

TEST_CASE("openfoam/flange_heat.vtk (2.0 BINARY, hexes + 372 wedges, FIELD arrays)", "[io][data]") {
  std::string const path = real_file("openfoam/flange_heat.vtk");
  UnstructuredGrid const g = read_mesh(path);
  CHECK(g.hex_count() == 5340 + 372);  // the wedges as collapsed hexahedra
  CHECK(g.report.cells_read.at(13) == 372);
  CHECK(g.report.skipped_count() == 0);
  CHECK(g.vertex_count() == 7189);
  check_point(g, "T", 273, 573);
  // The README's cell range: hexes and wedges.
  auto const [lo, hi] = range(g.cell_array("T")->hex_values);
  CHECK(lo == Approx(273.002).epsilon(6e-6));
  CHECK(hi == Approx(572.837).epsilon(6e-6));
  CHECK(g.cell_array("T")->hex_values.size() == 5340 + 372);
  // Every wedge repeats two corners: 1 2 2 and 4 5 5 of its hexahedron.
  uint64_t collapsed = 0;
  for (uint64_t c = 0; c < g.hex_count(); ++c)
    collapsed += g.hexes[8 * c + 2] == g.hexes[8 * c + 3] && g.hexes[8 * c + 6] == g.hexes[8 * c + 7];
  CHECK(collapsed == 372);
  check_views(g);
}

TEST_CASE("openfoam/component8_heat_84k.vtk", "[io][data]") {
  UnstructuredGrid const g = read_mesh(real_file("openfoam/component8_heat_84k.vtk"));
  CHECK(g.tet_count() == 84438);
  CHECK(g.vertex_count() == 17667);
  check_point(g, "T", 273, 573);
  check_cell(g, "T", 273.123, 569.071);
  check_views(g);
}

TEST_CASE("openfoam/component8_heat_608k.vtk (19 MB)", "[io][data]") {
  auto const path = test::shared_data_file("openfoam/component8_heat_608k.vtk");
  if (!path) return;
  UnstructuredGrid const g = read_mesh(*path);
  CHECK(g.tet_count() == 608316);
  CHECK(g.vertex_count() == 112931);
  check_point(g, "T", 273, 573);
  check_cell(g, "T", 273.065, 571.02);
  check_views(g);
}

TEST_CASE("openfoam/boxturb48_dns.vtk (two point and two cell arrays)", "[io][data]") {
  auto const path = test::shared_data_file("openfoam/boxturb48_dns.vtk");
  if (!path) return;
  UnstructuredGrid const g = read_mesh(*path);
  CHECK(g.hex_count() == 110592);
  CHECK(g.vertex_count() == 117649);
  check_point(g, "enstrophy", 0.0015834, 0.717252);
  check_point(g, "p", -0.0333107, 0.0320973);
  check_cell(g, "enstrophy", 5.27667e-05, 0.723415);
  check_cell(g, "p", -0.0335067, 0.0322536);
  check_views(g);
}

}  // namespace test_io_real_files
