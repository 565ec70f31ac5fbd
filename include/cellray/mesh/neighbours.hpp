#pragma once
// Face neighbours of a tetrahedral or a hexahedral mesh (wedges, pyramids
// and folded tets as collapsed hexahedra): for each cell and face, the cell
// on the other side. Cell-segment DVR (tets and hexahedra) and
// ambient-occlusion rays (tets) march from cell to cell through them
// instead of clipping every cell of every BVH leaf a packet reaches
// (traverse/march.hpp). Topology only: a new time step
// (CellMesh::with_values) keeps them; new connectivity needs a new build.
//
// Tets: face f of a cell is the face opposite its f-th corner in ascending
// vertex id order, the order the tet kernels use (cells/corners.hpp,
// tet.hpp), so the clip's exit face index picks the entry across it
// directly. Hexahedra: VTK's faces in cells/hex.hpp's order.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include "../error.hpp"
#include "../memory.hpp"
#include "cell_mesh.hpp"

namespace cellray {

namespace detail {

/// A cell's four vertex ids in ascending order (a sorting network: no
/// branches on the ids). One compare and two selects per exchange: GCC 12
/// made a std::min/std::max pair a branch, taken at random on a mesh whose
/// corner ids are not in order (component8: 1.24x the matching time).
template <class Src> inline void sorted_corners(Src const* cell, Src v[4]) noexcept {
  Src a = cell[0], b = cell[1], c = cell[2], d = cell[3];
  auto cswap = [](Src& x, Src& y) {
    bool const s = y < x;
    Src const lo = s ? y : x, hi = s ? x : y;
    x = lo, y = hi;
  };
  cswap(a, b), cswap(c, d), cswap(a, c), cswap(b, d), cswap(b, c);
  v[0] = a, v[1] = b, v[2] = c, v[3] = d;
}

/// A face within its bucket (its smallest vertex): the other two vertex ids,
/// packed so one compare tells them apart, and the (cell, face) it is of.
template <class Id> struct FaceKey {
  uint64_t bc;
  uint32_t cell, face;
  static FaceKey make(Id b, Id c, uint64_t cell, int face) {
    return {uint64_t(b) << 32 | uint64_t(c), uint32_t(cell), uint32_t(face)};
  }
  bool same(FaceKey const& o) const noexcept { return bc == o.bc; }
  uint64_t hash() const noexcept { return bc * 0x9e3779b97f4a7c15ull; }
  static FaceKey sentinel() noexcept { return {~uint64_t(0), 0, 0}; }  // b < c in real keys
};
template <> struct FaceKey<uint64_t> {  // beyond 2^32 vertices
  uint64_t b, c;
  uint32_t cell, face;
  static FaceKey make(uint64_t b, uint64_t c, uint64_t cell, int face) { return {b, c, uint32_t(cell), uint32_t(face)}; }
  bool same(FaceKey const& o) const noexcept { return b == o.b && c == o.c; }
  uint64_t hash() const noexcept { return (b * 0x9e3779b97f4a7c15ull ^ c) * 0xff51afd7ed558ccdull; }
  static FaceKey sentinel() noexcept { return {~uint64_t(0), ~uint64_t(0), 0, 0}; }
};

/// The parallel counting sort both matchers bucket their faces with: each
/// of B blocks of cells counts its entries into its own histogram over the
/// vertices (no atomics), one scan turns the histograms into every block's
/// cursor in every bucket, and each block scatters its entries. Blocks: one
/// per thread, each at least 16k cells, their histograms (4 bytes per
/// vertex each) at most `histogram_bytes_per_cell` bytes per cell.
class VertexBuckets {
 public:
  VertexBuckets(uint64_t cells, uint64_t vertices, uint64_t histogram_bytes_per_cell) : n_(cells), nv_(vertices) {
    blocks_ = uint64_t(std::max(1, tbb::this_task_arena::max_concurrency()));
    blocks_ = std::min(blocks_, std::max<uint64_t>(1, n_ >> 14));
    blocks_ = std::min(blocks_, std::max<uint64_t>(1, histogram_bytes_per_cell / 4 * n_ / std::max<uint64_t>(nv_, 1)));
    cursor_.resize(blocks_ * nv_);
  }

