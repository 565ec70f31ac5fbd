// split_pvtu IN_MESH K OUT_STEM: reads a mesh (read_mesh: .vtk, .vtu, .pvtu)
// and writes it as OUT_STEM.pvtu with K pieces OUT_STEM_0.vtu .. (see
// tests/support/write_vtu.hpp). Exit 0, or 1 with a message on stderr.

#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>

#include <cellray/io/read_mesh.hpp>

#include "support/write_vtu.hpp"

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: split_pvtu IN_MESH K OUT_STEM  (writes OUT_STEM.pvtu and OUT_STEM_0.vtu ... OUT_STEM_{K-1}.vtu)\n";
    return 1;
  }
  std::string const k_text = argv[2];
  char* end = nullptr;
  long const k = std::strtol(k_text.c_str(), &end, 10);
  if (k_text.empty() || *end != '\0' || k < 1 || k > 100000) {
    std::cerr << "split_pvtu: K must be a whole number from 1 to 100000, not '" << k_text << "'\n";
    return 1;
  }
  try {
    cellray::UnstructuredGrid const grid = cellray::read_mesh(argv[1]);
    cellray::test::write_pvtu_pieces(grid, int(k), argv[3]);
  } catch (std::exception const& e) {
    std::cerr << "split_pvtu: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
