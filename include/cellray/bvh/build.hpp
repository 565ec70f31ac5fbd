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
#include "../mesh/cell_types.hpp"
#include "build_common.hpp"
#include "build_median.hpp"
#include "build_morton.hpp"
#include "build_sah.hpp"

namespace cellray {

/// One piece of a multi-piece data set (a partition, or one cell type's
/// part of a mixed file): a reference to a mesh view of any listed type.
/// The mesh must outlive the call it is passed to (not the BVH).
using MeshPiece = AnyCellMesh;

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

/// What one pass over the item boxes finds: the first bad box and the
/// bounds of the doubled centroids of all good ones.
struct BoxScan {
  uint64_t first_bad = std::numeric_limits<uint64_t>::max();  ///< index of a NaN/inf/inverted box
  Box3 centroids;

  void merge(BoxScan const& o) {
    first_bad = std::min(first_bad, o.first_bad);
    centroids.grow(o.centroids);
  }
};

/// Scans boxes [b, e) (sequential; callers split).
inline BoxScan scan_boxes(ItemBox const* boxes, uint64_t b, uint64_t e) {
  BoxScan s;
  PointBounds4 c;
  int ok = 7;  // lanes 0-2 (xyz) of every box so far finite and ordered
  for (uint64_t i = b; i < e; ++i) {
    float const* v = reinterpret_cast<float const*>(boxes + i);
    F4 const lo = F4::load(v), hi = F4::load(v + 4);
    ok &= finite_ordered(lo, hi);
    c.grow(lo + hi);
  }
  if ((ok & 7) == 7) {
    s.centroids = c.box();
    return s;
  }
  // Rare: find the first bad box and bound the good ones only.
  c = PointBounds4{};
  for (uint64_t i = b; i < e; ++i) {
    float const* v = reinterpret_cast<float const*>(boxes + i);
    F4 const lo = F4::load(v), hi = F4::load(v + 4);
    if ((finite_ordered(lo, hi) & 7) != 7) s.first_bad = std::min(s.first_bad, i);
    else c.grow(lo + hi);
  }
  s.centroids = c.box();
  return s;
}

inline BoxScan scan_boxes_parallel(ItemBox const* boxes, uint64_t n) {
  return tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, n, scan_block), BoxScan{},
      [&](tbb::blocked_range<uint64_t> const& r, BoxScan acc) {
        acc.merge(scan_boxes(boxes, r.begin(), r.end()));
        return acc;
      },
      [](BoxScan a, BoxScan const& b) {
        a.merge(b);
        return a;
      });
}

/// `cb`: bounds of the doubled centroids of all n boxes (from the scan).
/// The SAH and median builders reorder `boxes` (a scratch copy).
template <class Index>
MinMaxBvh build_tree(ItemBox* boxes, uint64_t n, Box3 const& cb, BuildOptions const& opt) {
  MinMaxBvh bvh;
  BvhAccess::set_info(bvh, sizeof(Index) == 8, opt.builder, opt.max_leaf_size, 0);
  BvhAccess::piece_offsets(bvh) = {0, n};
  if (n == 0) return bvh;
  LargeVector<Index> items(n);  // unset: every entry is written below
  populate_parallel(items.data(), n * sizeof(Index));
  SubtreePool pool;  // before root: holds its private node buffers until assembled
  std::unique_ptr<Subtree> root;
  if (opt.builder == BvhBuilder::morton) {
    LargeVector<uint32_t> codes(n);  // unset: every entry is written
    populate_parallel(codes.data(), n * sizeof(uint32_t));
    morton_order(boxes, n, cb, items.data(), codes.data());
    MortonSplitter<Index> s{codes.data(), boxes, items.data(), opt.max_leaf_size};
    root = build_upper(s, 0, n, 0, Box3{}, pool);
  } else {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) items[i] = Index(i);
    });
    Slots<Index> const slots{boxes, items.data()};
    if (opt.builder == BvhBuilder::spatial_median) {
      MedianSplitter<Index> s{slots, opt.max_leaf_size, opt.sah};
      root = build_upper(s, 0, n, 0, cb, pool);
    } else {
      SahSplitter<Index> s{slots, opt.max_leaf_size, opt.sah, opt.sah_bins};
      root = build_upper(s, 0, n, 0, cb, pool);
    }
  }
  assemble(*root, BvhAccess::nodes(bvh), BvhAccess::ranges(bvh));
  uint32_t const depth = root->depth;
  root.reset();
  BvhAccess::set_info(bvh, sizeof(Index) == 8, opt.builder, opt.max_leaf_size, depth);
  if constexpr (sizeof(Index) == 8) BvhAccess::items64(bvh) = std::move(items);
  else BvhAccess::items32(bvh) = std::move(items);
  return bvh;
}

inline MinMaxBvh build_any(ItemBox* boxes, uint64_t n, Box3 const& cb, BuildOptions const& opt) {
  if (opt.wide_items || n > uint64_t(std::numeric_limits<uint32_t>::max()))
    return build_tree<uint64_t>(boxes, n, cb, opt);
  return build_tree<uint32_t>(boxes, n, cb, opt);
}

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// First cell of [b, e) naming a vertex id >= the vertex count, or e.
template <int N> uint64_t first_bad_cell(CellMesh<N> const& mesh, uint64_t b, uint64_t e) {
  uint64_t const nv = mesh.vertex_count();
  if (mesh.has_32bit_indices() && nv > 0 && nv - 1 <= std::numeric_limits<uint32_t>::max()) {
    // The common case: one branch-free pass over the ids (2 instructions
    // per id, against 9 per cell through mesh.vertex(); GCC 12 does not
    // vectorise it). Unsigned id > last as a signed compare after flipping
    // the sign bits.
    uint32_t const* ids = mesh.indices32();
    auto const last = int32_t(uint32_t(nv - 1) ^ 0x80000000u);
    int32_t bad = 0;
    for (uint64_t k = b * N; k < e * N; ++k) bad |= int32_t(int32_t(ids[k] ^ 0x80000000u) > last);
    if (bad == 0) return e;
  }
  for (uint64_t c = b; c < e; ++c)
    for (int k = 0; k < N; ++k)
      if (mesh.vertex(c, k) >= nv) return c;
  return e;
}