  /// Counts: `count_cell(c, count)` adds cell c's entries (++count[vertex])
  /// and returns false for a cell naming a vertex out of range, which ends
  /// its block. Returns the first such cell, or the cell count.
  template <class CountCell> uint64_t count(CountCell const& count_cell) {
    std::atomic<uint64_t> first_bad{n_};
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks_, 1), [&](tbb::blocked_range<uint64_t> const& range) {
      for (uint64_t b = range.begin(); b < range.end(); ++b) {
        uint32_t* const count = cursor_.data() + b * nv_;
        std::fill(count, count + nv_, 0u);
        for (uint64_t c = block_begin(b), e = block_begin(b + 1); c < e; ++c)
          if (!count_cell(c, count)) {
            uint64_t seen = first_bad.load();
            while (c < seen && !first_bad.compare_exchange_weak(seen, c)) {
            }
            break;
          }
      }
    });
    if (first_bad.load() < n_) return first_bad.load();
    // Bucket a holds, block by block, [cursor of block 0 in a, end of a).
    // 32-bit offsets: the callers keep the entries under 2^32.
    uint32_t running = 0;
    for (uint64_t a = 0; a < nv_; ++a)
      for (uint64_t b = 0; b < blocks_; ++b) {
        uint32_t const k = cursor_[b * nv_ + a];
        cursor_[b * nv_ + a] = running;
        running += k;
      }
    total_ = running;
    return n_;
  }

  /// Entries counted: the size of the array `scatter` fills.
  uint32_t total() const noexcept { return total_; }

  /// Scatters: `place_cell(c, fill)` stores cell c's entries, in the order
  /// it counted them, at fill[vertex]++.
  template <class PlaceCell> void scatter(PlaceCell const& place_cell) {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks_, 1), [&](tbb::blocked_range<uint64_t> const& range) {
      for (uint64_t b = range.begin(); b < range.end(); ++b) {
        uint32_t* const fill = cursor_.data() + b * nv_;
        for (uint64_t c = block_begin(b), e = block_begin(b + 1); c < e; ++c) place_cell(c, fill);
      }
    });
  }

  /// After scatter: bucket a is [end(a - 1), end(a)) (end(-1) = 0).
  uint32_t const* ends() const noexcept { return cursor_.data() + (blocks_ - 1) * nv_; }

 private:
  uint64_t block_begin(uint64_t b) const noexcept { return b * n_ / blocks_; }
  uint64_t n_, nv_, blocks_ = 1;
  uint32_t total_ = 0;
  LargeVector<uint32_t> cursor_;
};

