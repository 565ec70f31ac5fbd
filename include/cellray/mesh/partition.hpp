#pragma once
// A k-d partition of a mesh for distributed rendering (issue #22): k regions,
// boxes that tile the mesh bounds, split by cell centroids so each region
// holds about n / k cells; a cell whose bounding box straddles a split plane
// belongs to every region its box overlaps (ParaView's
// vtkRedistributeDataSetFilter, ASSIGN_TO_ALL_INTERSECTING_REGIONS). With
// each region's rays clipped to its box (render/clip.hpp, clip_box), the
// regions' images composited front to back in `front_to_back(eye)` order
// ("over", premultiplied) are the image of the whole mesh: every ray meets
// the boxes in that order, and inside a box it sees every cell it would see
// in the whole mesh there.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../error.hpp"
#include "cell_mesh.hpp"

namespace cellray {

/// One region of a KdPartition: its box (a cell of the k-d tree, closed) and
/// the mesh cells whose bounding boxes overlap it (closed intervals on each
/// axis: a cell touching the box's face counts), ascending.
struct KdRegion {
  glm::vec3 lo{0.f}, hi{0.f};
  std::vector<uint64_t> cells;
};

/// The k-d tree behind a partition: inner node i splits its box at
/// `position` on `axis`; `below` / `above` are child ids, a negative id -r-1
/// names region r (a leaf). Node 0 is the root (none when k = 1).
struct KdSplit {
  int axis = 0;
  float position = 0.f;
  int below = -1, above = -1;
};

/// k regions tiling the mesh bounds [lo, hi] (the union of the cells' boxes).
struct KdPartition {
  glm::vec3 lo{0.f}, hi{0.f};
  std::vector<KdRegion> regions;
  std::vector<KdSplit> splits;  ///< k - 1 inner nodes; empty for k = 1

  /// Region ids front to back as seen from `eye`: k-d tree order, at each
  /// split the side holding the eye first (an eye on the plane: below
  /// first; either order is right there). For any ray from `eye`, a region
  /// earlier in the order is never behind a later one along the ray, which
  /// is what ordered compositing needs (IceT's icetCompositeOrder). Also
  /// right for an eye outside the bounds.
  std::vector<int> front_to_back(glm::vec3 const& eye) const {
    std::vector<int> order;
    order.reserve(regions.size());
    if (splits.empty()) {
      for (size_t r = 0; r < regions.size(); ++r) order.push_back(int(r));
      return order;
    }
    std::vector<int> stack{0};
    while (!stack.empty()) {
      int const id = stack.back();
      stack.pop_back();
      if (id < 0) {
        order.push_back(-id - 1);
        continue;
      }
      KdSplit const& s = splits[size_t(id)];
      bool const eye_below = eye[s.axis] <= s.position;
      stack.push_back(eye_below ? s.above : s.below);  // popped last: the far side
      stack.push_back(eye_below ? s.below : s.above);
    }
    return order;
  }

  /// Cells held in all regions together (cells on a boundary count once per region).
  uint64_t assigned_cells() const {
    uint64_t n = 0;
    for (auto const& r : regions) n += r.cells.size();
    return n;
  }
};

namespace detail {

struct KdBuild {
  std::vector<glm::vec3> centroid;
  std::vector<uint64_t> ids;  // reordered in place by the splits
  KdPartition* out = nullptr;

