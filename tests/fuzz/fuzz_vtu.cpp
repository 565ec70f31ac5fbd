// libFuzzer harness: the VTU reader (ascii, inline base64, appended raw and
// base64, zlib blocks, 32/64-bit headers, both byte orders) on arbitrary
// bytes. It must return a consistent grid or throw IoError; anything else is
// a finding. Seeds: tests/fuzz/seeds/vtu, tests/data/broken.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include <cellray/io/vtu.hpp>

#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(uint8_t const* data, size_t size) {
  std::string_view const bytes(reinterpret_cast<char const*>(data), size);
  cellray::ReadOptions opts;
  opts.skip_unsupported_cells = size % 2 == 1;
  cellray::UnstructuredGrid grid;
  try {
    grid = cellray::read_vtu_from_memory(bytes, "fuzz.vtu", opts);
  } catch (cellray::IoError const&) {
    return 0;
  }
  cellray::fuzz::check_grid(grid);
  return 0;
}