/// build_tet_neighbours over `Src` vertex ids (the mesh's index type),
/// bucketed with `Id` (32-bit when the vertex count fits).
///
/// Every non-degenerate cell with sorted ids v0 < v1 < v2 < v3 has faces
/// 1..3 in the bucket of v0 and face 0 in the bucket of v1, so the buckets
/// hold cells, not faces: 2 entries per cell, filled by VertexBuckets'
/// parallel counting sort. Within a bucket, faces with the same other two
/// vertices meet in a small hash table; a group of exactly two is a shared
/// face. Only the groups reach the result, not the order within a bucket,
/// so it does not depend on the blocks or the thread count.
template <class Id, class Src> void match_tet_faces(Src const* idx, uint64_t n, uint64_t nv, int32_t* across) {
  VertexBuckets buckets(n, nv, 4);
  uint64_t const bad = buckets.count([&](uint64_t c, uint32_t* count) {
    Src v[4];
    sorted_corners(idx + 4 * c, v);
    if (v[3] >= nv) return false;
    if (v[0] == v[1] || v[1] == v[2] || v[2] == v[3]) {  // degenerate: no neighbours
      for (int f = 0; f < 4; ++f) across[4 * c + uint64_t(f)] = -1;
      return true;
    }
    ++count[v[0]];
    ++count[v[1]];
    return true;
  });
  if (bad < n) {
    Src v[4];
    sorted_corners(idx + 4 * bad, v);
    throw InvalidMesh("cell " + std::to_string(bad) + " refers to vertex " + std::to_string(v[3]) + " of " +
                      std::to_string(nv));
  }
  // The scatter copies each cell's ids into its entries: the buckets then
  // read sequentially, not the cells at random (1.35x faster matching on
  // component8_608k, whose cell order is not spatially coherent).
  struct Entry {
    Id v[3];      // the cell's ids v1, v2, v3 (v0 is the bucket or below it)
    uint32_t cr;  // 2 cell + (bucket is v1)
  };
  LargeVector<Entry> entry(buckets.total());
  buckets.scatter([&](uint64_t c, uint32_t* fill) {
    Src v[4];
    sorted_corners(idx + 4 * c, v);
    if (v[0] == v[1] || v[1] == v[2] || v[2] == v[3]) return;
    entry[fill[v[0]]++] = Entry{{Id(v[1]), Id(v[2]), Id(v[3])}, uint32_t(2 * c)};
    entry[fill[v[1]]++] = Entry{{Id(v[1]), Id(v[2]), Id(v[3])}, uint32_t(2 * c + 1)};
  });
  uint32_t const* const end = buckets.ends();
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nv, 2048), [&](tbb::blocked_range<uint64_t> const& range) {
    struct Group {
      uint32_t head, count, second;  // first key of the group; keys in it; the second key
    };
    std::vector<FaceKey<Id>> keys;
    std::vector<Group> group;
    std::vector<uint32_t> table;
    group.reserve(64), table.reserve(128);
    for (uint64_t a = range.begin(); a < range.end(); ++a) {
      uint32_t const first = a == 0 ? 0 : end[a - 1];
      // Up to 3 keys per entry, 2 past the last (written, then not counted).
      if (keys.size() < 3 * size_t(end[a] - first) + 3) keys.resize(2 * (3 * size_t(end[a] - first) + 3));
      FaceKey<Id>* key = keys.data();
      for (uint32_t i = first; i < end[a]; ++i) {
        uint64_t const c = entry[i].cr >> 1;
        uint32_t const v1_bucket = entry[i].cr & 1u;  // face 0 only; else faces 1..3
        Id const v1 = entry[i].v[0], v2 = entry[i].v[1], v3 = entry[i].v[2];
        // Branch-free: always 3 keys written, 1 or 3 kept.
        key[0] = FaceKey<Id>::make(v2, v3, c, int(1 - v1_bucket));
        key[1] = FaceKey<Id>::make(v1, v3, c, 2);
        key[2] = FaceKey<Id>::make(v1, v2, c, 3);
        key += v1_bucket ? 1 : 3;
      }
      // Equal keys meet in an open-addressing table (over twice the keys,
      // linear probing): each key learns the first key of its group (`head`),
      // which counts them and keeps the last one after itself. GCC 12 makes
      // the first/second-occurrence select a branch; written branch-free it
      // was slower (docs/performance.md, "Kept", tet face neighbours).
      size_t const k = size_t(key - keys.data());
      key[0] = FaceKey<Id>::sentinel();  // what an empty slot (k) points at
      int bits = 4;
      while ((size_t(1) << bits) < 2 * k) ++bits;
      size_t const mask = (size_t(1) << bits) - 1;
      table.assign(mask + 1, uint32_t(k));
      if (group.size() < k) group.resize(2 * k);
      for (uint32_t i = 0; i < uint32_t(k); ++i) {
        // The result row is stored at random below (in a cell order that is
        // not spatial, as component8's): ask for its line now.
        __builtin_prefetch(across + 4 * uint64_t(keys[i].cell), 1);
        size_t h = keys[i].hash() >> (64 - bits);
        uint32_t t = table[h];
        while (!((t == k) | keys[t].same(keys[i]))) t = table[h = (h + 1) & mask];
        uint32_t const head = t == k ? i : t;
        table[h] = head;
        group[i].head = head;
        group[i].count = 0;
        ++group[head].count;
        group[head].second = i;
      }
      for (uint32_t i = 0; i < uint32_t(k); ++i) {
        uint32_t const head = group[i].head;
        uint32_t const other = i == head ? group[head].second : head;
        int32_t const cell = int32_t(keys[other].cell);
        across[4 * uint64_t(keys[i].cell) + keys[i].face] = group[head].count == 2 ? cell : -1;
      }
    }
  });
}

}  // namespace detail

