#pragma once
// split_vtk_cells: a host's cells in VTK 9's layout (vtkCellArray's offsets
// and connectivity, vtkUnstructuredGrid's cell types) as the index arrays
// the kernels read, for TetMesh / HexMesh views over the host's own points
// and point arrays (nothing but the indices is copied).
//
// The kernels read homogeneous cells: 4 ids per tetrahedron, 8 per
// hexahedron with wedges, pyramids and voxels as hexahedra (mesh/
// vtk_cells.hpp), so a mixed mesh becomes a tet part and a hex part over the
// same points, split exactly as the file readers split one. A mesh of
// tetrahedra only (or hexahedra only) needs no split: its connectivity is
// already the index array, and a view of it copies nothing.

#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "../error.hpp"
#include "../mesh/span.hpp"
#include "detail.hpp"
#include "grid.hpp"

namespace cellray {

/// What split_vtk_cells returns: index arrays for TetMesh / HexMesh views,
/// and for each of their cells the host cell it came from (to carry cell
/// data along), in host order.
struct SplitCells {
  std::vector<uint32_t> tets;        ///< 4 point ids per tetrahedron (VTK order)
  std::vector<uint32_t> hexes;       ///< 8 per hexahedron (wedges, pyramids, voxels: mesh/vtk_cells.hpp)
  std::vector<uint64_t> tet_cells;   ///< host cell id of each tetrahedron
  std::vector<uint64_t> hex_cells;   ///< host cell id of each hexahedron
  ReadReport report;                 ///< cells per VTK type, skipped and reduced to linear ones
};

namespace io {
template <class T> constexpr NumType num_type_of() {
  if constexpr (std::is_same_v<T, uint8_t>) return NumType::u8;
  else if constexpr (std::is_same_v<T, int32_t>) return NumType::i32;
  else if constexpr (std::is_same_v<T, uint32_t>) return NumType::u32;
  else if constexpr (std::is_same_v<T, int64_t>) return NumType::i64;
  else {
    static_assert(std::is_same_v<T, uint64_t>, "cell arrays of uint8, int32, uint32, int64 or uint64");
    return NumType::u64;
  }
}
}  // namespace io

/// Splits `types.size` cells -- cell c has VTK type `types[c]` and point ids
/// `connectivity[offsets[c], offsets[c + 1])` -- into tetrahedra and
/// hexahedra, as the file readers do: quadratic and higher-order cells keep
/// their corners; a cell with repeated ids is the shape it really is.
/// Polyhedra (42), 2D and other cells are an error naming the first, or
/// with `opts.skip_unsupported_cells` a counted skip (polyhedra need their
/// faces: read them from a .vtu). Parallel (TBB) over the cells.
/// @throws InvalidMesh naming the cell and the problem: offsets that
///         decrease or run past the connectivity, a point id outside
///         [0, point_count), too few ids for the type, an unknown type, a
///         cell with fewer than 4 distinct points.
template <class Type, class Offset, class Id>
SplitCells split_vtk_cells(Span<Type> types, Span<Offset> offsets, Span<Id> connectivity, uint64_t point_count,
                           ReadOptions const& opts = {}) {
  uint64_t const ncells = types.size;
  if (offsets.size != ncells + 1)
    throw InvalidMesh("split_vtk_cells: " + std::to_string(ncells) + " cell types need " + std::to_string(ncells + 1) +
                      " offsets, got " + std::to_string(offsets.size));
  if (!io::point_count_fits(point_count))
    throw InvalidMesh("split_vtk_cells: " + std::to_string(point_count) + " points: ids are 32-bit (at most 2^32-1 points)");
  for (uint64_t c = 0; c < ncells; ++c) {
    int64_t const b = int64_t(offsets[c]), e = int64_t(offsets[c + 1]);
    if (b < 0 || e < b || uint64_t(e) > connectivity.size)
      throw InvalidMesh("split_vtk_cells: cell " + std::to_string(c) + ": offsets [" + std::to_string(b) + ", " +
                        std::to_string(e) + ") do not lie in the connectivity's " + std::to_string(connectivity.size) +
                        " ids");
  }
  auto view_of = [](auto const& s) {
    using T = std::remove_cv_t<std::remove_reference_t<decltype(s[0])>>;
    return io::NumArray::viewing(io::num_type_of<T>(), s.size, reinterpret_cast<unsigned char const*>(s.data), false);
  };
  io::NumArray const t = view_of(types), conn = view_of(connectivity);
  io::CellLocator where;
  where.type = [](uint64_t c) { return "split_vtk_cells: cell " + std::to_string(c) + ": "; };
  where.conn = [](uint64_t k) { return "split_vtk_cells: connectivity[" + std::to_string(k) + "]: "; };
  UnstructuredGrid grid;
  grid.report.file = "host cells";
  grid.report.format = "VTK 9 cell arrays";
  io::CellKinds kinds;
  try {
    kinds = io::build_cells(
        ncells, t, conn,
        [&offsets](uint64_t c) { return std::pair<uint64_t, uint64_t>(uint64_t(offsets[c]), uint64_t(offsets[c + 1])); },
        point_count, opts, grid, where);
  } catch (IoError const& e) {
    throw InvalidMesh(e.what());  // the host's arrays, not a file
  }
  SplitCells out;
  out.tets = std::move(grid.tets);
  out.hexes = std::move(grid.hexes);
  out.report = std::move(grid.report);
  out.tet_cells.reserve(out.tets.size() / 4);
  out.hex_cells.reserve(out.hexes.size() / 8);
  for (uint64_t c = 0; c < ncells; ++c) {
    if (kinds[c] == 0) out.tet_cells.push_back(c);
    else if (kinds[c] == 1) out.hex_cells.push_back(c);
  }
  return out;
}

}  // namespace cellray
