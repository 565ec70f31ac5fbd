// Catch2 main that understands `--isa=NAME`: the ISA the [isa] tests of this
// run exercise. A CPU without that ISA (or a build without its units) exits
// 77, which ctest reports as skipped (SKIP_RETURN_CODE), so a missing ISA is
// never a silent pass.
//
// Missing data ends the same way: a test case whose file is absent from
// $CELLRAY_DATA_DIR (support/test_data.hpp: shared_data_file) is recorded
// here, and a run that lacked any file exits 77 when nothing failed, so
// ctest reports that test case as skipped. A run of many test cases exits 77
// too when some lacked data (it lists which files), and the failure count
// as usual when an assertion failed: failures always win over skips.

#ifdef CELLRAY_TEST_PREBUILT_CATCH2
// Debian's compiled Catch2 runner with its main renamed (tests/CMakeLists.txt).
extern "C" int cellray_catch2_main(int argc, char** argv);
#else
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>
#endif

#include <cstdio>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include "test_isa.hpp"

namespace cellray::test {
void note_missing_data(std::string const& path);
}

namespace {
cellray::Isa g_isa = cellray::best_isa();
std::set<std::string> g_missing_data;

int run_catch(std::vector<char*>& args) {
#ifdef CELLRAY_TEST_PREBUILT_CATCH2
  int const n = int(args.size());
  args.push_back(nullptr);  // argv[argc] is null, as for a real main
  return cellray_catch2_main(n, args.data());
#else
  return Catch::Session().run(int(args.size()), args.data());
#endif
}
}  // namespace

cellray::Isa cellray::test::isa() { return g_isa; }

void cellray::test::note_missing_data(std::string const& path) { g_missing_data.insert(path); }

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
  int const rc = run_catch(args);
  // Catch2 exits with the number of failed assertions (at most 255): 77 of
  // them must not read as "skipped".
  if (rc == 77) return 78;
  if (rc != 0 || g_missing_data.empty()) return rc;
  // One unwrapped line per file (Catch2 wraps its warnings at 80 columns).
  for (auto const& p : g_missing_data) std::printf("skipped: %s missing (set CELLRAY_DATA_DIR)\n", p.c_str());
  return 77;
}
