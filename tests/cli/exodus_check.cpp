// cellray-render's Exodus II reader (examples/exodus.hpp) against VTK: the
// four cells VTK 9.1 wrote both as four_cells.e (vtkExodusIIWriter) and as
// four_cells.vtu (data/make_four_cells.py) must read as the same cells, the
// same positively oriented shapes, with the same point array.
// usage: exodus_check <dir holding four_cells.e and four_cells.vtu>

#include <cstdio>
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
  std::printf("%s\n%s\n", e.report.summary().c_str(), failures ? "FAILED" : "passed");
  return failures ? 1 : 0;
}
