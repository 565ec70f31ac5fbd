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
//
// The pieces, for a host that distributes the cells itself (as
// cellray-mpi-render does from a .pvtu): kd_tree() builds the tree from any
// points (e.g. a sample of centroids gathered from every rank),
// cell_extents() gives a mesh's cell boxes, assign_cells() lists each
// region's cells (optionally with a halo), and subset_cells() makes a
// region a mesh of its own with compact vertices. partition_kd() is all of
// it for a mesh one process holds.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
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
  std::vector<glm::vec3> const* point = nullptr;
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
    // Points in proportion to the regions on each side (k odd: the sides
    // get k / 2 and k - k / 2 regions and as many n / k shares of points).
    uint64_t const n = end - begin;
    uint64_t const m = begin + uint64_t(double(n) * double(k_below) / double(k));
    float pos = 0.5f * (lo[axis] + hi[axis]);  // no points: the middle
    if (n > 0) {
      auto key = [&](uint64_t c) { return (*point)[c][axis]; };
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

inline constexpr uint64_t kd_block = 4096;  // cells per task in the parallel passes

}  // namespace detail

/// The k-d tree of `points` in the box [lo, hi] (regions' cell lists left
/// empty): each split halves a box on its longest axis at the point that
/// leaves points in proportion to the regions on each side (k need not be a
/// power of two). Deterministic: the same points in the same order give the
/// same tree on every machine (what MPI ranks rely on when each builds it
/// from the same gathered sample). Points outside [lo, hi] are allowed (the
/// split positions are clamped to the box).
/// @throws InvalidArgument for k < 1.
inline KdPartition kd_tree(std::vector<glm::vec3> const& points, glm::vec3 lo, glm::vec3 hi, int k) {
  if (k < 1) throw InvalidArgument("partition_kd: k must be at least 1, got " + std::to_string(k));
  KdPartition part;
  part.lo = lo, part.hi = hi;
  part.regions.reserve(size_t(k));
  part.splits.reserve(size_t(k - 1));
  detail::KdBuild b;
  b.point = &points;
  b.ids.resize(points.size());
  for (uint64_t c = 0; c < points.size(); ++c) b.ids[c] = c;
  b.out = &part;
  b.build(0, points.size(), lo, hi, k);
  return part;
}

/// Per-cell bounding boxes and centroids (vertex means) of a mesh, and what
/// partitioning needs from them: 36 bytes per cell.
struct CellExtents {
  std::vector<glm::vec3> lo, hi, centroid;
  glm::vec3 bounds_lo{0.f}, bounds_hi{0.f};  ///< union of the boxes; [0, 0] when there are none
  /// Per axis, the largest extent of any cell's box. As a halo (assign_cells),
  /// it makes a region hold every cell around every vertex of its cells.
  glm::vec3 largest_extent{0.f};
  uint64_t size() const noexcept { return lo.size(); }
};

/// TBB-parallel over cells.
/// @throws InvalidMesh for a cell with a vertex id past the positions or a
///         non-finite vertex position, naming the cell.
template <int N> CellExtents cell_extents(CellMesh<N> const& mesh) {
  uint64_t const n = mesh.cell_count();
  uint64_t const nv = mesh.vertex_count();
  CellExtents out;
  out.lo.resize(n), out.hi.resize(n), out.centroid.resize(n);
  constexpr uint64_t none = std::numeric_limits<uint64_t>::max();
  uint64_t const block = detail::kd_block;
  std::vector<uint64_t> bad_block((n + block - 1) / block, none);  // first bad cell per block
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
        out.lo[c] = lo, out.hi[c] = hi;
        out.centroid[c] = sum / float(N);
      }
  });
  for (uint64_t c : bad_block)
    if (c != none)
      throw InvalidMesh("partition_kd: cell " + std::to_string(c) +
                        " has a vertex id past the positions or a non-finite vertex position");
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-lo), ext(0.f);
  for (uint64_t c = 0; c < n; ++c) {
    lo = glm::min(lo, out.lo[c]), hi = glm::max(hi, out.hi[c]);
    ext = glm::max(ext, out.hi[c] - out.lo[c]);
  }
  if (n == 0) lo = hi = glm::vec3(0.f);
  out.bounds_lo = lo, out.bounds_hi = hi, out.largest_extent = ext;
  return out;
}