/// Face neighbours of a mesh with N corners per cell: `across(cell, f)` is
/// the cell sharing face f, or -1 on the mesh boundary and at a face shared
/// by more than two cells (duplicated or overlapping cells: no single
/// neighbour is right). After link_face_neighbours, a value v <= -2 names
/// cell -2 - v of the other part of a mixed mesh (a tet's face shared with a
/// wedge's or pyramid's triangle); readers that know no other part treat it
/// as the boundary, as they treat -1.
/// - Tets (TetNeighbours, 16 bytes per cell): faces opposite each corner;
///   every face of a cell with a repeated vertex id is -1 (degenerate).
/// - Hexahedra (HexNeighbours, 24 bytes per cell; wedges and pyramids read
///   as collapsed ones, mesh/vtk_cells.hpp): VTK's hexahedron faces, in the
///   order of cells/hex.hpp's hex_faces (bottom, top, then the four sides).
///   Two faces are shared when they have the same distinct vertices: a quad
///   with a quad, a triangle (a wedge's end, a pyramid's side) with a
///   triangle. A face with fewer than three distinct vertices is -1 (a
///   collapsed face has no area: no ray leaves through it), and so are two
///   faces of one cell over the same vertices (a cell folded flat): a cell
///   is never its own neighbour.
template <int N> class FaceNeighbours {
  static_assert(N == 4 || N == 8, "tets or hexahedra");

 public:
  static constexpr int faces = N == 4 ? 4 : 6;
  FaceNeighbours() = default;
  uint64_t cell_count() const noexcept { return across_.size() / faces; }
  int32_t across(uint64_t cell, int face) const noexcept { return across_[faces * cell + uint64_t(face)]; }
  int32_t const* data() const noexcept { return across_.data(); }
  uint64_t memory_bytes() const noexcept { return across_.size() * sizeof(int32_t); }

  /// Whether these were built over `mesh`'s connectivity, as far as a cheap
  /// check tells: the same cell and vertex counts and the same vertex ids
  /// in 64 cells spread over the mesh. Neighbours of another mesh would send
  /// a march to cells its ray does not enter next (wrong pixels, not a
  /// crash), so the renderer refuses them.
  bool fits(CellMesh<N> const& mesh) const noexcept {
    return mesh.cell_count() == cell_count() && mesh.vertex_count() == vertex_count_ && fingerprint(mesh) == fingerprint_;
  }

  /// Whether the links into another part (values <= -2) name cells of
  /// `other`, by the same check as `fits`: link_face_neighbours linked these
  /// with neighbours of `other`.
  template <int M> bool linked_to(CellMesh<M> const& other) const noexcept {
    return linked_ && M != N && other.cell_count() == linked_cells_ && other.vertex_count() == vertex_count_ &&
           FaceNeighbours<M>::fingerprint(other) == linked_fingerprint_;
  }

 private:
  template <int> friend class FaceNeighbours;
  friend FaceNeighbours<4> build_tet_neighbours(TetMesh const& mesh);
  friend FaceNeighbours<8> build_hex_neighbours(HexMesh const& mesh);
  friend void link_face_neighbours(TetMesh const& tets, FaceNeighbours<4>& tet_nb, HexMesh const& hexes,
                                   FaceNeighbours<8>& hex_nb);
  static uint64_t fingerprint(CellMesh<N> const& mesh) noexcept {
    uint64_t const n = mesh.cell_count();
    uint64_t h = 0x9e3779b97f4a7c15ull;
    for (uint64_t k = 0; k < 64 && n > 0; ++k) {
      uint64_t const c = k * (n - 1) / 63;
      for (int i = 0; i < N; ++i) h = (h ^ mesh.vertex(c, i)) * 0x100000001b3ull;
    }
    return h;
  }
  detail::LargeVector<int32_t> across_;  // unset until built
  uint64_t vertex_count_ = 0, fingerprint_ = 0;
  bool linked_ = false;  ///< link_face_neighbours ran: the other part's cell count and fingerprint
  uint64_t linked_cells_ = 0, linked_fingerprint_ = 0;
};

using TetNeighbours = FaceNeighbours<4>;
using HexNeighbours = FaceNeighbours<8>;

