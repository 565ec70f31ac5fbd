#pragma once
// Where the tests find real meshes.
//
// - real_file("vtk-data/post.vtk"): the small meshes copied into the
//   repository (tests/data/real/, see its README.md). Always present.
// - shared_data_file("openfoam/boxturb48_dns.vtk"): the team's larger data
//   set, found at run time in $CELLRAY_DATA_DIR (default: ../shared/data
//   beside the repository). When the file is missing, the test case reports
//   "skipped: <path> missing (set CELLRAY_DATA_DIR)" as a Catch2 warning and
//   the run ends with exit code 77 if nothing failed (support/test_main.cpp),
//   which ctest shows as skipped. Usage:
//
//     auto const path = test::shared_data_file("openfoam/boxturb48_dns.vtk");
//     if (!path) return;  // reported as skipped, never passed

#include <catch2/catch.hpp>

#include <cstdlib>
#include <optional>
#include <string>
#include <sys/stat.h>

namespace cellray::test {

/// Records that this run lacked a data file (defined in test_main.cpp): the
/// run then exits 77 unless something failed.
void note_missing_data(std::string const& path);

/// $CELLRAY_DATA_DIR, or ../shared/data beside the repository.
inline std::string shared_data_dir() {
  char const* env = std::getenv("CELLRAY_DATA_DIR");
  return env && *env ? std::string(env) : std::string(CELLRAY_DEFAULT_DATA_DIR);
}

/// The repository's copy of a small real mesh (tests/data/real/<rel>).
inline std::string real_file(std::string const& rel) { return std::string(CELLRAY_TEST_DATA) + "/real/" + rel; }

/// <data dir>/<rel> when it is a readable regular file; otherwise reports the
/// test case as skipped (see above) and returns nothing.
inline std::optional<std::string> shared_data_file(std::string const& rel) {
  std::string const path = shared_data_dir() + "/" + rel;
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) return path;
  WARN("skipped: " << path << " missing (set CELLRAY_DATA_DIR)");
  note_missing_data(path);
  return std::nullopt;
}

}  // namespace cellray::test
