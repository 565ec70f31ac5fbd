#pragma once
// An optional, caller-owned companion of one MinMaxBvh for fast time-step
// refits: per leaf, the distinct vertex ids of its cells. A refit through
// the plan reads each vertex value once per leaf, in leaf order, instead of
// every corner of every cell plus a per-cell range array read at random by
// item id (what `refit_ranges` without a plan does).

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "build.hpp"
#include "refit.hpp"

namespace cellray {

class RefitPlan;

namespace detail {
struct RefitPlanAccess;
}

/// Per leaf of one MinMaxBvh, the sorted distinct vertex ids of the cells in
/// that leaf (global ids: piece p's vertex v is `vertex_offsets()[p] + v`).
/// Made by `make_refit_plan(bvh, mesh or pieces)`; used by
/// `refit_ranges(bvh, plan, mesh or pieces, out)`, which gives bit for bit
/// the ranges of the plain refit (and of a rebuild). It describes the tree's
/// leaves and the meshes' connectivity: a new tree or new cell indices need a
/// new plan (the refit checks node, cell and vertex counts, not the indices).
/// Owns its arrays (`bytes()`: 4 B per stored vertex id, per leaf and per
/// node; about 8.4 B per tet and 21 B per hex with the default leaf size,
/// as vertices shared inside a leaf are stored once); immutable, safe to read
/// from any number of threads. A default-constructed plan is empty and
/// matches no tree.
///
/// Layout, chosen so the refit runs without data-dependent branches:
///   ids()       the leaves' vertex ids one leaf after the other, leaves in
///               node order, each leaf padded to whole chunks of 4 by
///               repeating its last id; bit 31 marks the last id of a leaf's
///               last chunk, bits [0,31) the vertex
///   leaf_node() per leaf in that order, its node index
///   child()     per node: the left child of an inner node, the node itself
///               for a leaf (so "range = union of child(i) and the node
///               after it, or itself" needs no branch)
///   block_begin() the first id of every `leaf_block`-th leaf (parallel blocks)
class RefitPlan {
 public:
  /// Leaves per parallel block of the refit.
  static constexpr uint64_t leaf_block = 2048;
  /// Bit of an entry of ids() that marks the last id of a leaf.
  static constexpr uint32_t last_bit = 0x80000000u;

  RefitPlan() = default;

  /// True for a default-constructed plan (made for no tree).
  bool empty() const noexcept { return child_.empty(); }
  /// Nodes of the tree it was made for.
  uint64_t node_count() const noexcept { return child_.size(); }
  uint64_t leaf_count() const noexcept { return leaf_node_.size(); }
  /// Vertex ids over all leaves (a vertex shared by k leaves counts k times).
  uint64_t id_count() const noexcept { return ids_.size(); }
  uint32_t const* ids() const noexcept { return ids_.data(); }
  uint32_t const* leaf_node() const noexcept { return leaf_node_.data(); }
  uint32_t const* child() const noexcept { return child_.data(); }
  /// block_begin()[b] = first id of leaf b * leaf_block; one extra entry = id_count().
  uint64_t const* block_begin() const noexcept { return block_begin_.data(); }
  /// Piece p's vertices are global ids [vertex_offsets()[p], vertex_offsets()[p + 1]).
  std::vector<uint64_t> const& vertex_offsets() const noexcept { return vertex_offsets_; }
  /// Bytes the plan owns.
  uint64_t bytes() const noexcept {
    return (ids_.size() + leaf_node_.size() + child_.size()) * sizeof(uint32_t) +
           (block_begin_.size() + vertex_offsets_.size() + cell_offsets_.size()) * sizeof(uint64_t);
  }

 private:
  friend struct detail::RefitPlanAccess;

