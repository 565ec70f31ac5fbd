// Where the tests find real meshes (support/test_data.hpp): the repository's
// copies in tests/data/real, and $CELLRAY_DATA_DIR for the larger files,
// whose absence skips a test case instead of failing it. The two hidden
// cases are run by the "data: ..." ctests (tests/CMakeLists.txt) with
// CELLRAY_DATA_DIR pointing nowhere: the run must exit 77 and name the file,
// or fail when an assertion failed too.

#include <catch2/catch.hpp>

#include <cstdlib>
#include <optional>
#include <string>
#include <sys/stat.h>

#include "support/test_data.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_io_data_dir {

using namespace cellray;

namespace {

bool regular_file(std::string const& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

/// Sets CELLRAY_DATA_DIR for one scope and restores it after.
struct DataDirOverride {
  std::optional<std::string> old;
  explicit DataDirOverride(std::string const& dir) {
    if (char const* e = std::getenv("CELLRAY_DATA_DIR")) old = e;
    ::setenv("CELLRAY_DATA_DIR", dir.c_str(), 1);
  }
  ~DataDirOverride() {
    if (old) ::setenv("CELLRAY_DATA_DIR", old->c_str(), 1);
    else ::unsetenv("CELLRAY_DATA_DIR");
  }
  DataDirOverride(DataDirOverride const&) = delete;
  DataDirOverride& operator=(DataDirOverride const&) = delete;
};

}  // namespace

TEST_CASE("the small real meshes are in the repository", "[io][data]") {
  for (char const* rel : {"vtk-data/post.vtk", "vtk-data/disk_out_ref.vtu", "vtk-data/hexa.vtk",
                          "vtk-data/Tetrahedron.vtu", "vtk-data/tetraMesh.vtk", "openfoam/component8_heat_84k.vtk",
                          "openfoam/flange_heat.vtk"}) {
    CAPTURE(rel);
    CHECK(regular_file(test::real_file(rel)));
  }
}

TEST_CASE("shared_data_file looks in $CELLRAY_DATA_DIR at run time", "[io][data]") {
  DataDirOverride const env(std::string(CELLRAY_TEST_DATA) + "/real");
  CHECK(test::shared_data_dir() == std::string(CELLRAY_TEST_DATA) + "/real");
  auto const post = test::shared_data_file("vtk-data/post.vtk");
  REQUIRE(post);
  CHECK(*post == test::real_file("vtk-data/post.vtk"));
  ::setenv("CELLRAY_DATA_DIR", "", 1);  // empty: the default, ../shared/data
  CHECK(test::shared_data_dir() == CELLRAY_DEFAULT_DATA_DIR);
}

TEST_CASE("data-dir check: a missing file skips the test case", "[.data-skip-check]") {
  CHECK_FALSE(test::shared_data_file("no/such/mesh.vtk"));
}

TEST_CASE("data-dir check: a failure wins over a skip", "[.data-skip-fail]") {
  CHECK_FALSE(test::shared_data_file("no/such/mesh.vtk"));
  CHECK(1 + 1 == 3);
}

}  // namespace test_io_data_dir
