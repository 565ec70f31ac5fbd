#pragma once
// Per-cell bounding boxes and value ranges: what the BVH builders and the
// range refit consume. Computed with SIMD gathers in the ISA units.

#include <cstdint>

#include <glm/vec3.hpp>

#include "../dispatch/dispatch.hpp"
#include "cell_mesh.hpp"
#include "cell_types.hpp"

namespace cellray {

/// Bounds and scalar range of one item (a cell). 32 bytes:
///   [ 0,12) lo    box min xyz      [12,16) vmin  smallest vertex value
///   [16,28) hi    box max xyz      [28,32) vmax  largest vertex value
/// A cell with a NaN or +-inf vertex value gets the empty range vmin = +inf,
/// vmax = -inf, so no isovalue or transfer-function range ever selects it.
struct ItemBox {
  glm::vec3 lo;
  float vmin;
  glm::vec3 hi;
  float vmax;
};
static_assert(sizeof(ItemBox) == 32, "ItemBox is documented as 32 bytes");

/// Fills `out[i - begin]` for cells [begin, end) of `mesh` (active array; a
/// mesh without values gets the empty range). Single-threaded; callers split
/// the cell range across threads.
template <class Arch> struct CellBoxes {
  static void run(AnyCellMesh mesh, uint64_t begin, uint64_t end, ItemBox* out);
};
CELLRAY_EXTERN_ENTRY(CellBoxes)

/// Only value ranges (for a time-step refit): vmin/vmax per cell, NaN rule as above.
template <class Arch> struct CellRanges {
  static void run(AnyCellMesh mesh, uint64_t begin, uint64_t end, float* vmin, float* vmax);
};
CELLRAY_EXTERN_ENTRY(CellRanges)

}  // namespace cellray