  std::vector<uint32_t> ids_;
  std::vector<uint32_t> leaf_node_;
  std::vector<uint32_t> child_;
  std::vector<uint64_t> block_begin_;
  std::vector<uint64_t> vertex_offsets_;  ///< per piece, first global vertex id; last = total
  std::vector<uint64_t> cell_offsets_;    ///< the tree's piece table when the plan was made
};

namespace detail {

struct RefitPlanAccess {
  static std::vector<uint32_t>& ids(RefitPlan& p) { return p.ids_; }
  static std::vector<uint32_t>& leaf_node(RefitPlan& p) { return p.leaf_node_; }
  static std::vector<uint32_t>& child(RefitPlan& p) { return p.child_; }
  static std::vector<uint64_t>& block_begin(RefitPlan& p) { return p.block_begin_; }
  static std::vector<uint64_t>& vertex_offsets(RefitPlan& p) { return p.vertex_offsets_; }
  static std::vector<uint64_t>& cell_offsets(RefitPlan& p) { return p.cell_offsets_; }
  static std::vector<uint64_t> const& cell_offsets(RefitPlan const& p) { return p.cell_offsets_; }
};

inline uint64_t piece_vertex_count(MeshPiece const& p) { return p.vertex_count(); }

/// Calls f(global vertex id) for every corner of item `id` (piece offsets
/// applied). Throws InvalidMesh for a vertex id out of its piece's range.
template <class F>
void for_corners(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces, std::vector<uint64_t> const& voff,
                 uint64_t id, F const& f) {
  PieceCell const pc = pieces.size() == 1 ? PieceCell{0, id} : bvh.locate(id);
  pieces[pc.piece].visit([&](auto const& mesh) {
    constexpr int corners = std::remove_reference_t<decltype(mesh)>::corners;
    for (int k = 0; k < corners; ++k) {
      uint64_t const v = mesh.vertex(pc.cell, k);
      if (v >= mesh.vertex_count())
        throw InvalidMesh("piece " + std::to_string(pc.piece) + " cell " + std::to_string(pc.cell) + " corner " +
                          std::to_string(k) + " names vertex " + std::to_string(v) + " but the mesh has " +
                          std::to_string(mesh.vertex_count()) + " vertices");
      f(voff[pc.piece] + v);
    }
  });
}

/// The plan's vertex table for `pieces`, or a throw when the ids do not fit 31 bits.
inline std::vector<uint64_t> plan_vertex_offsets(std::vector<MeshPiece> const& pieces) {
  std::vector<uint64_t> voff{0};
  for (auto const& p : pieces) voff.push_back(voff.back() + piece_vertex_count(p));
  if (voff.back() >= uint64_t(RefitPlan::last_bit))
    throw InvalidArgument("refit plan: " + std::to_string(voff.back()) +
                          " vertices over all pieces do not fit 31-bit ids; refit without a plan");
  return voff;
}

inline void check_plan(MinMaxBvh const& bvh, RefitPlan const& plan, std::vector<MeshPiece> const& pieces) {
  check_refit_pieces(bvh, pieces);
  if (plan.node_count() != bvh.node_count() || RefitPlanAccess::cell_offsets(plan) != bvh.piece_offsets())
    throw InvalidArgument("refit plan made for a tree of " + std::to_string(plan.node_count()) +
                          " nodes, given a tree of " + std::to_string(bvh.node_count()));
  auto const& voff = plan.vertex_offsets();
  for (size_t p = 0; p < pieces.size(); ++p)
    if (piece_vertex_count(pieces[p]) != voff[p + 1] - voff[p])
      throw InvalidArgument("refit plan: piece " + std::to_string(p) + " has " +
                            std::to_string(piece_vertex_count(pieces[p])) + " vertices, the plan was made for " +
                            std::to_string(voff[p + 1] - voff[p]));
}

inline RefitPlan make_plan(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces) {
  check_refit_pieces(bvh, pieces);
  RefitPlan plan;
  RefitPlanAccess::vertex_offsets(plan) = plan_vertex_offsets(pieces);
  RefitPlanAccess::cell_offsets(plan) = bvh.piece_offsets();
  auto const& voff = plan.vertex_offsets();
  uint64_t const nodes = bvh.node_count(), n = bvh.item_count();
  auto& child = RefitPlanAccess::child(plan);
  child.resize(nodes);
  uint64_t corners = 4;
  for (auto const& p : pieces)
    corners = std::max<uint64_t>(corners, p.visit([](auto const& mesh) {
      return uint64_t(std::remove_reference_t<decltype(mesh)>::corners);
    }));
  // Pass 1, per node: child(); for a leaf its sorted distinct ids into its
  // own region of a scratch array (slot s owns [s * corners, (s + 1) *
  // corners)), their count and the node at its first slot.
  std::unique_ptr<uint32_t[]> scratch(new uint32_t[std::max<uint64_t>(1, n * corners)]);
  std::vector<uint32_t> count_at(nodes, 0);
  constexpr uint64_t block = 4096;
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nodes, block), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t i = r.begin(); i < r.end(); ++i) {
      Node const& nd = bvh.node(i);
      child[i] = nd.is_leaf() ? uint32_t(i) : nd.left();
      if (!nd.is_leaf() || nd.item_count() == 0) continue;
      uint64_t const first = nd.first_item();
      uint32_t* out = scratch.get() + first * corners;
      uint32_t m = 0;
      for (uint64_t s = first; s < first + nd.item_count(); ++s)
        for_corners(bvh, pieces, voff, bvh.item(s), [&](uint64_t v64) {
          auto const v = uint32_t(v64);
          uint32_t j = m;  // insertion into the sorted distinct ids so far
          while (j > 0 && out[j - 1] > v) --j;
          if (j > 0 && out[j - 1] == v) return;
          std::copy_backward(out + j, out + m, out + m + 1);
          out[j] = v;
          ++m;
        });
      count_at[i] = m;
    }
  });
  // Leaves in slot order; their first ids (a leaf has at least one id).
  auto& leaf_node = RefitPlanAccess::leaf_node(plan);
  std::vector<uint64_t> leaf_first;  // first slot of each leaf
  std::vector<uint64_t> id_begin;    // first id of each leaf
  uint64_t total = 0;
  for (uint64_t i = 0; i < nodes; ++i)
    if (count_at[i] != 0) {
      leaf_node.push_back(uint32_t(i));
      leaf_first.push_back(bvh.node(i).first_item());
      id_begin.push_back(total);
      total += (count_at[i] + 3) & ~uint64_t(3);  // padded to whole chunks of 4
    }
  auto& block_begin = RefitPlanAccess::block_begin(plan);
  for (uint64_t l = 0; l < leaf_node.size(); l += RefitPlan::leaf_block) block_begin.push_back(id_begin[l]);
  block_begin.push_back(total);
  auto& ids = RefitPlanAccess::ids(plan);
  ids.resize(total);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, leaf_node.size(), block), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t l = r.begin(); l < r.end(); ++l) {
      uint32_t const* in = scratch.get() + leaf_first[l] * corners;
      uint32_t const m = count_at[leaf_node[l]], padded = (m + 3) & ~3u;
      uint32_t* out = ids.data() + id_begin[l];
      std::copy(in, in + m, out);
      std::fill(out + m, out + padded, in[m - 1]);  // a repeated id changes no min or max
      out[padded - 1] |= RefitPlan::last_bit;
    }
  });
  return plan;
}

