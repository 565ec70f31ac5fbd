// cellray-render's Exodus II reader (examples/exodus.hpp) against VTK: the
// four cells VTK 9.1 wrote both as four_cells.e (vtkExodusIIWriter) and as
// four_cells.vtu (data/make_four_cells.py) must read as the same cells, the
// same positively oriented shapes, with the same point array. And a file
// written here through the Exodus library, whose element number map is not
// 1..n and whose first block is not of volume cells: validation names its
// cells by their element numbers.
// usage: exodus_check <dir holding four_cells.e and four_cells.vtu>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/validate.hpp>

#include "exodus.hpp"

int main(int argc, char** argv) {
  if (argc != 2) return std::fprintf(stderr, "usage: exodus_check DIR\n"), 2;
  std::string const dir = argv[1];
  cellray::UnstructuredGrid const e = cellray::cli::read_exodus(dir + "/four_cells.e");
  cellray::UnstructuredGrid const v = cellray::read_mesh(dir + "/four_cells.vtu");
  int failures = 0;
  auto expect = [&](bool ok, char const* what) {
    if (!ok) std::fprintf(stderr, "FAIL: %s\n", what), ++failures;
  };
  // Corner positions cell by cell (the files may number points alike or not).
  auto same = [&](std::vector<uint32_t> const& x, std::vector<uint32_t> const& y) {
    if (x.size() != y.size()) return false;
    for (size_t i = 0; i < x.size(); ++i)
      for (uint64_t k = 0; k < 3; ++k)
        if (e.xyz[3 * uint64_t(x[i]) + k] != v.xyz[3 * uint64_t(y[i]) + k]) return false;
    return true;
  };
  expect(e.tet_count() == 1 && e.hex_count() == 3, "1 tetrahedron and 3 hexahedra (hex, wedge, pyramid)");
  expect(same(e.tets, v.tets), "the tetrahedron's corners are the .vtu's");
  expect(same(e.hexes, v.hexes), "the hexahedron's, wedge's and pyramid's corners are the .vtu's");
  expect(!cellray::validate(e.hex_mesh()).inverted && !cellray::validate(e.tet_mesh()).inverted, "no cell inverted");
  cellray::PointArray const* t = e.point_array("T");
  expect(t && t->values.size() == 12 && t->values[11] == 111.f, "point array T read at every node");
  // vtkExodusIIWriter numbers the elements 1..4 in its blocks' order.
  expect(e.hex_file_cells == std::vector<uint32_t>{1, 2, 3} && e.tet_file_cells == std::vector<uint32_t>{4},
         "four_cells.e's cells carry their element numbers 1..4");

  // A shell block first (ignored), an inside-out hexahedron numbered 30 and
  // a tetrahedron numbered 20.
  std::string const numbered =
      (std::filesystem::temp_directory_path() / ("exodus_check_" + std::to_string(::getpid()) + ".e")).string();
  {
    int cpu = int(sizeof(double)), io = int(sizeof(double));
    int const exo = ex_create(numbered.c_str(), EX_CLOBBER, &cpu, &io);
    double const x[9] = {0, 1, 1, 0, 0, 1, 1, 0, -1}, y[9] = {0, 0, 1, 1, 0, 0, 1, 1, 0};
    double const z[9] = {0, 0, 0, 0, 1, 1, 1, 1, 0};
    int const shell[4] = {1, 2, 3, 4}, hex[8] = {5, 6, 7, 8, 1, 2, 3, 4}, tet[4] = {9, 1, 4, 5};
    int const map[3] = {500, 30, 20};
    bool const written = exo >= 0 && ex_put_init(exo, "numbered", 3, 9, 3, 3, 0, 0) >= 0 &&
                         ex_put_coord(exo, x, y, z) >= 0 &&
                         ex_put_block(exo, EX_ELEM_BLOCK, 1, "SHELL4", 1, 4, 0, 0, 0) >= 0 &&
                         ex_put_conn(exo, EX_ELEM_BLOCK, 1, shell, nullptr, nullptr) >= 0 &&
                         ex_put_block(exo, EX_ELEM_BLOCK, 2, "HEX8", 1, 8, 0, 0, 0) >= 0 &&
                         ex_put_conn(exo, EX_ELEM_BLOCK, 2, hex, nullptr, nullptr) >= 0 &&
                         ex_put_block(exo, EX_ELEM_BLOCK, 3, "TETRA4", 1, 4, 0, 0, 0) >= 0 &&
                         ex_put_conn(exo, EX_ELEM_BLOCK, 3, tet, nullptr, nullptr) >= 0 &&
                         ex_put_id_map(exo, EX_ELEM_MAP, map) >= 0;
    if (exo >= 0) ex_close(exo);
    expect(written, "the numbered file written through the Exodus library");
  }
  cellray::UnstructuredGrid const n = cellray::cli::read_exodus(numbered);
  std::filesystem::remove(numbered);
  expect(n.hex_file_cells == std::vector<uint32_t>{30} && n.tet_file_cells == std::vector<uint32_t>{20},
         "cells carry the element number map's ids, past an ignored block");
  cellray::ValidationReport const rep = cellray::validate(n.hex_mesh(), cellray::view(n.hex_file_cells));
  expect(rep.inverted.count == 1 && rep.inverted.first == 30 &&
             rep.message().find("first cell 30") != std::string::npos,
         "validation names the inside-out hexahedron by its element number");
  std::printf("%s\n", rep.message().c_str());
  std::printf("%s\n%s\n", e.report.summary().c_str(), failures ? "FAILED" : "passed");
  return failures ? 1 : 0;
}
