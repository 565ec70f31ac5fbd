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
  auto read = [](std::string_view bytes, char const* name, cellray::ReadOptions const& opts) {
    return cellray::read_vtk_legacy_from_memory(bytes, name, opts);
  };
  return cellray::fuzz::fuzz_reader(data, size, "fuzz.vtk", read);
}
