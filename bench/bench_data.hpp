#pragma once
// Where the benchmarks find real meshes: $CELLRAY_DATA_DIR, by default
// ../shared/data beside the repository (the team's data set; see
// tests/data/real/README.md for the files it holds). A missing file ends the
// run with a message naming it and exit code 2, not an uncaught exception.

#include <cstdio>
#include <cstdlib>
#include <string>
#include <sys/stat.h>

namespace cellray::bench {

/// <data dir>/<rel>; exits the program with a message when it is missing.
inline std::string data_file(std::string const& rel) {
  char const* env = std::getenv("CELLRAY_DATA_DIR");
  std::string const dir = env && *env ? std::string(env) : std::string(CELLRAY_DEFAULT_DATA_DIR);
  std::string const path = dir + "/" + rel;
  struct stat st;
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) {
    std::fprintf(stderr, "error: %s missing: this benchmark reads the shared data set; set CELLRAY_DATA_DIR to it\n",
                 path.c_str());
    std::exit(2);
  }
  return path;
}

}  // namespace cellray::bench