/// Range of a leaf whose distinct vertices include a NaN or +-inf value: per cell, so
/// a NaN cell drops out without dropping its neighbours' shared vertices.
inline NodeRange leaf_range_per_cell(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces,
                                     std::vector<uint64_t> const& voff, float const* values, Node const& n) {
  NodeRange r{inf_f, -inf_f};
  uint64_t const first = n.first_item();
  for (uint64_t s = first; s < first + n.item_count(); ++s) {
    NodeRange c{inf_f, -inf_f};
    bool nan = false;
    for_corners(bvh, pieces, voff, bvh.item(s), [&](uint64_t v) {
      float const x = values[v];
      nan = nan || !std::isfinite(x);
      c.vmin = std::min(c.vmin, x);
      c.vmax = std::max(c.vmax, x);
    });
    if (nan) continue;
    r.vmin = std::min(r.vmin, c.vmin);
    r.vmax = std::max(r.vmax, c.vmax);
  }
  return r;
}

/// Leaves per parallel task of the refit: `refit_streams` blocks.
inline constexpr int refit_streams = 2;

/// Leaf ranges of the leaves of blocks [b, e), e - b <= refit_streams, into
/// `ranges` (at their nodes). A leaf's ids come in chunks of 4 (padded by
/// repeating one), the last chunk's fourth id carrying the last bit. Every
/// chunk updates the running 4-lane minimum and maximum of its block, which
/// are stored for the current leaf on every chunk (the final store wins) and
/// reset to empty after a leaf's last chunk, so nothing branches on the
/// data; the blocks advance side by side so their dependency chains overlap.
/// Each leaf's 4 lanes are then reduced into `ranges`. Returns bit s set
/// when block b + s read a NaN or +-inf value.
inline uint32_t fit_leaf_blocks(RefitPlan const& plan, float const* values, uint64_t b, uint64_t e,
                                NodeRange* ranges) {
  constexpr int streams = refit_streams;
  constexpr uint64_t lb = RefitPlan::leaf_block;
  uint32_t const* ids = plan.ids();
  int const live = int(e - b);
  uint64_t k[streams], end[streams], leaf[streams];
  for (int s = 0; s < streams; ++s) {
    uint64_t const q = b + uint64_t(std::min(s, live - 1));  // idle streams repeat the last block, empty
    k[s] = plan.block_begin()[q];
    end[s] = s < live ? plan.block_begin()[q + 1] : k[s];
    leaf[s] = 0;
  }
  // Per stream and leaf: 4 lanes of minima, then 4 of maxima.
  std::unique_ptr<float[]> lanes(new float[streams * lb * 8]);
  uint32_t nan_blocks = 0;
#if defined(__SSE2__)
  __m128 const empty_lo = _mm_set1_ps(inf_f), empty_hi = _mm_set1_ps(-inf_f);
  __m128 lo[streams], hi[streams], nan[streams];
  for (int s = 0; s < streams; ++s) lo[s] = empty_lo, hi[s] = empty_hi, nan[s] = _mm_setzero_ps();
  auto step = [&](int s) {
    uint32_t const* q = ids + k[s];
    k[s] += 4;
    uint32_t const r3 = q[3];
    __m128 const x01 = _mm_unpacklo_ps(_mm_load_ss(values + q[0]), _mm_load_ss(values + q[1]));
    __m128 const x23 = _mm_unpacklo_ps(_mm_load_ss(values + q[2]), _mm_load_ss(values + (r3 & ~RefitPlan::last_bit)));
    __m128 const x = _mm_movelh_ps(x01, x23);
    __m128 const zero_if_finite = _mm_sub_ps(x, x);  // NaN for NaN and +-inf
    nan[s] = _mm_or_ps(nan[s], _mm_cmpunord_ps(zero_if_finite, zero_if_finite));
    lo[s] = _mm_min_ps(x, lo[s]);  // a NaN x keeps the accumulator (minps takes the second)
    hi[s] = _mm_max_ps(x, hi[s]);
    float* out = lanes.get() + (uint64_t(s) * lb + leaf[s]) * 8;
    _mm_storeu_ps(out, lo[s]);
    _mm_storeu_ps(out + 4, hi[s]);
    uint32_t const last = r3 >> 31;
    leaf[s] += last;
    __m128 const reset = _mm_castsi128_ps(_mm_set1_epi32(-int32_t(last)));
    lo[s] = _mm_or_ps(_mm_andnot_ps(reset, lo[s]), _mm_and_ps(reset, empty_lo));
    hi[s] = _mm_or_ps(_mm_andnot_ps(reset, hi[s]), _mm_and_ps(reset, empty_hi));
  };
#else
  float lo[streams][4], hi[streams][4];
  bool nan[streams];
  for (int s = 0; s < streams; ++s) {
    std::fill(lo[s], lo[s] + 4, inf_f), std::fill(hi[s], hi[s] + 4, -inf_f);
    nan[s] = false;
  }
  auto step = [&](int s) {
    uint32_t const* q = ids + k[s];
    k[s] += 4;
    float* out = lanes.get() + (uint64_t(s) * lb + leaf[s]) * 8;
    for (int l = 0; l < 4; ++l) {
      float const x = values[q[l] & ~RefitPlan::last_bit];
      nan[s] = nan[s] || !std::isfinite(x);
      lo[s][l] = x < lo[s][l] ? x : lo[s][l];
      hi[s][l] = x > hi[s][l] ? x : hi[s][l];
      out[l] = lo[s][l], out[4 + l] = hi[s][l];
    }
    uint32_t const last = q[3] >> 31;
    leaf[s] += last;
    if (last) std::fill(lo[s], lo[s] + 4, inf_f), std::fill(hi[s], hi[s] + 4, -inf_f);
  };
#endif
  uint64_t common = end[0] - k[0];
  for (int s = 1; s < streams; ++s) common = std::min(common, end[s] - k[s]);
  for (uint64_t j = 0; j < common; j += 4)
    for (int s = 0; s < streams; ++s) step(s);
  for (int s = 0; s < streams; ++s)
    while (k[s] < end[s]) step(s);
  for (int s = 0; s < live; ++s) {
#if defined(__SSE2__)
    bool const any_nan = _mm_movemask_ps(nan[s]) != 0;
#else
    bool const any_nan = nan[s];
#endif
    if (any_nan) nan_blocks |= 1u << s;
    uint32_t const* leaf_node = plan.leaf_node() + (b + uint64_t(s)) * lb;
    float const* in = lanes.get() + uint64_t(s) * lb * 8;
    for (uint64_t l = 0; l < leaf[s]; ++l, in += 8)
      ranges[leaf_node[l]] = {std::min(std::min(in[0], in[1]), std::min(in[2], in[3])),
                              std::max(std::max(in[4], in[5]), std::max(in[6], in[7]))};
  }
  return nan_blocks;
}