  // Builds the subtree over ids[begin, end) in box [lo, hi] with k regions;
  // returns its node id (negative: a region).
  int build(uint64_t begin, uint64_t end, glm::vec3 lo, glm::vec3 hi, int k) {
    if (k == 1) {
      int const r = int(out->regions.size());
      out->regions.push_back({lo, hi, {}});
      return -r - 1;
    }
    glm::vec3 const ext = hi - lo;
    int const axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : ext.y >= ext.z ? 1 : 2;
    int const k_below = k / 2;
    // Cells in proportion to the regions on each side (k odd: the sides
    // get k / 2 and k - k / 2 regions and as many n / k shares of cells).
    uint64_t const n = end - begin;
    uint64_t const m = begin + uint64_t(double(n) * double(k_below) / double(k));
    float pos = 0.5f * (lo[axis] + hi[axis]);  // no cells: the middle
    if (n > 0) {
      auto key = [&](uint64_t c) { return centroid[c][axis]; };
      uint64_t const nth = std::min(m, end - 1);
      std::nth_element(ids.begin() + std::ptrdiff_t(begin), ids.begin() + std::ptrdiff_t(nth),
                       ids.begin() + std::ptrdiff_t(end), [&](uint64_t a, uint64_t b) { return key(a) < key(b); });
      pos = std::clamp(key(ids[nth]), lo[axis], hi[axis]);
    }
    int const id = int(out->splits.size());
    out->splits.push_back({axis, pos, 0, 0});
    glm::vec3 below_hi = hi, above_lo = lo;
    below_hi[axis] = pos;
    above_lo[axis] = pos;
    int const b = build(begin, m, lo, below_hi, k_below);
    int const a = build(m, end, above_lo, hi, k - k_below);
    out->splits[size_t(id)].below = b;
    out->splits[size_t(id)].above = a;
    return id;
  }
};

}  // namespace detail

/// Partitions `mesh` into `k` regions by its cells' centroids: each split
/// halves a box on its longest axis at the centroid that leaves cells in
/// proportion to the regions on each side (k need not be a power of two).
/// Empty regions are possible (k above the cell count, many equal
/// centroids) and valid. TBB-parallel over cells; O(n log k) plus the
/// assignment, and 24 bytes per cell while running (centroids and ids).
/// @throws InvalidArgument for k < 1; InvalidMesh for a cell with a
///         non-finite vertex position or a vertex id past the positions
///         (naming the cell). An empty mesh gives k empty regions of the
///         empty box [0, 0].
template <int N> KdPartition partition_kd(CellMesh<N> const& mesh, int k) {
  if (k < 1) throw InvalidArgument("partition_kd: k must be at least 1, got " + std::to_string(k));
  uint64_t const n = mesh.cell_count();
  uint64_t const nv = mesh.vertex_count();
  std::vector<glm::vec3> box_lo(n), box_hi(n);
  detail::KdBuild b;
  b.centroid.resize(n);
  constexpr uint64_t none = std::numeric_limits<uint64_t>::max();
  std::vector<uint64_t> bad_block;  // first bad cell per block
  uint64_t const block = 4096;
  bad_block.assign((n + block - 1) / block, none);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, bad_block.size()), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t bi = r.begin(); bi != r.end(); ++bi)
      for (uint64_t c = bi * block; c < std::min(n, (bi + 1) * block); ++c) {
        glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-lo), sum(0.f);
        bool ok = true;
        for (int j = 0; j < N; ++j) {
          uint64_t const v = mesh.vertex(c, j);
          if (v >= nv) {
            ok = false;
            break;
          }
          glm::vec3 const p = mesh.position(v);
          ok = ok && std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
          lo = glm::min(lo, p), hi = glm::max(hi, p), sum += p;
        }
        if (!ok && bad_block[bi] == none) bad_block[bi] = c;
        box_lo[c] = lo, box_hi[c] = hi;
        b.centroid[c] = sum / float(N);
      }
  });
  for (uint64_t c : bad_block)
    if (c != none)
      throw InvalidMesh("partition_kd: cell " + std::to_string(c) +
                        " has a vertex id past the positions or a non-finite vertex position");

  KdPartition part;
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-lo);
  for (uint64_t c = 0; c < n; ++c) lo = glm::min(lo, box_lo[c]), hi = glm::max(hi, box_hi[c]);
  if (n == 0) lo = hi = glm::vec3(0.f);
  part.lo = lo, part.hi = hi;
  part.regions.reserve(size_t(k));
  part.splits.reserve(size_t(k - 1));
  b.ids.resize(n);
  for (uint64_t c = 0; c < n; ++c) b.ids[c] = c;
  b.out = &part;
  b.build(0, n, lo, hi, k);
  b.ids = {};
  b.centroid = {};

  // Assignment by box overlap, down the tree: a cell goes below a split when
  // its box reaches at or below the plane, above when it reaches at or above.
  // Two passes over blocks of cells (count per block and region, then fill
  // at the prefix sums) keep each region's cells ascending without a
  // per-region bitmap (k n bytes: too much at k = 512).
  size_t const ku = size_t(k), blocks = bad_block.size();
  std::vector<uint64_t> count(blocks * ku, 0);
  auto visit = [&](uint64_t c, auto&& emit) {
    int stack[64];  // depth <= log2(k) + 1 per pending branch: k < 2^31
    int top = 0;
    stack[top++] = part.splits.empty() ? -1 : 0;
    while (top > 0) {
      int const id = stack[--top];
      if (id < 0) {
        emit(size_t(-id - 1));
        continue;
      }
      KdSplit const& s = part.splits[size_t(id)];
      if (box_hi[c][s.axis] >= s.position) stack[top++] = s.above;
      if (box_lo[c][s.axis] <= s.position) stack[top++] = s.below;
    }
  };
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t bi = r.begin(); bi != r.end(); ++bi)
      for (uint64_t c = bi * block; c < std::min(n, (bi + 1) * block); ++c)
        visit(c, [&](size_t region) { ++count[bi * ku + region]; });
  });
  for (size_t r = 0; r < ku; ++r) {
    uint64_t total = 0;
    for (size_t bi = 0; bi < blocks; ++bi) {
      uint64_t const c = count[bi * ku + r];
      count[bi * ku + r] = total;
      total += c;
    }
    part.regions[r].cells.resize(total);
  }
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t bi = r.begin(); bi != r.end(); ++bi)
      for (uint64_t c = bi * block; c < std::min(n, (bi + 1) * block); ++c)
        visit(c, [&](size_t region) { part.regions[region].cells[count[bi * ku + region]++] = c; });
  });
  return part;
}

