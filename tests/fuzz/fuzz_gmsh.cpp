// libFuzzer harness: the gmsh MSH reader (2.2 and 4.1 ASCII and binary, 4.0
// ASCII) on arbitrary bytes. It must return a consistent grid or throw
// IoError; anything else (another exception, a crash, a sanitizer report, a
// broken invariant) is a finding. Seeds: tests/fuzz/seeds/msh.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include <cellray/io/gmsh.hpp>

#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(uint8_t const* data, size_t size) {
  auto read = [](std::string_view bytes, char const* name, cellray::ReadOptions const& opts) {
    return cellray::read_gmsh_from_memory(bytes, name, opts);
  };
  return cellray::fuzz::fuzz_reader(data, size, "fuzz.msh", read);
}