/// Redoes the leaves of block `b` that read a NaN value, per cell.
inline void fix_nan_leaves(MinMaxBvh const& bvh, RefitPlan const& plan, std::vector<MeshPiece> const& pieces,
                           float const* values, uint64_t b, NodeRange* ranges) {
  uint32_t const* ids = plan.ids();
  uint32_t const* leaf_node = plan.leaf_node() + b * RefitPlan::leaf_block;
  uint64_t const ke = plan.block_begin()[b + 1];
  bool nan = false;
  uint64_t leaf = 0;
  for (uint64_t k = plan.block_begin()[b]; k < ke; ++k) {
    float const x = values[ids[k] & ~RefitPlan::last_bit];
    nan = nan || !std::isfinite(x);
    if (ids[k] & RefitPlan::last_bit) {
      if (nan) {
        uint32_t const node = leaf_node[leaf];
        ranges[node] = leaf_range_per_cell(bvh, pieces, plan.vertex_offsets(), values, bvh.node(node));
      }
      nan = false;
      ++leaf;
    }
  }
}

/// Inner ranges of node `i`'s subtree from its leaves' (already set): as
/// fit_ranges, but the sweep reads the plan's child() (4 B per node, no
/// branch: a leaf is the union of itself) instead of the 32-B nodes.
inline void fit_inner_ranges(Node const* nodes, uint32_t const* child, NodeRange* ranges, uint64_t i, uint32_t depth) {
  Node const& n = nodes[i];
  if (n.is_leaf()) return;
  if (depth < parallel_fit_depth) {
    tbb::parallel_invoke([&] { fit_inner_ranges(nodes, child, ranges, n.left(), depth + 1); },
                         [&] { fit_inner_ranges(nodes, child, ranges, n.right(), depth + 1); });
  } else {
    for (uint64_t k = subtree_end(nodes, i); k-- > n.left();) {
      uint64_t const l = child[k], r = l + uint64_t(l != k);
      ranges[k] = {std::min(ranges[l].vmin, ranges[r].vmin), std::max(ranges[l].vmax, ranges[r].vmax)};
    }
  }
  uint64_t const l = n.left(), r = n.right();
  ranges[i] = {std::min(ranges[l].vmin, ranges[r].vmin), std::max(ranges[l].vmax, ranges[r].vmax)};
}

