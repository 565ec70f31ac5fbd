// libFuzzer harness: the gmsh MSH reader (2.2 and 4.1 ASCII) on arbitrary
// bytes. It must return a consistent grid or throw IoError; anything else
// (another exception, a crash, a sanitizer report, a broken invariant) is a
// finding. Seeds: tests/fuzz/seeds/msh.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include <cellray/io/gmsh.hpp>

#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(uint8_t const* data, size_t size) {
  std::string_view const bytes(reinterpret_cast<char const*>(data), size);
  cellray::ReadOptions opts;
  opts.skip_unsupported_cells = size % 2 == 1;  // both policies, chosen by the input
  cellray::UnstructuredGrid grid;
  try {
    grid = cellray::read_gmsh_from_memory(bytes, "fuzz.msh", opts);
  } catch (cellray::IoError const&) {
    return 0;
  }
  cellray::fuzz::check_grid(grid);
  return 0;
}