/// The regions (ids into part.regions) whose boxes overlap [lo - halo, hi +
/// halo] (closed intervals: touching counts), passed to `emit` in k-d tree
/// order. O(regions visited).
template <class Emit>
void for_each_overlapping_region(KdPartition const& part, glm::vec3 lo, glm::vec3 hi, glm::vec3 halo, Emit&& emit) {
  lo -= halo, hi += halo;
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
    if (hi[s.axis] >= s.position) stack[top++] = s.above;
    if (lo[s.axis] <= s.position) stack[top++] = s.below;
  }
}

/// For each region of `part`, the cells (ascending ids) whose boxes overlap
/// the region's box grown by `halo` on each side. halo = 0: the cells the
/// region's rays can meet. halo = boxes.largest_extent: also every cell
/// around every vertex of those cells, so per-vertex quantities summed over
/// cells (smooth-normal gradients) come out as on the whole mesh.
/// TBB-parallel; two passes over blocks of cells (count per block and
/// region, then fill at the prefix sums) keep each region's cells ascending
/// without a per-region bitmap (k n bytes: too much at k = 512).
inline std::vector<std::vector<uint64_t>> assign_cells(KdPartition const& part, CellExtents const& boxes,
                                                       glm::vec3 halo = glm::vec3(0.f)) {
  uint64_t const n = boxes.size(), block = detail::kd_block;
  size_t const ku = part.regions.size(), blocks = size_t((n + block - 1) / block);
  std::vector<std::vector<uint64_t>> cells(ku);
  std::vector<uint64_t> count(blocks * ku, 0);
  auto visit = [&](uint64_t c, auto&& emit) { for_each_overlapping_region(part, boxes.lo[c], boxes.hi[c], halo, emit); };
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks), [&](tbb::blocked_range<size_t> const& r) {
    for (size_t bi = r.begin(); bi != r.end(); ++bi)
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
    cells[r].resize(total);
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks), [&](tbb::blocked_range<size_t> const& r) {
    for (size_t bi = r.begin(); bi != r.end(); ++bi)
      for (uint64_t c = bi * block; c < std::min(n, (bi + 1) * block); ++c)
        visit(c, [&](size_t region) { cells[region][count[bi * ku + region]++] = c; });
  });
  return cells;
}

/// Partitions `mesh` into `k` regions by its cells' centroids (kd_tree over
/// all of them, in the mesh bounds) and assigns the cells (assign_cells,
/// with `halo`). Empty regions are possible (k above the cell count, many
/// equal centroids) and valid. TBB-parallel over cells; O(n log k) plus the
/// assignment, and 44 bytes per cell while running.
/// @throws InvalidArgument for k < 1; InvalidMesh for a cell with a
///         non-finite vertex position or a vertex id past the positions
///         (naming the cell). An empty mesh gives k empty regions of the
///         empty box [0, 0].
template <int N> KdPartition partition_kd(CellMesh<N> const& mesh, int k, glm::vec3 halo = glm::vec3(0.f)) {
  if (k < 1) throw InvalidArgument("partition_kd: k must be at least 1, got " + std::to_string(k));
  CellExtents const boxes = cell_extents(mesh);
  KdPartition part = kd_tree(boxes.centroid, boxes.bounds_lo, boxes.bounds_hi, k);
  std::vector<std::vector<uint64_t>> cells = assign_cells(part, boxes, halo);
  for (size_t r = 0; r < cells.size(); ++r) part.regions[r].cells = std::move(cells[r]);
  return part;
}