/// Matches every face of `mesh` with the face of another cell over the same
/// three vertices: faces bucketed by their smallest vertex (a counting sort
/// in parallel, per block of cells), then matched within each bucket on the
/// other two vertices, buckets in parallel on TBB (detail::match_tet_faces).
/// The result does not depend on the thread count. Transient memory: 32 bytes
/// per cell (64 beyond 2^32 vertices) plus 4 per vertex and thread (at most
/// 4 more per cell); large arrays are advised as transparent huge pages.
/// @throws InvalidArgument when the mesh has 2^31 cells or more (cell ids are
///         32-bit, as in traversal) or InvalidMesh naming the first cell
///         with a vertex id out of range.
inline TetNeighbours build_tet_neighbours(TetMesh const& mesh) {
  uint64_t const n = mesh.cell_count(), nv = mesh.vertex_count();
  if (n >= (uint64_t(1) << 31))
    throw InvalidArgument("face neighbours support up to 2^31 - 1 cells, the mesh has " + std::to_string(n));
  TetNeighbours out;
  out.across_.resize(4 * n);  // unset: every entry is written below
  out.vertex_count_ = nv;
  out.fingerprint_ = TetNeighbours::fingerprint(mesh);
  if (n == 0) return out;
  bool const narrow = nv <= (uint64_t(1) << 32);
  if (mesh.has_32bit_indices()) detail::match_tet_faces<uint32_t>(mesh.indices32(), n, nv, out.across_.data());
  else if (narrow) detail::match_tet_faces<uint32_t>(mesh.indices64(), n, nv, out.across_.data());
  else detail::match_tet_faces<uint64_t>(mesh.indices64(), n, nv, out.across_.data());
  return out;
}

