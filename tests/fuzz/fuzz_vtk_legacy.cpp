// libFuzzer harness: the legacy VTK reader (ASCII and BINARY, versions 1.0 to
// 5.1) on arbitrary bytes. It must return a consistent grid or throw IoError;
// anything else (another exception, a crash, a sanitizer report, a broken
// invariant) is a finding. Seeds: tests/fuzz/seeds/vtk, tests/data/broken.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include <cellray/io/vtk_legacy.hpp>

#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(uint8_t const* data, size_t size) {
  std::string_view const bytes(reinterpret_cast<char const*>(data), size);
  cellray::ReadOptions opts;
  opts.skip_unsupported_cells = size % 2 == 1;  // both policies, chosen by the input
  cellray::UnstructuredGrid grid;
  try {
    grid = cellray::read_vtk_legacy_from_memory(bytes, "fuzz.vtk", opts);
  } catch (cellray::IoError const&) {
    return 0;
  }
  cellray::fuzz::check_grid(grid);
  return 0;
}