inline void refit_with_plan(MinMaxBvh const& bvh, RefitPlan const& plan, std::vector<MeshPiece> const& pieces,
                            ValueRanges& out) {
  check_plan(bvh, plan, pieces);
  uint64_t const nodes = bvh.node_count();
  out.resize(nodes);
  auto const& voff = plan.vertex_offsets();
  // One value array over all pieces' vertices (global ids); a piece without
  // values reads NaN, so its cells get the empty range like a NaN cell.
  float const* values = nullptr;
  std::unique_ptr<float[]> joined;
  if (pieces.size() == 1) {
    values = pieces[0].visit([](auto const& mesh) { return mesh.values(); });
  } else {
    joined.reset(new float[std::max<uint64_t>(1, voff.back())]);
    for (size_t p = 0; p < pieces.size(); ++p)
      pieces[p].visit([&](auto const& mesh) {
        float const* v = mesh.values();
        float* to = joined.get() + voff[p];
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, mesh.vertex_count(), scan_block),
                          [&](tbb::blocked_range<uint64_t> const& r) {
                            if (v) std::copy(v + r.begin(), v + r.end(), to + r.begin());
                            else std::fill(to + r.begin(), to + r.end(), std::numeric_limits<float>::quiet_NaN());
                          });
      });
    values = joined.get();
  }
  NodeRange* ranges = out.data();
  if (values == nullptr || bvh.empty()) {  // geometry only: every range empty
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nodes, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
      std::fill(ranges + r.begin(), ranges + r.end(), NodeRange{inf_f, -inf_f});
    });
    return;
  }
  uint64_t const blocks = (plan.leaf_count() + RefitPlan::leaf_block - 1) / RefitPlan::leaf_block;
  uint64_t const groups = (blocks + refit_streams - 1) / refit_streams;
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, groups, 1), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t g = r.begin(); g < r.end(); ++g) {
      uint64_t const b = g * refit_streams, e = std::min(blocks, b + refit_streams);
      uint32_t const nan_blocks = fit_leaf_blocks(plan, values, b, e, ranges);
      for (uint64_t q = b; q < e; ++q)
        if (nan_blocks >> (q - b) & 1u) fix_nan_leaves(bvh, plan, pieces, values, q, ranges);
    }
  });
  fit_inner_ranges(bvh.nodes(), plan.child(), ranges, 0, 0);
}

}  // namespace detail