namespace detail {

/// VTK hexahedron faces (cells/hex.hpp's hex_faces: mesh/ does not include
/// the kernels).
inline constexpr int hex_face_corners[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                               {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};

/// A hex face in the bucket of its smallest vertex: its other distinct
/// vertex ids, ascending (a triangle's third is the largest Id), and the
/// slot 6 x cell + face it is of. 16 bytes with 32-bit ids.
template <class Id> struct HexFaceKey {
  Id v[3];
  uint32_t slot;  ///< fits: build_hex_neighbours takes under 2^29 cells
  bool same_face(HexFaceKey const& o) const noexcept { return v[0] == o.v[0] && v[1] == o.v[1] && v[2] == o.v[2]; }
  uint64_t hash() const noexcept {
    uint64_t const h = (uint64_t(v[0]) * 0x9e3779b97f4a7c15ull ^ uint64_t(v[1])) * 0xff51afd7ed558ccdull;
    return (h ^ uint64_t(v[2])) * 0xc4ceb9fe1a85ec53ull;
  }
  bool operator<(HexFaceKey const& o) const noexcept {
    for (int i = 0; i < 3; ++i)
      if (v[i] != o.v[i]) return v[i] < o.v[i];
    return slot < o.slot;  // a total order: the matching does not depend on arrival order
  }
};

/// The six faces of one hex cell, each as its smallest vertex id (`low`),
/// its key (the other distinct ids) and its count of distinct ids: read
/// from the cell's 8 ids once, with sorting networks and selects (no
/// branches on the ids).
template <class Id> struct HexCellFaces {
  Id low[6];
  HexFaceKey<Id> key[6];
  int distinct[6];

  template <class Src> void read(Src const* cell, uint64_t c) noexcept {
    constexpr Id none = std::numeric_limits<Id>::max();
    Id id[8];
    for (int k = 0; k < 8; ++k) id[k] = Id(cell[k]);
    auto cswap = [](Id& x, Id& y) {
      Id const lo = x < y ? x : y, hi = x < y ? y : x;
      x = lo, y = hi;
    };
    for (int f = 0; f < 6; ++f) {
      Id w0 = id[hex_face_corners[f][0]], w1 = id[hex_face_corners[f][1]];
      Id w2 = id[hex_face_corners[f][2]], w3 = id[hex_face_corners[f][3]];
      cswap(w0, w1), cswap(w2, w3), cswap(w0, w2), cswap(w1, w3), cswap(w1, w2);
      int const d = 1 + int(w0 != w1) + int(w1 != w2) + int(w2 != w3);
      // With one repeated id (a triangle) the distinct ones are w0 and two
      // of w1..w3: drop w1 when it repeats w0, w3 when it repeats w2.
      low[f] = w0;
      key[f].v[0] = w0 == w1 ? w2 : w1;
      key[f].v[1] = d == 4 || w2 == w3 ? w2 : w3;
      key[f].v[2] = d == 4 ? w3 : none;
      key[f].slot = uint32_t(6 * c + uint64_t(f));
      distinct[f] = d;
    }
  }
};

/// build_hex_neighbours over `Src` vertex ids (the mesh's index type),
/// bucketed with `Id` (32-bit when the vertex count fits). Every face with
/// three or more distinct vertices goes to the bucket of its smallest
/// vertex: VertexBuckets' parallel counting sort (each block scatters its
/// faces, recomputed from the cell's ids rather than stored), keys carrying
/// the other ids so buckets read sequentially. Each bucket is then sorted on
/// the other ids and a run of exactly two equal faces is a shared face.
/// Buckets are small (a vertex is the smallest of a few faces) and processed
/// in parallel; only the runs reach the result, so it does not depend on the
/// blocks or thread count.
template <class Id, class Src> void match_hex_faces(Src const* idx, uint64_t n, uint64_t nv, int32_t* across) {
  constexpr uint32_t small_bucket = 16;  // sorted below, hashed above
  // Under 6 x 2^29 faces: 32-bit offsets (see the caller).
  VertexBuckets buckets(n, nv, 32);
  uint64_t const bad = buckets.count([&](uint64_t c, uint32_t* count) {
    Src const* const cell = idx + 8 * c;
    Src top = cell[0];
    for (int k = 1; k < 8; ++k) top = std::max(top, cell[k]);
    if (top >= nv) return false;
    HexCellFaces<Id> faces;
    faces.read(cell, c);
    for (int f = 0; f < 6; ++f) {
      if (faces.distinct[f] >= 3) ++count[faces.low[f]];
      else across[6 * c + uint64_t(f)] = -1;  // no area: no neighbour
    }
    return true;
  });
  if (bad < n) {
    for (int k = 0; k < 8; ++k)
      if (uint64_t(idx[8 * bad + uint64_t(k)]) >= nv)
        throw InvalidMesh("cell " + std::to_string(bad) + " corner " + std::to_string(k) + " names vertex " +
                          std::to_string(uint64_t(idx[8 * bad + uint64_t(k)])) + ", the mesh has " +
                          std::to_string(nv));
  }
  LargeVector<HexFaceKey<Id>> keys(buckets.total());  // unset: every entry is written below
  buckets.scatter([&](uint64_t c, uint32_t* fill) {
    HexCellFaces<Id> faces;
    faces.read(idx + 8 * c, c);
    for (int f = 0; f < 6; ++f)
      if (faces.distinct[f] >= 3) keys[fill[faces.low[f]]++] = faces.key[f];
  });
  uint32_t const* const end = buckets.ends();
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nv, 2048), [&](tbb::blocked_range<uint64_t> const& range) {
    struct Group {
      uint32_t head, count, second;  // first key of the group; keys in it; the last key
    };
    std::vector<Group> group;
    std::vector<uint32_t> table;
    for (uint64_t a = range.begin(); a < range.end(); ++a) {
      uint32_t const first = a == 0 ? 0 : end[a - 1];
      HexFaceKey<Id>* const b = keys.data() + first;
      uint32_t const m = end[a] - first;
      if (m <= small_bucket) {
        for (uint32_t i = 1; i < m; ++i) {  // insertion sort: most buckets hold a few faces
          HexFaceKey<Id> const k = b[i];
          uint32_t j = i;
          for (; j > 0 && k < b[j - 1]; --j) b[j] = b[j - 1];
          b[j] = k;
        }
        for (uint32_t i = 0; i < m;) {
          uint32_t j = i + 1;
          while (j < m && b[j].same_face(b[i])) ++j;
          if (j - i == 2 && b[i].slot / 6 != b[i + 1].slot / 6) {  // not one cell's face twice (folded flat)
            across[b[i].slot] = int32_t(b[i + 1].slot / 6);
            across[b[i + 1].slot] = int32_t(b[i].slot / 6);
          } else {
            for (uint32_t k = i; k < j; ++k) across[b[k].slot] = -1;  // the boundary, or more than two cells
          }
          i = j;
        }
        continue;
      }
      // A vertex that is the smallest of many faces (OpenFOAM numbers the
      // points of a snappy mesh so: the flange's buckets reach hundreds):
      // equal faces meet in an open-addressing table (over twice the keys,
      // linear probing), as in match_tet_faces, not in an m log m sort.
      int bits = 4;
      while ((uint32_t(1) << bits) < 2 * m) ++bits;
      uint32_t const mask = (uint32_t(1) << bits) - 1;
      table.assign(size_t(mask) + 1, m);  // m: empty
      if (group.size() < m) group.resize(2 * size_t(m));
      for (uint32_t i = 0; i < m; ++i) {
        uint32_t h = uint32_t(b[i].hash() >> (64 - bits));
        uint32_t t = table[h];
        while (t != m && !b[t].same_face(b[i])) t = table[h = (h + 1) & mask];
        uint32_t const head = t == m ? i : t;
        table[h] = head;
        group[i].head = head;
        group[i].count = 0;
        ++group[head].count;
        group[head].second = i;
      }
      for (uint32_t i = 0; i < m; ++i) {
        uint32_t const head = group[i].head;
        uint32_t const other = i == head ? group[head].second : head;
        bool const pair = group[head].count == 2 && b[other].slot / 6 != b[i].slot / 6;
        across[b[i].slot] = pair ? int32_t(b[other].slot / 6) : -1;
      }
    }
  });
}

}  // namespace detail

