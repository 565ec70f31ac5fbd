#pragma once
// Shared by the fuzz harnesses: a check that aborts with a message (so
// libFuzzer records the input as a crash) and the invariants every grid a
// reader returns must hold.

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include <cellray/io/grid.hpp>

namespace cellray::fuzz {

/// Stops the run with `what` on stderr: a broken invariant is a finding.
[[noreturn]] inline void fail(char const* what) {
  std::fprintf(stderr, "fuzz invariant broken: %s\n", what);
  std::abort();
}

inline void require(bool ok, char const* what) {
  if (!ok) fail(what);
}

/// What a reader promises about a grid it returns (grid.hpp): every vertex
/// id is in range, every array has one value per vertex or kept cell, the
/// views construct, and a cell array converts to a point array.
inline void check_grid(UnstructuredGrid& g) {
  require(g.xyz.size() % 3 == 0, "positions not a multiple of 3");
  require(g.tets.size() % 4 == 0 && g.hexes.size() % 8 == 0, "cell index count not a multiple of the corners");
  uint64_t const nv = g.vertex_count();
  for (uint32_t v : g.tets) require(v < nv, "tet vertex id out of range");
  for (uint32_t v : g.hexes) require(v < nv, "hex vertex id out of range");
  for (auto const& a : g.point_arrays) require(a.values.size() == nv, "point array size differs from the vertex count");
  for (auto const& a : g.cell_arrays)
    require(a.tet_values.size() == g.tet_count() && a.hex_values.size() == g.hex_count(),
            "cell array size differs from the kept cell count");
  TetMesh const tm = g.tet_mesh();  // throws InvalidMesh on a size mismatch: that would be a reader bug
  HexMesh const hm = g.hex_mesh();
  require(tm.cell_count() == g.tet_count() && hm.cell_count() == g.hex_count(), "view cell count");
  if (!g.cell_arrays.empty()) {
    // A name the file does not use: cell_to_point refuses to replace a point
    // array (InvalidArgument, as documented), and the fuzzer finds the name
    // (regressions/vtk/point_array_named_like_the_converted_one).
    std::string name = "fuzz_point_" + g.cell_arrays[0].name;
    while (g.point_array(name)) name += '_';
    g.cell_to_point(g.cell_arrays[0].name, name);
    require(g.point_array(name) && g.point_array(name)->values.size() == nv, "cell_to_point size");
  }
}

/// One input through a reader `read(bytes, name, opts)`: it must return a
/// grid that passes check_grid or throw IoError; anything else is a finding.
/// Both skip policies are exercised, chosen by the input's size.
template <class Read> int fuzz_reader(uint8_t const* data, size_t size, char const* name, Read read) {
  std::string_view const bytes(reinterpret_cast<char const*>(data), size);
  ReadOptions opts;
  opts.skip_unsupported_cells = size % 2 == 1;
  UnstructuredGrid grid;
  try {
    grid = read(bytes, name, opts);
  } catch (IoError const&) {
    return 0;
  }
  check_grid(grid);
  return 0;
}

}  // namespace cellray::fuzz
