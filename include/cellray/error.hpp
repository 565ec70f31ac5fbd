#pragma once
// The exception types every public entry point may throw. Each message names
// what is wrong and where (file and line or byte offset, cell or vertex id).

#include <stdexcept>
#include <string>

namespace cellray {

/// Base of everything cellray throws on purpose.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A mesh view that is inconsistent (array sizes) or fails `validate()`.
struct InvalidMesh : Error {
  using Error::Error;
};

/// A file that cannot be read or parsed; the message names the file and the
/// line (text) or byte offset (binary) where reading stopped.
struct IoError : Error {
  using Error::Error;
};

/// A parameter outside its documented range (image size, step, isovalues...).
struct InvalidArgument : Error {
  using Error::Error;
};

}  // namespace cellray
