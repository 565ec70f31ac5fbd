// Catch2 main that understands `--isa=NAME`: the ISA the [isa] tests of this
// run exercise. A CPU without that ISA (or a build without its units) exits
// 77, which ctest reports as skipped (SKIP_RETURN_CODE), so a missing ISA is
// never a silent pass.

#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include <cstdio>
#include <cstring>
#include <vector>

#include "test_isa.hpp"

namespace {
cellray::Isa g_isa = cellray::best_isa();
}

cellray::Isa cellray::test::isa() { return g_isa; }

int main(int argc, char** argv) {
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (std::strncmp(argv[i], "--isa=", 6) == 0) {
      g_isa = cellray::parse_isa(argv[i] + 6);
      if (!cellray::isa_available(g_isa)) {
        std::printf("SKIPPED: %s\n", cellray::isa_unavailable_reason(g_isa).c_str());
        return 77;
      }
      continue;
    }
    args.push_back(argv[i]);
  }
  return Catch::Session().run(int(args.size()), args.data());
}