/// One parallel pass over the cells of `mesh`: checks their vertex ids,
/// writes their boxes to out[0, cell_count) with the SIMD `CellBoxes` and
/// scans them. Throws InvalidMesh naming piece, cell (and corner) for a
/// vertex id out of range; a bad box is returned in the scan.
template <int N> BoxScan cell_boxes(CellMesh<N> const& mesh, ItemBox* out, Isa isa, uint32_t piece) {
  uint64_t const nc = mesh.cell_count();
  struct Part {
    uint64_t bad_cell;
    BoxScan scan;
  };
  Part const part = tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, nc, scan_block), Part{nc, {}},
      [&](tbb::blocked_range<uint64_t> const& r, Part acc) {
        uint64_t const bad = first_bad_cell(mesh, r.begin(), r.end());
        if (bad != r.end()) {  // never let the kernel read past the vertex arrays
          acc.bad_cell = std::min(acc.bad_cell, bad);
          return acc;
        }
        dispatch<CellBoxes>(isa, mesh, r.begin(), r.end(), out + r.begin());
        BoxScan s = scan_boxes(out, r.begin(), r.end());
        acc.scan.merge(s);
        return acc;
      },
      [](Part a, Part const& b) {
        a.bad_cell = std::min(a.bad_cell, b.bad_cell);
        a.scan.merge(b.scan);
        return a;
      });
  if (part.bad_cell != nc) {
    uint64_t const c = part.bad_cell;
    for (int k = 0; k < N; ++k)
      if (mesh.vertex(c, k) >= mesh.vertex_count())
        throw InvalidMesh("piece " + std::to_string(piece) + " cell " + std::to_string(c) + " corner " +
                          std::to_string(k) + " names vertex " + std::to_string(mesh.vertex(c, k)) +
                          " but the mesh has " + std::to_string(mesh.vertex_count()) + " vertices");
  }
  return part.scan;
}

inline MinMaxBvh build_pieces(std::vector<MeshPiece> const& pieces, BuildOptions const& opt) {
  auto const t0 = std::chrono::steady_clock::now();
  check_options(opt);
  Isa const isa = opt.isa ? *opt.isa : default_isa();
  std::vector<uint64_t> offsets{0};
  for (auto const& p : pieces) offsets.push_back(offsets.back() + p.cell_count());
  uint64_t const n = offsets.back();
  LargeVector<ItemBox> boxes(n);  // unset: every entry is written
  BoxScan scan;
  for (size_t p = 0; p < pieces.size(); ++p)
    pieces[p].visit([&](auto const& mesh) {
      BoxScan s = cell_boxes(mesh, boxes.data() + offsets[p], isa, uint32_t(p));
      if (s.first_bad != std::numeric_limits<uint64_t>::max()) s.first_bad += offsets[p];
      scan.merge(s);
    });
  if (scan.first_bad != std::numeric_limits<uint64_t>::max()) {
    uint64_t const bad = scan.first_bad;
    auto const p = uint64_t(std::upper_bound(offsets.begin(), offsets.end(), bad) - offsets.begin() - 1);
    throw InvalidMesh("piece " + std::to_string(p) + " cell " + std::to_string(bad - offsets[p]) +
                      " has a non-finite vertex position (validate() names the vertex)");
  }
  MinMaxBvh bvh = build_any(boxes.data(), n, scan.centroids, opt);
  boxes = {};  // freed before the caller allocates more
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
  detail::BoxScan const scan = detail::scan_boxes_parallel(boxes.data, boxes.size);
  if (scan.first_bad != std::numeric_limits<uint64_t>::max())
    throw InvalidArgument("item " + std::to_string(scan.first_bad) + " has a non-finite bound or lo > hi");
  // The builders reorder their boxes: work on a copy.
  detail::LargeVector<ItemBox> copy(boxes.size);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, boxes.size, detail::scan_block),
                    [&](tbb::blocked_range<uint64_t> const& r) {
                      std::copy(boxes.data + r.begin(), boxes.data + r.end(), copy.data() + r.begin());
                    });
  MinMaxBvh bvh = detail::build_any(copy.data(), boxes.size, scan.centroids, opt);
  copy = {};
  detail::BvhAccess::set_seconds(bvh, detail::seconds_since(t0));
  return bvh;
}

/// Builds over the cells of `mesh` (item id = cell id) with the value ranges
/// of its active array (NaN cells get the empty range). The per-cell boxes
/// are computed in parallel with the SIMD `CellBoxes` and freed afterwards;
/// the mesh arrays are only read. Call `validate()` first for a full report.
/// @throws InvalidMesh for a vertex id out of range or a non-finite position
///         (naming the cell); InvalidArgument for bad options.
template <int N> MinMaxBvh build_minmax_bvh(CellMesh<N> const& mesh, BuildOptions const& opt = {}) {
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
