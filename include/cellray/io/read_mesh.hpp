#pragma once
// read_mesh(path): picks the reader from the file extension.

#include <string>
#include <string_view>

#include "detail.hpp"
#include "gmsh.hpp"
#include "grid.hpp"
#include "pvtu.hpp"
#include "vtk_legacy.hpp"
#include "vtu.hpp"

namespace cellray {

/// Reads a mesh file: ".vtk" (legacy VTK), ".vtu" (VTK XML), ".pvtu"
/// (ParaView's parallel VTK XML: every piece, merged; see read_pvtu()) or
/// ".msh" (gmsh, MSH 2.2, 4.0 and 4.1, ASCII or binary; see read_gmsh()),
/// extension case-insensitive. See UnstructuredGrid for what is kept and
/// ReadOptions for unsupported cells. Thread-safe (no shared state).
/// @throws IoError naming the file and the line or byte offset of the
///         problem, or naming the extension when it is neither.
inline UnstructuredGrid read_mesh(std::string const& path, ReadOptions const& opts = {}) {
  size_t const dot = path.find_last_of("./");
  std::string_view const ext =
      (dot == std::string::npos || path[dot] != '.') ? std::string_view() : std::string_view(path).substr(dot);
  if (io::iequals(ext, ".vtk")) return read_vtk_legacy(path, opts);
  if (io::iequals(ext, ".vtu")) return read_vtu(path, opts);
  if (io::iequals(ext, ".pvtu")) return read_pvtu(path, opts);
  if (io::iequals(ext, ".msh")) return read_gmsh(path, opts);
  throw IoError(path + ": unsupported file extension " + (ext.empty() ? std::string("(none)") : io::in_quotes(ext)) +
                " (cellray reads .vtk, .vtu, .pvtu and .msh)");
}

/// Like read_mesh() for bytes in memory; `name_for_errors` (a file name)
/// chooses the reader by its extension and starts every error message.
/// A ".pvtu" is refused: its pieces are other files.
inline UnstructuredGrid read_mesh_from_memory(std::string_view bytes, std::string const& name_for_errors,
                                              ReadOptions const& opts = {}) {
  size_t const dot = name_for_errors.find_last_of("./");
  std::string_view const ext = (dot == std::string::npos || name_for_errors[dot] != '.')
                                   ? std::string_view()
                                   : std::string_view(name_for_errors).substr(dot);
  if (io::iequals(ext, ".vtk")) return read_vtk_legacy_from_memory(bytes, name_for_errors, opts);
  if (io::iequals(ext, ".vtu")) return read_vtu_from_memory(bytes, name_for_errors, opts);
  if (io::iequals(ext, ".msh")) return read_gmsh_from_memory(bytes, name_for_errors, opts);
  if (io::iequals(ext, ".pvtu"))
    throw IoError(name_for_errors + ": a .pvtu names other files (its pieces) and must be read from disk (read_mesh)");
  throw IoError(name_for_errors + ": unsupported file extension " +
                (ext.empty() ? std::string("(none)") : io::in_quotes(ext)) + " (cellray reads .vtk, .vtu, .pvtu and .msh)");
}

}  // namespace cellray
