#pragma once
// build_minmax_bvh: item boxes, a mesh, or several mesh pieces in; a
// MinMaxBvh out. Parallel (TBB), deterministic: the same input gives the
// same tree, byte for byte, whatever the thread count.

#include <chrono>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>

#include "../dispatch/dispatch.hpp"
#include "../mesh/cell_boxes.hpp"
#include "../mesh/cell_mesh.hpp"
#include "build_common.hpp"
#include "build_median.hpp"
#include "build_morton.hpp"
#include "build_sah.hpp"

namespace cellray {

/// One piece of a multi-piece data set (a partition, or the tet or hex part
/// of a mixed file): a reference to a tet or a hex mesh view. Holds a
/// pointer; the mesh must outlive the call it is passed to (not the BVH).
class MeshPiece {
 public:
  MeshPiece(TetMesh const& m) : tets_(&m) {}   // NOLINT: implicit on purpose
  MeshPiece(HexMesh const& m) : hexes_(&m) {}  // NOLINT: implicit on purpose

  uint64_t cell_count() const noexcept { return tets_ ? tets_->cell_count() : hexes_->cell_count(); }
  /// Calls f(TetMesh const&) or f(HexMesh const&).
  template <class F> decltype(auto) visit(F&& f) const { return tets_ ? f(*tets_) : f(*hexes_); }

 private:
  TetMesh const* tets_ = nullptr;
  HexMesh const* hexes_ = nullptr;
};

namespace detail {

inline void check_options(BuildOptions const& opt) {
  if (opt.max_leaf_size < 1 || opt.max_leaf_size > Node::max_leaf_items)
    throw InvalidArgument("max_leaf_size " + std::to_string(opt.max_leaf_size) + " is outside [1, " +
                          std::to_string(Node::max_leaf_items) + "]");
  if (opt.sah_bins < 2 || opt.sah_bins > max_sah_bins)
    throw InvalidArgument("sah_bins " + std::to_string(opt.sah_bins) + " is outside [2, " +
                          std::to_string(max_sah_bins) + "]");
  if (!(opt.sah.traversal >= 0.f) || !(opt.sah.item > 0.f))
    throw InvalidArgument("SAH costs must be traversal >= 0 and item > 0");
}

/// The smallest index whose box is not finite or has lo > hi, or n.
inline uint64_t first_bad_box(ItemBox const* boxes, uint64_t n) {
  return tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, n, scan_block), n,
      [&](tbb::blocked_range<uint64_t> const& r, uint64_t found) {
        for (uint64_t i = r.begin(); i < r.end() && i < found; ++i) {
          ItemBox const& b = boxes[i];
          bool ok = true;
          for (int k = 0; k < 3; ++k) ok = ok && std::isfinite(b.lo[k]) && std::isfinite(b.hi[k]) && b.lo[k] <= b.hi[k];
          if (!ok) return i;
        }
        return found;
      },
      [](uint64_t a, uint64_t b) { return std::min(a, b); });
}

template <class Index> MinMaxBvh build_tree(ItemBox const* boxes, uint64_t n, BuildOptions const& opt) {
  MinMaxBvh bvh;
  BvhAccess::set_info(bvh, sizeof(Index) == 8, opt.builder, opt.max_leaf_size, 0);
  BvhAccess::piece_offsets(bvh) = {0, n};
  if (n == 0) return bvh;
  std::vector<Index> items(n);
  std::unique_ptr<Subtree> root;
  if (opt.builder == BvhBuilder::morton) {
    std::vector<uint32_t> codes(n);
    morton_order(boxes, n, items.data(), codes.data());
    MortonSplitter<Index> s{codes.data(), opt.max_leaf_size};
    root = build_upper(s, 0, n, 0, Box3{});
  } else {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) items[i] = Index(i);
    });
    std::vector<Index> scratch(n);
    Box3 const cb = centroid_bounds(boxes, items.data(), 0, n);
    if (opt.builder == BvhBuilder::spatial_median) {
      MedianSplitter<Index> s{boxes, items.data(), scratch.data(), opt.max_leaf_size, opt.sah};
      root = build_upper(s, 0, n, 0, cb);
    } else {
      SahSplitter<Index> s{boxes, items.data(), scratch.data(), opt.max_leaf_size, opt.sah, opt.sah_bins};
      root = build_upper(s, 0, n, 0, cb);
    }
  }
  std::vector<Node>& nodes = BvhAccess::nodes(bvh);
  nodes = assemble(*root);
  root.reset();
  ValueRanges& ranges = BvhAccess::ranges(bvh);
  ranges.resize(nodes.size());
  uint32_t const depth = fit_bounds_and_ranges(nodes.data(), ranges.data(), boxes, items.data(), 0, 0);
  BvhAccess::set_info(bvh, sizeof(Index) == 8, opt.builder, opt.max_leaf_size, depth);
  if constexpr (sizeof(Index) == 8) BvhAccess::items64(bvh) = std::move(items);
  else BvhAccess::items32(bvh) = std::move(items);
  return bvh;
}