/// Matches every face of a hexahedral mesh (wedges and pyramids included as
/// collapsed hexahedra) with the face of another cell over the same distinct
/// vertices: faces bucketed by their smallest vertex (a counting sort in
/// parallel, per block of cells), matched within each bucket
/// (detail::match_hex_faces), in parallel on TBB; the result does not
/// depend on the thread count. Transient memory: 16 bytes per face with
/// area, up to 96 per cell (32 and 192 from 2^32 - 1 vertices), plus 4 per
/// vertex and thread (at most 32 more per cell); large arrays are advised as
/// huge pages.
/// @throws InvalidArgument when the mesh has 2^29 cells or more, or
///         InvalidMesh naming the first cell with a vertex id out of range.
inline HexNeighbours build_hex_neighbours(HexMesh const& mesh) {
  uint64_t const n = mesh.cell_count(), nv = mesh.vertex_count();
  if (n >= (uint64_t(1) << 29))  // 6 faces per cell: bucket offsets stay 32-bit
    throw InvalidArgument("hexahedral face neighbours support up to 2^29 - 1 cells, the mesh has " + std::to_string(n));
  HexNeighbours out;
  out.across_.resize(6 * n);  // unset: every entry is written below
  out.vertex_count_ = nv;
  out.fingerprint_ = HexNeighbours::fingerprint(mesh);
  if (n == 0) return out;
  int32_t* const across = out.across_.data();
  // 32-bit keys while no vertex is 2^32 - 1: that id pads a triangle's key.
  bool const narrow = nv < (uint64_t(1) << 32);
  if (mesh.has_32bit_indices() && narrow) detail::match_hex_faces<uint32_t>(mesh.indices32(), n, nv, across);
  else if (mesh.has_32bit_indices()) detail::match_hex_faces<uint64_t>(mesh.indices32(), n, nv, across);
  else if (narrow) detail::match_hex_faces<uint32_t>(mesh.indices64(), n, nv, across);
  else detail::match_hex_faces<uint64_t>(mesh.indices64(), n, nv, across);
  return out;
}