/// The cells `ids` of `mesh` as a mesh of their own: an owned index array
/// (the same index width as the mesh's) over the mesh's positions and point
/// arrays, which are viewed, not copied (they must outlive this). Cell i of
/// `mesh()` is cell ids[i] of `mesh`.
template <int N> struct CellSubset {
  CellMesh<N> parent;
  std::vector<uint32_t> idx32;
  std::vector<uint64_t> idx64;

  /// The view over the subset, with the parent's arrays and active array.
  CellMesh<N> mesh() const {
    Span<float> const xyz{parent.positions(), parent.vertex_count() * 3};
    CellMesh<N> m = parent.has_32bit_indices() ? CellMesh<N>(xyz, view(idx32)) : CellMesh<N>(xyz, view(idx64));
    for (ScalarArray const& a : parent.arrays()) m.add_array(a.name, a.values);
    return parent.has_values() ? m.with_array(parent.active_array()) : m;
  }
};

/// @throws InvalidArgument for an id past the mesh's cells.
template <int N> CellSubset<N> subset_cells(CellMesh<N> const& mesh, std::vector<uint64_t> const& ids) {
  CellSubset<N> s;
  s.parent = mesh;
  uint64_t const n = mesh.cell_count();
  for (uint64_t c : ids)
    if (c >= n)
      throw InvalidArgument("subset_cells: cell id " + std::to_string(c) + " past the mesh's " + std::to_string(n) +
                            " cells");
  if (mesh.has_32bit_indices()) {
    s.idx32.resize(ids.size() * N);
    for (size_t i = 0; i < ids.size(); ++i)
      std::copy_n(mesh.indices32() + ids[i] * N, N, s.idx32.data() + i * N);
  } else {
    s.idx64.resize(ids.size() * N);
    for (size_t i = 0; i < ids.size(); ++i)
      std::copy_n(mesh.indices64() + ids[i] * N, N, s.idx64.data() + i * N);
  }
  return s;
}

}  // namespace cellray