inline MinMaxBvh build_any(ItemBox const* boxes, uint64_t n, BuildOptions const& opt) {
  if (opt.wide_items || n > uint64_t(std::numeric_limits<uint32_t>::max())) return build_tree<uint64_t>(boxes, n, opt);
  return build_tree<uint32_t>(boxes, n, opt);
}

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Throws InvalidMesh naming the first cell (of piece `piece`) with a vertex id out of range.
template <int N> void check_indices(CellMesh<N> const& mesh, uint32_t piece) {
  uint64_t const nv = mesh.vertex_count(), nc = mesh.cell_count();
  uint64_t const bad = tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, nc, scan_block), nc,
      [&](tbb::blocked_range<uint64_t> const& r, uint64_t found) {
        for (uint64_t c = r.begin(); c < r.end() && c < found; ++c)
          for (int k = 0; k < N; ++k)
            if (mesh.vertex(c, k) >= nv) return c;
        return found;
      },
      [](uint64_t a, uint64_t b) { return std::min(a, b); });
  if (bad == nc) return;
  for (int k = 0; k < N; ++k)
    if (mesh.vertex(bad, k) >= nv)
      throw InvalidMesh("piece " + std::to_string(piece) + " cell " + std::to_string(bad) + " corner " +
                        std::to_string(k) + " names vertex " + std::to_string(mesh.vertex(bad, k)) +
                        " but the mesh has " + std::to_string(nv) + " vertices");
}

/// Boxes of every cell of `mesh` into out[0, cell_count), parallel.
template <int N> void cell_boxes(CellMesh<N> const& mesh, ItemBox* out, Isa isa) {
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, mesh.cell_count(), scan_block),
                    [&](tbb::blocked_range<uint64_t> const& r) {
                      dispatch<CellBoxes>(isa, mesh, r.begin(), r.end(), out + r.begin());
                    });
}

inline MinMaxBvh build_pieces(std::vector<MeshPiece> const& pieces, BuildOptions const& opt) {
  auto const t0 = std::chrono::steady_clock::now();
  check_options(opt);
  Isa const isa = opt.isa ? *opt.isa : default_isa();
  std::vector<uint64_t> offsets{0};
  for (auto const& p : pieces) offsets.push_back(offsets.back() + p.cell_count());
  std::vector<ItemBox> boxes(offsets.back());
  for (size_t p = 0; p < pieces.size(); ++p)
    pieces[p].visit([&](auto const& mesh) {
      check_indices(mesh, uint32_t(p));
      cell_boxes(mesh, boxes.data() + offsets[p], isa);
    });
  uint64_t const bad = first_bad_box(boxes.data(), boxes.size());
  if (bad != boxes.size()) {
    auto const p = uint64_t(std::upper_bound(offsets.begin(), offsets.end(), bad) - offsets.begin() - 1);
    throw InvalidMesh("piece " + std::to_string(p) + " cell " + std::to_string(bad - offsets[p]) +
                      " has a non-finite vertex position (validate() names the vertex)");
  }
  MinMaxBvh bvh = build_any(boxes.data(), boxes.size(), opt);
  BvhAccess::piece_offsets(bvh) = std::move(offsets);
  BvhAccess::set_seconds(bvh, seconds_since(t0));
  return bvh;
}

}  // namespace detail

/// Builds over `boxes` (item i = boxes[i]; ranges from vmin/vmax). The boxes
/// are read during the call only. Zero boxes give the empty BVH.
/// @throws InvalidArgument for a box with a NaN/inf bound or lo > hi (naming
///         the item), or options outside their documented ranges.
inline MinMaxBvh build_minmax_bvh(Span<ItemBox> boxes, BuildOptions const& opt = {}) {
  auto const t0 = std::chrono::steady_clock::now();
  detail::check_options(opt);
  uint64_t const bad = detail::first_bad_box(boxes.data, boxes.size);
  if (bad != boxes.size)
    throw InvalidArgument("item " + std::to_string(bad) + " has a non-finite bound or lo > hi");
  MinMaxBvh bvh = detail::build_any(boxes.data, boxes.size, opt);
  detail::BvhAccess::set_seconds(bvh, detail::seconds_since(t0));
  return bvh;
}

/// Builds over the cells of `mesh` (item id = cell id) with the value ranges
/// of its active array (NaN cells get the empty range). The per-cell boxes
/// are computed in parallel with the SIMD `CellBoxes` and freed afterwards;
/// the mesh arrays are only read. Call `validate()` first for a full report.
/// @throws InvalidMesh for a vertex id out of range or a non-finite position
///         (naming the cell); InvalidArgument for bad options.
inline MinMaxBvh build_minmax_bvh(TetMesh const& mesh, BuildOptions const& opt = {}) {
  return detail::build_pieces({MeshPiece(mesh)}, opt);
}
inline MinMaxBvh build_minmax_bvh(HexMesh const& mesh, BuildOptions const& opt = {}) {
  return detail::build_pieces({MeshPiece(mesh)}, opt);
}

/// One BVH over all cells of all pieces. Item id = piece offset + cell id
/// (`bvh.piece_offsets()`, decoded by `bvh.locate(id)`), so a 32-bit item
/// list serves up to 2^32 - 1 cells in total. Errors as for one mesh, naming
/// the piece.
inline MinMaxBvh build_minmax_bvh(std::vector<MeshPiece> const& pieces, BuildOptions const& opt = {}) {
  return detail::build_pieces(pieces, opt);
}

}  // namespace cellray
