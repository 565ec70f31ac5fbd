#pragma once
// Face neighbours of a tetrahedral mesh: for each cell and face, the cell on
// the other side. Cell-segment DVR and ambient-occlusion rays march from cell
// to cell through them instead of clipping every cell of every BVH leaf a
// packet reaches (traverse/march.hpp). Topology only: a new time step
// (CellMesh::with_values) keeps them; new connectivity needs a new build.
//
// Face f of a cell is the face opposite its f-th corner in ascending vertex
// id order: the order the tet kernels use (cells/corners.hpp, tet.hpp), so
// the clip's exit face index picks the entry across it directly.

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../error.hpp"
#include "cell_mesh.hpp"

namespace cellray {

/// 16 bytes per tet: `across(cell, f)` is the cell sharing face f, or -1 on
/// the mesh boundary, at a face shared by more than two cells (duplicated or
/// overlapping cells: no single neighbour is right) and for every face of a
/// cell with a repeated vertex id (degenerate).
class TetNeighbours {
 public:
  TetNeighbours() = default;
  uint64_t cell_count() const noexcept { return across_.size() / 4; }
  int32_t across(uint64_t cell, int face) const noexcept { return across_[4 * cell + uint64_t(face)]; }
  int32_t const* data() const noexcept { return across_.data(); }
  uint64_t memory_bytes() const noexcept { return across_.size() * sizeof(int32_t); }

  /// Whether these were built over `mesh`'s connectivity, as far as a cheap
  /// check tells: the same cell and vertex counts and the same vertex ids
  /// in 64 cells spread over the mesh. Neighbours of another mesh would send
  /// a march to cells its ray does not enter next (wrong pixels, not a
  /// crash), so the renderer refuses them.
  bool fits(TetMesh const& mesh) const noexcept {
    return mesh.cell_count() == cell_count() && mesh.vertex_count() == vertex_count_ && fingerprint(mesh) == fingerprint_;
  }

