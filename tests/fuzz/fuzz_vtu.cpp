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
  auto read = [](std::string_view bytes, char const* name, cellray::ReadOptions const& opts) {
    return cellray::read_vtu_from_memory(bytes, name, opts);
  };
  return cellray::fuzz::fuzz_reader(data, size, "fuzz.vtu", read);
}
