// Catch2 main that understands `--isa=NAME`: the ISA the [isa] tests of this
// run exercise. A CPU without that ISA (or a build without its units) exits
// 77, which ctest reports as skipped (SKIP_RETURN_CODE), so a missing ISA is
// never a silent pass.

#ifdef CELLRAY_TEST_PREBUILT_CATCH2
// Debian's compiled Catch2 runner with its main renamed (tests/CMakeLists.txt).
extern "C" int cellray_catch2_main(int argc, char** argv);
#else
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>
#endif

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
#ifdef CELLRAY_TEST_PREBUILT_CATCH2
  int const n = int(args.size());
  args.push_back(nullptr);  // argv[argc] is null, as for a real main
  return cellray_catch2_main(n, args.data());
#else
  return Catch::Session().run(int(args.size()), args.data());
#endif
}
