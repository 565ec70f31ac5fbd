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

 private:
  friend TetNeighbours build_tet_neighbours(TetMesh const& mesh);
  std::vector<int32_t> across_;
};

namespace detail {

/// A cell's vertex ids in ascending order.
inline void sorted_tet_vertices(TetMesh const& mesh, uint64_t cell, uint64_t (&v)[4]) {
  for (int i = 0; i < 4; ++i) v[i] = mesh.vertex(cell, i);
  std::sort(v, v + 4);
}

}  // namespace detail

/// Matches every face of `mesh` with the face of another cell over the same
/// three vertices. Faces are bucketed by their smallest vertex (a counting
/// sort of 8 bytes per face), then matched within each bucket on the other
/// two vertices, buckets in parallel on TBB. Transient memory: 32 bytes per
/// cell plus 8 per vertex.
/// @throws InvalidArgument when the mesh has 2^31 cells or more (cell ids are
///         32-bit, as in traversal) or InvalidMesh when a vertex id is out of
///         range.
inline TetNeighbours build_tet_neighbours(TetMesh const& mesh) {
  uint64_t const n = mesh.cell_count(), nv = mesh.vertex_count();
  if (n >= (uint64_t(1) << 31))
    throw InvalidArgument("face neighbours support up to 2^31 - 1 cells, the mesh has " + std::to_string(n));
  TetNeighbours out;
  out.across_.assign(4 * n, -1);
  if (n == 0) return out;
  // Faces by smallest vertex: offsets per vertex, then face slots (4 cell + f).
  std::vector<uint64_t> start(nv + 1, 0);
  // A face is keyed by its smallest vertex: v[0] for faces 1..3, v[1] for
  // face 0. A cell with a repeated id (degenerate) gets no neighbours.
  auto face_ok = [](uint64_t const (&v)[4], int f, uint64_t& a) {
    a = f == 0 ? v[1] : v[0];
    return v[0] != v[1] && v[1] != v[2] && v[2] != v[3];
  };
  for (uint64_t c = 0; c < n; ++c) {
    uint64_t v[4];
    detail::sorted_tet_vertices(mesh, c, v);
    if (v[3] >= nv)
      throw InvalidMesh("cell " + std::to_string(c) + " refers to vertex " + std::to_string(v[3]) + " of " +
                        std::to_string(nv));
    for (int f = 0; f < 4; ++f)
      if (uint64_t a; face_ok(v, f, a)) ++start[a + 1];
  }
  for (uint64_t i = 0; i < nv; ++i) start[i + 1] += start[i];
  std::vector<uint64_t> slot(start[nv]);
  {
    std::vector<uint64_t> fill(start.begin(), start.end() - 1);
    for (uint64_t c = 0; c < n; ++c) {
      uint64_t v[4];
      detail::sorted_tet_vertices(mesh, c, v);
      for (int f = 0; f < 4; ++f)
        if (uint64_t a; face_ok(v, f, a)) slot[fill[a]++] = 4 * c + uint64_t(f);
    }
  }
  // Within a bucket: sort by the face's other two vertices; runs of exactly
  // two equal keys are neighbours.
  struct Key {
    uint64_t b, c, slot;
  };
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nv, 4096), [&](tbb::blocked_range<uint64_t> const& range) {
    std::vector<Key> keys;
    for (uint64_t a = range.begin(); a < range.end(); ++a) {
      keys.clear();
      for (uint64_t i = start[a]; i < start[a + 1]; ++i) {
        uint64_t v[4];
        uint64_t const cell = slot[i] / 4;
        int const f = int(slot[i] % 4);
        detail::sorted_tet_vertices(mesh, cell, v);
        uint64_t w[3];
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
          out.across_[keys[i].slot] = int32_t(keys[i + 1].slot / 4);
          out.across_[keys[i + 1].slot] = int32_t(keys[i].slot / 4);
        }
        i = j;
      }
    }
  });
  return out;
}

}  // namespace cellray