/// Makes the refit plan of `bvh` over `pieces` (the meshes it was built
/// from, or any with the same cell counts and connectivity). Parallel;
/// O(cells x corners); deterministic. Worth it when a tree serves several
/// time steps: 1M generated tets (morton tree, 1 thread; the plain refit's
/// cell pass on AVX-512) refit in about 3 ms through a plan of 8.4 B/cell
/// against about 10 ms without, 1M hexes in about 7 ms (21 B/cell) against
/// about 15 ms; making a plan costs about 9 plain refits.
/// @throws InvalidArgument when the pieces or cell counts differ from the
///         build, or the pieces have 2^31 vertices or more in all (refit
///         without a plan then); InvalidMesh for a vertex id out of range.
inline RefitPlan make_refit_plan(MinMaxBvh const& bvh, std::vector<MeshPiece> const& pieces) {
  return detail::make_plan(bvh, pieces);
}
template <int N> RefitPlan make_refit_plan(MinMaxBvh const& bvh, CellMesh<N> const& mesh) {
  return detail::make_plan(bvh, {MeshPiece(mesh)});
}

/// `refit_ranges(bvh, pieces, out)` through a plan: the same ranges, bit for
/// bit (min/max are exact, and a leaf with a NaN vertex value is refit per
/// cell so only the NaN cells drop out), from each leaf's distinct vertices.
/// `pieces` have the connectivity the plan was made with; only their active
/// arrays may differ. Parallel; `out` is resized and its memory reused.
/// @throws InvalidArgument when the plan was made for another tree or the
///         pieces' cell or vertex counts differ from the plan's.
inline void refit_ranges(MinMaxBvh const& bvh, RefitPlan const& plan, std::vector<MeshPiece> const& pieces,
                         ValueRanges& out) {
  detail::refit_with_plan(bvh, plan, pieces, out);
}
template <int N>
void refit_ranges(MinMaxBvh const& bvh, RefitPlan const& plan, CellMesh<N> const& mesh, ValueRanges& out) {
  detail::refit_with_plan(bvh, plan, {MeshPiece(mesh)}, out);
}

}  // namespace cellray