 private:
  friend TetNeighbours build_tet_neighbours(TetMesh const& mesh);
  static uint64_t fingerprint(TetMesh const& mesh) noexcept {
    uint64_t const n = mesh.cell_count();
    uint64_t h = 0x9e3779b97f4a7c15ull;
    for (uint64_t k = 0; k < 64 && n > 0; ++k) {
      uint64_t const c = k * (n - 1) / 63;
      for (int i = 0; i < 4; ++i) h = (h ^ mesh.vertex(c, i)) * 0x100000001b3ull;
    }
    return h;
  }
  std::vector<int32_t> across_;
  uint64_t vertex_count_ = 0, fingerprint_ = 0;
};

namespace detail {

/// build_tet_neighbours with vertex ids stored as `Id` (32-bit when they fit).
template <class Id> void match_tet_faces(TetMesh const& mesh, std::vector<int32_t>& across) {
  uint64_t const n = mesh.cell_count(), nv = mesh.vertex_count();
  // Every cell's ids in ascending order, once (TBB): the face keys below
  // read them instead of sorting a cell's ids for each of its faces.
  std::vector<Id> ids(4 * n);
  std::atomic<uint64_t> first_bad{n};  // the first cell with a vertex id out of range
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 8192), [&](tbb::blocked_range<uint64_t> const& range) {
    for (uint64_t c = range.begin(); c < range.end(); ++c) {
      uint64_t v[4];
      for (int i = 0; i < 4; ++i) v[i] = mesh.vertex(c, i);
      std::sort(v, v + 4);
      if (v[3] >= nv) {
        uint64_t seen = first_bad.load();
        while (c < seen && !first_bad.compare_exchange_weak(seen, c)) {
        }
        return;
      }
      for (int i = 0; i < 4; ++i) ids[4 * c + uint64_t(i)] = Id(v[i]);
    }
  });
  if (uint64_t const c = first_bad.load(); c < n) {
    uint64_t bad = 0;
    for (int i = 0; i < 4; ++i) bad = std::max(bad, mesh.vertex(c, i));
    throw InvalidMesh("cell " + std::to_string(c) + " refers to vertex " + std::to_string(bad) + " of " +
                      std::to_string(nv));
  }
  // A face is keyed by its smallest vertex: v[0] for faces 1..3, v[1] for
  // face 0. A cell with a repeated id (degenerate) gets no neighbours.
  auto degenerate = [&](uint64_t c) {
    Id const* v = &ids[4 * c];
    return v[0] == v[1] || v[1] == v[2] || v[2] == v[3];
  };
  auto key_vertex = [&](uint64_t c, int f) { return uint64_t(ids[4 * c + (f == 0 ? 1 : 0)]); };
  std::vector<uint64_t> start(nv + 1, 0);
  for (uint64_t c = 0; c < n; ++c)
    if (!degenerate(c))
      for (int f = 0; f < 4; ++f) ++start[key_vertex(c, f) + 1];
  for (uint64_t i = 0; i < nv; ++i) start[i + 1] += start[i];
  std::vector<uint64_t> slot(start[nv]);  // faces by key vertex: 4 cell + f
  {
    std::vector<uint64_t> fill(start.begin(), start.end() - 1);
    for (uint64_t c = 0; c < n; ++c)
      if (!degenerate(c))
        for (int f = 0; f < 4; ++f) slot[fill[key_vertex(c, f)]++] = 4 * c + uint64_t(f);
  }
  // Within a bucket: sort by the face's other two vertices; runs of exactly
  // two equal keys are neighbours.
  struct Key {
    Id b, c;
    uint64_t slot;
  };
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nv, 4096), [&](tbb::blocked_range<uint64_t> const& range) {
    std::vector<Key> keys;
    for (uint64_t a = range.begin(); a < range.end(); ++a) {
      keys.clear();
      for (uint64_t i = start[a]; i < start[a + 1]; ++i) {
        Id const* v = &ids[slot[i] & ~uint64_t(3)];
        int const f = int(slot[i] & 3u);
        Id w[3];
        for (int k = 0, j = 0; k < 4; ++k)
          if (k != f) w[j++] = v[k];
        keys.push_back({w[1], w[2], slot[i]});
      }
      std::sort(keys.begin(), keys.end(), [](Key const& x, Key const& y) {
        return x.b != y.b ? x.b < y.b : x.c != y.c ? x.c < y.c : x.slot < y.slot;
      });
      for (size_t i = 0; i < keys.size();) {
        size_t j = i + 1;
        while (j < keys.size() && keys[j].b == keys[i].b && keys[j].c == keys[i].c) ++j;
        if (j - i == 2) {
          across[keys[i].slot] = int32_t(keys[i + 1].slot / 4);
          across[keys[i + 1].slot] = int32_t(keys[i].slot / 4);
        }
        i = j;
      }
    }
  });
}

}  // namespace detail

/// Matches every face of `mesh` with the face of another cell over the same
/// three vertices: each cell's ids sorted once (TBB), faces bucketed by their
/// smallest vertex (a counting sort), then matched within each bucket on the
/// other two vertices, buckets in parallel on TBB. Transient memory: 48 bytes
/// per cell (64 beyond 2^32 vertices) plus 8 per vertex.
/// @throws InvalidArgument when the mesh has 2^31 cells or more (cell ids are
///         32-bit, as in traversal) or InvalidMesh when a vertex id is out of
///         range.
inline TetNeighbours build_tet_neighbours(TetMesh const& mesh) {
  uint64_t const n = mesh.cell_count();
  if (n >= (uint64_t(1) << 31))
    throw InvalidArgument("face neighbours support up to 2^31 - 1 cells, the mesh has " + std::to_string(n));
  TetNeighbours out;
  out.across_.assign(4 * n, -1);
  out.vertex_count_ = mesh.vertex_count();
  out.fingerprint_ = TetNeighbours::fingerprint(mesh);
  if (n == 0) return out;
  if (mesh.vertex_count() <= (uint64_t(1) << 32)) detail::match_tet_faces<uint32_t>(mesh, out.across_);
  else detail::match_tet_faces<uint64_t>(mesh, out.across_);
  return out;
}

}  // namespace cellray
