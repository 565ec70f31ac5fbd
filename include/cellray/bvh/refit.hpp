#pragma once
// Time steps (Rathke 2015 §5.4, done differently): one tree for the
// geometry, one `ValueRanges` per scalar array. A refit recomputes every
// node's value range in O(n), in parallel, without touching bounds or
// topology; switching time steps is then a pointer swap.

#include <memory>
#include <string>
#include <vector>

#include "build.hpp"

namespace cellray {

namespace detail {

/// Fits `out` from `slot_range(s)` (NodeRange of item-list slot s).
template <class SlotRange> void fit_slot_ranges(MinMaxBvh const& bvh, SlotRange const& slot_range, ValueRanges& out) {
  out.resize(bvh.node_count());
  if (bvh.empty()) {
    out[0] = {inf_f, -inf_f};
    return;
  }
  fit_ranges(bvh.nodes(), out.data(), SlotLeafRange<SlotRange>{slot_range}, 0, 0);
}

/// Fits `out` from `item_range(id)` (NodeRange of item id).
template <class ItemRange> void fit_ranges_any(MinMaxBvh const& bvh, ItemRange const& item_range, ValueRanges& out) {
  if (bvh.wide_items()) {
    uint64_t const* items = bvh.items64();
    fit_slot_ranges(bvh, [items, &item_range](uint64_t s) { return item_range(items[s]); }, out);
  } else {
    uint32_t const* items = bvh.items32();
    fit_slot_ranges(bvh, [items, &item_range](uint64_t s) { return item_range(items[s]); }, out);
  }
}

/// Throws InvalidArgument unless `pieces` match the tree's piece table (count and cell counts).
inline void check_refit_pieces(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces) {
  auto const& offsets = bvh.piece_offsets();
  if (pieces.size() != bvh.piece_count())
    throw InvalidArgument("refit with " + std::to_string(pieces.size()) + " pieces of a BVH built over " +
                          std::to_string(bvh.piece_count()));
  for (size_t p = 0; p < pieces.size(); ++p)
    if (pieces[p].cell_count() != offsets[p + 1] - offsets[p])
      throw InvalidArgument("refit: piece " + std::to_string(p) + " has " + std::to_string(pieces[p].cell_count()) +
                            " cells, the BVH was built over " + std::to_string(offsets[p + 1] - offsets[p]));
}

inline void refit_pieces(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces, ValueRanges& out, Isa isa) {
  check_refit_pieces(bvh, pieces);
  auto const& offsets = bvh.piece_offsets();
  uint64_t const n = bvh.item_count();
  std::unique_ptr<float[]> vmin(new float[n]), vmax(new float[n]);
  // Per-cell ranges with the SIMD CellRanges (streaming over the cells),
  // then the tree pass reads them by item id. Measured against computing
  // the ranges in item-list order (an ISA entry gathering each slot's cell
  // indices, so the tree pass reads them in order): that was slower, 7.1 +
  // 4.3 ms against 4.4 + 5.3 ms (1M tets, AVX-512, 1 thread), the random
  // index reads costing more than the in-order range reads save.
  for (size_t p = 0; p < pieces.size(); ++p)
    pieces[p].visit([&](auto const& mesh) {
      uint64_t const o = offsets[p];
      tbb::parallel_for(tbb::blocked_range<uint64_t>(0, mesh.cell_count(), scan_block),
                        [&](tbb::blocked_range<uint64_t> const& r) {
                          dispatch<CellRanges>(isa, mesh, r.begin(), r.end(), vmin.get() + o + r.begin(),
                                               vmax.get() + o + r.begin());
                        });
    });
  float const* lo = vmin.get();
  float const* hi = vmax.get();
  fit_ranges_any(bvh, [lo, hi](uint64_t id) { return NodeRange{lo[id], hi[id]}; }, out);
}

}  // namespace detail

/// Fills `out` with the value ranges of `bvh` for the active array of
/// `pieces` (the same geometry and cell counts the tree was built over; the
/// values may differ). Equal, bit for bit, to the ranges a rebuild with that
/// array gives. Parallel; `out` is resized and its memory reused.
/// @throws InvalidArgument when the pieces or cell counts differ from the build.
inline void refit_ranges(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces, ValueRanges& out,
                         std::optional<Isa> isa = {}) {
  detail::refit_pieces(bvh, pieces, out, isa ? *isa : default_isa());
}
inline ValueRanges refit_ranges(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces, std::optional<Isa> isa = {}) {
  ValueRanges r;
  refit_ranges(bvh, pieces, r, isa);
  return r;
}
/// Single-mesh forms of the above (`mesh.with_array("t1")` or `with_values`).
template <int N>
void refit_ranges(MinMaxBvh const& bvh, CellMesh<N> const& mesh, ValueRanges& out, std::optional<Isa> isa = {}) {
  refit_ranges(bvh, std::vector<MeshPiece>{MeshPiece(mesh)}, out, isa);
}
template <int N>
ValueRanges refit_ranges(MinMaxBvh const& bvh, CellMesh<N> const& mesh, std::optional<Isa> isa = {}) {
  return refit_ranges(bvh, std::vector<MeshPiece>{MeshPiece(mesh)}, isa);
}

/// Ranges from per-item ranges (item id i has [vmin[i], vmax[i]]; an empty
/// range is vmin = +inf, vmax = -inf), for a tree built from item boxes.
/// @throws InvalidArgument when a span's length is not the item count.
inline void refit_ranges(MinMaxBvh const& bvh, Span<float> vmin, Span<float> vmax, ValueRanges& out) {
  if (vmin.size != bvh.item_count() || vmax.size != bvh.item_count())
    throw InvalidArgument("refit: " + std::to_string(vmin.size) + "/" + std::to_string(vmax.size) +
                          " item ranges for a BVH of " + std::to_string(bvh.item_count()) + " items");
  float const* lo = vmin.data;
  float const* hi = vmax.data;
  detail::fit_ranges_any(bvh, [lo, hi](uint64_t id) { return NodeRange{lo[id], hi[id]}; }, out);
}

/// Refits the BVH's own ranges in place (for a host with one time step at a
/// time; concurrent renders must not read the BVH meanwhile).
template <class MeshOrPieces> void refit_values(MinMaxBvh& bvh, MeshOrPieces const& mesh) {
  bvh.set_ranges(refit_ranges(bvh, mesh));
}

}  // namespace cellray