/// The vertex arrays of a subset (CellSubset, MixedCellSubset): compact
/// copies of the parent's vertices its cells use, in order of first use,
/// and every point array at them. Vertex j is vertex `vertex_ids[j]` of the
/// parent.
struct SubsetVertices {
  std::vector<float> xyz;
  std::vector<std::string> names;           ///< the parent's point arrays, in order
  std::vector<std::vector<float>> values;   ///< one per name, per subset vertex
  std::string active;                       ///< the parent's active array
  std::vector<uint64_t> vertex_ids;

  uint64_t memory_bytes() const noexcept {
    uint64_t b = xyz.size() * 4 + vertex_ids.size() * 8;
    for (auto const& v : values) b += v.size() * 4;
    return b;
  }

 protected:
  /// A view of cells `idx32` or `idx64` over these vertices, the parent's
  /// array active.
  template <int N> CellMesh<N> view_cells(std::vector<uint32_t> const& idx32, std::vector<uint64_t> const& idx64) const {
    CellMesh<N> m = idx64.empty() ? CellMesh<N>(view(xyz), view(idx32)) : CellMesh<N>(view(xyz), view(idx64));
    for (size_t a = 0; a < names.size(); ++a) m.add_array(names[a], view(values[a]));
    return active.empty() ? m : m.with_array(active);
  }
};

/// The cells `ids` of `mesh` as a mesh of their own, owning compact copies
/// of what they use: the vertices their cells name (in order of first use),
/// every point array at those vertices, and 32-bit indices (64-bit only past
/// 2^32 - 1 vertices). Cell i of `mesh()` is cell ids[i] of `mesh`; vertex j
/// is vertex `vertex_ids[j]` of `mesh`. A region's BVH, neighbours and
/// gradients then cost what the region holds, not what the whole mesh does.
template <int N> struct CellSubset : SubsetVertices {
  std::vector<uint32_t> idx32;
  std::vector<uint64_t> idx64;

  /// The view over the subset's own arrays, the parent's array active.
  CellMesh<N> mesh() const { return view_cells<N>(idx32, idx64); }
  uint64_t memory_bytes() const noexcept {
    return SubsetVertices::memory_bytes() + idx32.size() * 4 + idx64.size() * 8;
  }
};

/// The tets `tet_ids` and hexahedra `hex_ids` of a mixed mesh's two views
/// over one vertex array, as CellSubset makes them, over one compact vertex
/// array for both: the subset's two views share their vertices as the
/// parent's do, so their face neighbours can be linked
/// (link_face_neighbours) and DVR marches across them.
struct MixedCellSubset : SubsetVertices {
  std::vector<uint32_t> tet_idx32, hex_idx32;
  std::vector<uint64_t> tet_idx64, hex_idx64;

  TetMesh tets() const { return view_cells<4>(tet_idx32, tet_idx64); }
  HexMesh hexes() const { return view_cells<8>(hex_idx32, hex_idx64); }
  uint64_t memory_bytes() const noexcept {
    return SubsetVertices::memory_bytes() + (tet_idx32.size() + hex_idx32.size()) * 4 +
           (tet_idx64.size() + hex_idx64.size()) * 8;
  }
};

namespace detail {

/// Parent vertex -> subset vertex, over every part of one subset: a hash
/// map costs what the subset holds (a dense table would cost 4 bytes per
/// parent vertex on every rank).
class SubsetBuilder {
 public:
  explicit SubsetBuilder(SubsetVertices& out) : out_(out) {}