/// Links the face neighbours of a mixed mesh's two parts, tets and
/// hexahedra (wedges and pyramids as collapsed ones) over one vertex array:
/// a tet face on its part's boundary and a wedge's or pyramid's triangle on
/// the other part's boundary over the same three vertices become each
/// other's neighbours, stored as -2 - (the other part's cell) in both (see
/// FaceNeighbours). Cell-segment DVR of a scene of exactly these two parts
/// then marches across both (traverse/march.hpp, MixedMarch), with each
/// cell's own kernel, where it would otherwise clip every cell of both
/// trees' leaves. Links already present are replaced; a face met by more
/// than one cell of either part stays -1. Boundary faces only are read:
/// transient memory 40 bytes per boundary triangle.
/// @throws InvalidArgument when either neighbours were built over another
///         mesh, or the parts do not share their vertex array (ids would
///         not name the same points).
inline void link_face_neighbours(TetMesh const& tets, TetNeighbours& tet_nb, HexMesh const& hexes,
                                 HexNeighbours& hex_nb) {
  if (!tet_nb.fits(tets) || !hex_nb.fits(hexes))
    throw InvalidArgument("link_face_neighbours: face neighbours built over another mesh");
  if (tets.vertex_count() != hexes.vertex_count() || tets.positions() != hexes.positions())
    throw InvalidArgument("link_face_neighbours: the tetrahedral and hexahedral parts must index one vertex array (" +
                          std::to_string(tets.vertex_count()) + " and " + std::to_string(hexes.vertex_count()) +
                          " vertices)");
  struct Triangle {
    uint64_t v[3];  ///< ascending
    uint64_t slot;  ///< faces x cell + face in its part
    bool hex;
    bool operator<(Triangle const& o) const noexcept {
      for (int i = 0; i < 3; ++i)
        if (v[i] != o.v[i]) return v[i] < o.v[i];
      return hex != o.hex ? hex < o.hex : slot < o.slot;  // a total order: the result does not depend on threads
    }
    bool same(Triangle const& o) const noexcept { return v[0] == o.v[0] && v[1] == o.v[1] && v[2] == o.v[2]; }
  };
  // Boundary triangles of both parts, in fixed blocks of cells (the order
  // does not matter: sorted below). Old links are boundary again first.
  int32_t* const ta = tet_nb.across_.data();
  int32_t* const ha = hex_nb.across_.data();
  for (uint64_t i = 0; i < tet_nb.across_.size(); ++i) ta[i] = std::max(ta[i], int32_t(-1));
  for (uint64_t i = 0; i < hex_nb.across_.size(); ++i) ha[i] = std::max(ha[i], int32_t(-1));
  constexpr uint64_t block = uint64_t(1) << 15;
  uint64_t const nt = tets.cell_count(), nh = hexes.cell_count();
  uint64_t const tet_blocks = (nt + block - 1) / block, blocks = tet_blocks + (nh + block - 1) / block;
  std::vector<std::vector<Triangle>> found(blocks);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t b = r.begin(); b < r.end(); ++b) {
      auto& out = found[b];
      if (b < tet_blocks) {
        for (uint64_t c = b * block, e = std::min(nt, c + block); c < e; ++c) {
          if (ta[4 * c] >= 0 && ta[4 * c + 1] >= 0 && ta[4 * c + 2] >= 0 && ta[4 * c + 3] >= 0) continue;
          uint64_t id[4] = {tets.vertex(c, 0), tets.vertex(c, 1), tets.vertex(c, 2), tets.vertex(c, 3)};
          uint64_t v[4];
          detail::sorted_corners(id, v);
          if (v[0] == v[1] || v[1] == v[2] || v[2] == v[3]) continue;  // degenerate: no faces
          for (int f = 0; f < 4; ++f) {
            if (ta[4 * c + uint64_t(f)] >= 0) continue;
            Triangle t{{0, 0, 0}, 4 * c + uint64_t(f), false};  // face f: opposite sorted corner f
            for (int i = 0, k = 0; i < 4; ++i)
              if (i != f) t.v[k++] = v[i];
            out.push_back(t);
          }
        }
      } else {
        uint64_t const hb = b - tet_blocks;
        for (uint64_t c = hb * block, e = std::min(nh, c + block); c < e; ++c) {
          bool open = false;
          for (int f = 0; f < 6; ++f) open = open || ha[6 * c + uint64_t(f)] < 0;
          if (!open) continue;
          uint64_t id[8];
          for (int i = 0; i < 8; ++i) id[i] = hexes.vertex(c, i);
          detail::HexCellFaces<uint64_t> faces;
          faces.read(id, 0);
          for (int f = 0; f < 6; ++f)
            if (faces.distinct[f] == 3 && ha[6 * c + uint64_t(f)] < 0)
              out.push_back(Triangle{{faces.low[f], faces.key[f].v[0], faces.key[f].v[1]}, 6 * c + uint64_t(f), true});
        }
      }
    }
  });
  std::vector<Triangle> all;
  for (auto& f : found) all.insert(all.end(), f.begin(), f.end());
  found.clear();
  tbb::parallel_sort(all.begin(), all.end());  // a total order: the same result on any thread count
  // A run of exactly one tet face and one hexahedron face is a link; a face
  // of one part alone is the boundary; more cells on one face: none is right.
  for (size_t i = 0; i < all.size();) {
    size_t j = i + 1;
    while (j < all.size() && all[j].same(all[i])) ++j;
    if (j - i == 2 && !all[i].hex && all[i + 1].hex) {
      ta[all[i].slot] = -2 - int32_t(all[i + 1].slot / 6);
      ha[all[i + 1].slot] = -2 - int32_t(all[i].slot / 4);
    }
    i = j;
  }
  tet_nb.linked_ = hex_nb.linked_ = true;
  tet_nb.linked_cells_ = nh, tet_nb.linked_fingerprint_ = HexNeighbours::fingerprint(hexes);
  hex_nb.linked_cells_ = nt, hex_nb.linked_fingerprint_ = TetNeighbours::fingerprint(tets);
}

}  // namespace cellray
