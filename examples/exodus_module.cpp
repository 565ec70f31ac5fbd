// libcellray-exodus.so: cellray-render's Exodus II reader as a module that
// cellray-render loads only for an Exodus file (why: examples/exodus.hpp).

#include <exception>
#include <string>
#include <type_traits>

#include "exodus.hpp"

extern "C" __attribute__((visibility("default"))) bool cellray_read_exodus(char const* path,
                                                                           cellray::ReadOptions const* opts,
                                                                           cellray::UnstructuredGrid* out,
                                                                           std::string* error) {
  // Nothing is thrown across the module boundary: the caller turns the
  // message back into an IoError.
  try {
    *out = cellray::cli::read_exodus(path, *opts);
    return true;
  } catch (std::exception const& e) {
    *error = e.what();
  } catch (...) {
    *error = std::string(path) + ": unknown error in the Exodus II reader";
  }
  return false;
}

// The entry's type is the one cellray-render calls through.
static_assert(std::is_same_v<decltype(&cellray_read_exodus), cellray::cli::ReadExodusEntry>);