  /// The subset's corners of cells `ids` of `mesh`, its vertices added.
  template <int N> std::vector<uint64_t> corners(CellMesh<N> const& mesh, std::vector<uint64_t> const& ids) {
    uint64_t const n = mesh.cell_count(), nv = mesh.vertex_count();
    for (uint64_t c : ids)
      if (c >= n)
        throw InvalidArgument("subset_cells: cell id " + std::to_string(c) + " past the mesh's " + std::to_string(n) +
                              " cells");
    local_.reserve(local_.size() + ids.size() * (N == 4 ? 1 : 2));
    std::vector<uint64_t> corners(ids.size() * N);
    for (size_t i = 0; i < ids.size(); ++i)
      for (int j = 0; j < N; ++j) {
        uint64_t const v = mesh.vertex(ids[i], j);
        if (v >= nv)
          throw InvalidMesh("subset_cells: cell " + std::to_string(ids[i]) + " names vertex " + std::to_string(v) +
                            " past the mesh's " + std::to_string(nv) + " vertices");
        auto const [it, added] = local_.try_emplace(v, out_.vertex_ids.size());
        if (added) out_.vertex_ids.push_back(v);
        corners[i * N + size_t(j)] = it->second;
      }
    return corners;
  }

  /// Indices as 32-bit unless the subset's vertices need 64.
  void store(std::vector<uint64_t>&& corners, std::vector<uint32_t>& idx32, std::vector<uint64_t>& idx64) const {
    if (out_.vertex_ids.size() <= std::numeric_limits<uint32_t>::max()) idx32.assign(corners.begin(), corners.end());
    else idx64 = std::move(corners);
  }

  /// Positions and point arrays of the subset's vertices from `mesh`.
  template <int N> void copy_vertices(CellMesh<N> const& mesh) {
    std::vector<uint64_t> const& ids = out_.vertex_ids;
    out_.xyz.resize(ids.size() * 3);
    for (size_t j = 0; j < ids.size(); ++j) {
      glm::vec3 const p = mesh.position(ids[j]);
      out_.xyz[3 * j] = p.x, out_.xyz[3 * j + 1] = p.y, out_.xyz[3 * j + 2] = p.z;
    }
    for (ScalarArray const& a : mesh.arrays()) {
      out_.names.push_back(a.name);
      std::vector<float>& v = out_.values.emplace_back(ids.size());
      for (size_t j = 0; j < ids.size(); ++j) v[j] = a.values.data[ids[j]];
    }
    out_.active = std::string(mesh.active_array());
  }

 private:
  SubsetVertices& out_;
  std::unordered_map<uint64_t, uint64_t> local_;
};

}  // namespace detail

/// @throws InvalidArgument for an id past the mesh's cells; InvalidMesh
///         for a vertex id past the mesh's vertices (naming the cell).
template <int N> CellSubset<N> subset_cells(CellMesh<N> const& mesh, std::vector<uint64_t> const& ids) {
  CellSubset<N> s;
  detail::SubsetBuilder b(s);
  b.store(b.corners(mesh, ids), s.idx32, s.idx64);
  b.copy_vertices(mesh);
  return s;
}

/// The mixed subset of `tets` and `hexes`, which must view one vertex
/// array (a mixed mesh's two parts, as UnstructuredGrid::tet_mesh and
/// hex_mesh give them) with the same point arrays; the tets' active array
/// is active. Either list may be empty.
/// @throws InvalidArgument for parts over different vertex arrays and as
///         subset_cells.
inline MixedCellSubset subset_cells(TetMesh const& tets, std::vector<uint64_t> const& tet_ids, HexMesh const& hexes,
                                    std::vector<uint64_t> const& hex_ids) {
  if (tets.positions() != hexes.positions() || tets.vertex_count() != hexes.vertex_count())
    throw InvalidArgument("subset_cells: the tets and hexahedra do not view one vertex array");
  MixedCellSubset s;
  detail::SubsetBuilder b(s);
  // Each part's ids are 32-bit when they fit when it is stored: the tets'
  // stay valid if the hexahedra's vertices pass 2^32 - 1.
  b.store(b.corners(tets, tet_ids), s.tet_idx32, s.tet_idx64);
  b.store(b.corners(hexes, hex_ids), s.hex_idx32, s.hex_idx64);
  b.copy_vertices(tets);
  return s;
}

}  // namespace cellray
