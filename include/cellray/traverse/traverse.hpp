#pragma once
// The two traversal skeletons every query uses (Rathke 2015 §5.5):
//   packet: W rays visit one node together with one uniform stack;
//   SPMD:   each lane pops, tests and descends on its own stack.
// Hybrid is packet traversal that hands a subtree reached by fewer than a
// threshold of lanes to SPMD traversal of those lanes, so the vector unit
// stays busy with whatever other work the lanes have. Not in the paper:
// traverse_packets, packet traversal of K packets at once (neighbouring
// pixel blocks' camera rays), whose queries share each node's and leaf's
// scalar work (see there).
//
// A query supplies, for packet traversal:
//   bool node_relevant(float vmin, float vmax)      uniform value-range filter
//   vfloat<A> t_lo(), t_hi()                         per-lane interval to search
//   void leaf(uint64_t first_slot, uint32_t count, vmask<A> lanes)
//   bool done()                                      true: stop early (all answers found)
// and for SPMD:
//   vmask<A> relevant(vfloat<A> vmin, vfloat<A> vmax)
//   void leaf_items(vint<A> slots, vmask<A> lanes)  one item per lane
// ISA units only.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>

#include "packet.hpp"
#include "tree_view.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

inline constexpr int traversal_stack_size = int(MinMaxBvh::max_depth) + 2;

template <class A> inline int popcount(vmask<A> const& m) { return __builtin_popcount(simd::movemask(m)); }

/// The cell ids at item-list `slots` for the lanes in `m` (0 elsewhere).
template <class A> inline vint<A> slot_cells(TreeView const& tree, vint<A> const& slots, vmask<A> const& m) {
  alignas(64) int32_t s[width<A>], cells[width<A>] = {};
  simd::store(s, slots);
  for (uint32_t b = simd::movemask(m); b; b &= b - 1) {
    int const l = __builtin_ctz(b);
    cells[l] = int32_t(uint32_t(tree.item(uint64_t(uint32_t(s[l])))));
  }
  return simd::load<A>(cells);
}

/// Lanes whose [vmin, vmax] overlaps one of the value windows (SPMD node filter).
template <class A>
inline vmask<A> windows_overlap(ValueWindows const& w, vfloat<A> const& vmin, vfloat<A> const& vmax) {
  vmask<A> m = simd::no_lanes<A>();
  for (int k = 0; k < w.count; ++k) m = m || (vmin <= vfloat<A>(w.hi[k]) && vmax >= vfloat<A>(w.lo[k]));
  return m && vmin <= vmax;
}

template <class A, class Query>
void traverse_spmd(TreeView const& tree, RayPacket<A> const& r, vmask<A> active, Query& q, uint32_t root = 0);

/// {f(0), ..., f(K - 1)}: an array of K values that have no default
/// constructor (queries holding references).
template <int K, class F, size_t... I> inline auto make_array(F const& f, std::index_sequence<I...>) {
  return std::array<decltype(f(0)), K>{{f(int(I))...}};
}
template <int K, class F> inline auto make_array(F const& f) {
  return make_array<K>(f, std::make_index_sequence<size_t(K)>());
}

/// Whether every lane of `lanes` in the K packets `r` starts at one point
/// (a camera's packets), kept in `origin` as a broadcast: grouped queries
/// then set up a cell's clip once for all packets (CellOps::
/// shares_window_setup). Packets without lanes are not read.
template <class A, int K>
inline bool one_origin(RayPacket<A> const* r, vmask<A> const (&lanes)[K], Vec3<A>& origin) {
  int first = 0;
  while (first < K && simd::none(lanes[first])) ++first;
  if (first == K) return false;
  alignas(64) float o[3][width<A>];
  simd::store(o[0], r[first].ox), simd::store(o[1], r[first].oy), simd::store(o[2], r[first].oz);
  int const l = __builtin_ctz(simd::movemask(lanes[first]));
  origin = {vfloat<A>(o[0][l]), vfloat<A>(o[1][l]), vfloat<A>(o[2][l])};
  for (int p = first; p < K; ++p)
    if (simd::any(lanes[p]) &&
        !simd::all(!lanes[p] || (r[p].ox == origin.x && r[p].oy == origin.y && r[p].oz == origin.z)))
      return false;
  return true;
}

template <class A, class Query>
void traverse_packet(TreeView const& tree, RayPacket<A> const& r, vmask<A> active, Query& q, uint32_t root = 0,
                     int hybrid_threshold = 0) {
  if (tree.empty() || simd::none(active)) return;
  // A node is tested (value range, then box) when its parent is opened;
  // the stack keeps the lanes that entered it and where they did, so a pop
  // only drops the lanes whose interval has since shrunk past the node
  // (t_hi falls as hits are found) instead of testing the box again.
  struct Entry {
    vfloat<A> t_enter;
    uint32_t node;
    uint32_t lanes;
  };
  Entry stack[traversal_stack_size];
  int sp = 0;
  {
    Node const& node = tree.nodes[root];
    if (!q.node_relevant(tree.ranges[2 * root], tree.ranges[2 * root + 1])) return;
    vfloat<A> tn;
    vmask<A> const m = active && box_hit(r, node.lo, node.hi, q.t_lo(), q.t_hi(), tn);
    if (simd::none(m)) return;
    stack[sp++] = Entry{tn, root, simd::movemask(m)};
  }
  vfloat<A> const slack(1.f + 4.f * std::numeric_limits<float>::epsilon());  // as box_hit's exit
  while (sp > 0) {
    // By reference (no copy of the entry's vector): every read of `e`
    // comes before the pushes below reuse its slot.
    Entry const& e = stack[--sp];
    uint32_t ni = e.node;
    vmask<A> m = simd::mask_from_bits<A>(e.lanes) && e.t_enter <= q.t_hi() * slack;
    if (simd::none(m)) continue;
    // Down the tree without the stack while a child is entered: the nearer
    // child goes on at once (a push and pop of it would be the next step on
    // the dependent chain anyway), the farther one is pushed.
    while (true) {
      Node const& node = tree.nodes[ni];
      if constexpr (!std::is_same_v<A, scalar>) {
        if (hybrid_threshold > 0 && popcount<A>(m) < hybrid_threshold) {
          traverse_spmd<A>(tree, r, m, q, ni);
          break;
        }
      }
      if (node.is_leaf()) {
        q.leaf(node.first_item(), node.item_count(), m);
        if (q.done()) return;
        break;
      }
      uint32_t const li = node.left(), ri = node.right();
      Node const& left = tree.nodes[li];
      Node const& right = tree.nodes[ri];
      vfloat<A> tl(0.f), tr(0.f);
      vmask<A> ml = simd::no_lanes<A>(), mr = ml;
      if (q.node_relevant(tree.ranges[2 * li], tree.ranges[2 * li + 1]))
        ml = m && box_hit(r, left.lo, left.hi, q.t_lo(), q.t_hi(), tl);
      if (q.node_relevant(tree.ranges[2 * ri], tree.ranges[2 * ri + 1]))
        mr = m && box_hit(r, right.lo, right.hi, q.t_lo(), q.t_hi(), tr);
      uint32_t const bl = simd::movemask(ml), br = simd::movemask(mr);
      // The builders cap the depth at MinMaxBvh::max_depth, so the stack holds.
      if (bl && br) {
        // Nearer child first: the one most of the lanes that enter both enter first.
        bool const left_first = popcount<A>(ml && mr && tl <= tr) * 2 >= popcount<A>(ml && mr);
        stack[sp++] = left_first ? Entry{tr, ri, br} : Entry{tl, li, bl};
        ni = left_first ? li : ri;
        m = left_first ? ml : mr;
      } else if (bl) {
        ni = li, m = ml;
      } else if (br) {
        ni = ri, m = mr;
      } else {
        break;
      }
    }
  }
}

/// Packet traversal of K packets at once (neighbouring pixel blocks): each
/// node's value range is tested once and its box once per packet with
/// lanes in it, and a leaf is visited once for all K x W rays, so the
/// scalar work of a node and of a leaf (its cells' corner reads, value
/// ranges and boxes) is paid once where coherent packets would each pay
/// it. The nearer child goes first for the majority of the lanes that enter
/// both (as traverse_packet, over all K packets). Lanes stay masks per
/// packet (`packets`: bit k, packet k has some). A group query supplies
///   bool node_relevant(float vmin, float vmax)
///   vfloat<A> t_lo(int k), t_hi(int k)       packet k's interval
///   void leaf(uint64_t first_slot, uint32_t count, vmask<A> const (&lanes)[K], uint32_t packets)
template <class A, int K, class Group>
void traverse_packets(TreeView const& tree, RayPacket<A> const (&r)[K], vmask<A> const (&active)[K], Group& q) {
  if (tree.empty()) return;
  // Per packet, its lanes that entered the node and where: a pop drops
  // those whose interval has since shrunk past it (see traverse_packet).
  struct Entry {
    vfloat<A> t_enter[K];
    vmask<A> lanes[K];
    uint32_t node;
    uint32_t packets;
  };
  // The lanes of `from` whose rays enter the node's box, per packet.
  auto const enter = [&](Node const& node, vmask<A> const (&from)[K], uint32_t packets, vmask<A> (&in)[K],
                         vfloat<A> (&tn)[K]) {
    uint32_t entered = 0;
    for (int k = 0; k < K; ++k) {
      if (!((packets >> k) & 1u)) continue;
      in[k] = from[k] && box_hit(r[k], node.lo, node.hi, q.t_lo(k), q.t_hi(k), tn[k]);
      if (simd::any(in[k])) entered |= 1u << k;
    }
    return entered;
  };
  Entry stack[traversal_stack_size];
  int sp = 0;
  if (!q.node_relevant(tree.ranges[0], tree.ranges[1])) return;
  {
    uint32_t packets = 0;
    for (int k = 0; k < K; ++k) packets |= uint32_t(simd::any(active[k])) << k;
    Entry& root = stack[0];
    root.node = 0;
    root.packets = enter(tree.nodes[0], active, packets, root.lanes, root.t_enter);
    if (!root.packets) return;
    sp = 1;
  }
  vfloat<A> const slack(1.f + 4.f * std::numeric_limits<float>::epsilon());  // as box_hit's exit
  vmask<A> m[K], ml[K], mr[K];
  vfloat<A> tl[K], tr[K];
  for (int k = 0; k < K; ++k) m[k] = ml[k] = mr[k] = simd::no_lanes<A>(), tl[k] = tr[k] = vfloat<A>(0.f);
  while (sp > 0) {
    Entry const& e = stack[--sp];
    uint32_t ni = e.node;
    uint32_t packets = 0;
    for (int k = 0; k < K; ++k) {
      if (!((e.packets >> k) & 1u)) continue;
      m[k] = e.lanes[k] && e.t_enter[k] <= q.t_hi(k) * slack;
      if (simd::any(m[k])) packets |= 1u << k;
    }
    if (!packets) continue;
    while (true) {
      Node const& node = tree.nodes[ni];
      if (node.is_leaf()) {
        q.leaf(node.first_item(), node.item_count(), m, packets);
        break;
      }
      uint32_t const li = node.left(), ri = node.right();
      uint32_t const pl =
          q.node_relevant(tree.ranges[2 * li], tree.ranges[2 * li + 1]) ? enter(tree.nodes[li], m, packets, ml, tl) : 0;
      uint32_t const pr =
          q.node_relevant(tree.ranges[2 * ri], tree.ranges[2 * ri + 1]) ? enter(tree.nodes[ri], m, packets, mr, tr) : 0;
      if (pl && pr) {
        int both = 0, left_nearer = 0;
        for (int k = 0; k < K; ++k) {
          if (!((pl & pr) >> k & 1u)) continue;
          vmask<A> const b = ml[k] && mr[k];
          both += popcount<A>(b);
          left_nearer += popcount<A>(b && tl[k] <= tr[k]);
        }
        bool const left_first = left_nearer * 2 >= both;
        // The builders cap the depth at MinMaxBvh::max_depth, so the stack holds.
        Entry& far = stack[sp++];
        far.node = left_first ? ri : li;
        far.packets = left_first ? pr : pl;
        for (int k = 0; k < K; ++k) {
          if (!((far.packets >> k) & 1u)) continue;
          far.lanes[k] = left_first ? mr[k] : ml[k];
          far.t_enter[k] = left_first ? tr[k] : tl[k];
        }
        ni = left_first ? li : ri;
        packets = left_first ? pl : pr;
        for (int k = 0; k < K; ++k) m[k] = left_first ? ml[k] : mr[k];
      } else if (pl) {
        ni = li, packets = pl;
        for (int k = 0; k < K; ++k) m[k] = ml[k];
      } else if (pr) {
        ni = ri, packets = pr;
        for (int k = 0; k < K; ++k) m[k] = mr[k];
      } else {
        break;
      }
    }
  }
}

template <class A, class Query>
void traverse_spmd(TreeView const& tree, RayPacket<A> const& r, vmask<A> active, Query& q, uint32_t root) {
  constexpr int W = width<A>;
  if (tree.empty() || simd::none(active)) return;
  // Lane-interleaved stacks (entry k of lane l at stack[k][l]): the pops of
  // all lanes are one gather, and the stack depths one vector.
  alignas(64) int32_t stack[traversal_stack_size][W];
  for (int l = 0; l < W; ++l) stack[0][l] = int32_t(root);
  int32_t const* stack0 = &stack[0][0];
  vint<A> sp = simd::select(simd::to_int_mask(active), vint<A>(1), vint<A>(0));
  vint<A> const lane = simd::lane_index<A>();
  float const* nf = reinterpret_cast<float const*>(tree.nodes);
  int32_t const* ni32 = reinterpret_cast<int32_t const*>(tree.nodes);
  vfloat<A> const dir[3] = {r.dx, r.dy, r.dz};
  while (true) {
    vmaski<A> const has_i = sp > vint<A>(0);
    vmask<A> const has = simd::to_float_mask(has_i);
    if (simd::none(has)) break;
    sp = simd::select(has_i, sp - vint<A>(1), sp);
    vint<A> const node = simd::gather(stack0, simd::select(has_i, sp * vint<A>(W) + lane, vint<A>(0)));
    vint<A> const off = node * vint<A>(8);  // 8 words per node
    vfloat<A> const lo[3] = {simd::gather(nf, off), simd::gather(nf + 1, off), simd::gather(nf + 2, off)};
    vfloat<A> const hi[3] = {simd::gather(nf + 4, off), simd::gather(nf + 5, off), simd::gather(nf + 6, off)};
    vint<A> const first = simd::gather(ni32 + 3, off);
    vint<A> const raw_count = simd::gather(ni32 + 7, off);  // all bits set: inner node
    vint<A> const r2 = node * vint<A>(2);
    vfloat<A> tn;
    vmask<A> const m = has &&
                       q.relevant(simd::gather(tree.ranges, r2), simd::gather(tree.ranges + 1, r2)) &&
                       box_hit_varying(r, lo, hi, q.t_lo(), q.t_hi(), tn);
    vmask<A> const is_inner = simd::to_float_mask(raw_count == vint<A>(-1));
    vmask<A> const descend = m && is_inner;
    if (simd::any(descend)) {
      vmaski<A> const descend_i = simd::to_int_mask(descend);
      vint<A> const c0 = first;
      vint<A> const offa = simd::select(descend_i, c0 * vint<A>(8), vint<A>(0)), offb = offa + vint<A>(8);
      // Near child by the lane's direction along the axis that separates
      // the children's centres most (no second box test per lane).
      vfloat<A> best(-1.f), along(0.f);
      for (int k = 0; k < 3; ++k) {
        vfloat<A> const sep = (simd::gather(nf + k, offb) + simd::gather(nf + 4 + k, offb)) -
                              (simd::gather(nf + k, offa) + simd::gather(nf + 4 + k, offa));
        vmask<A> const wider = simd::abs(sep) > best;
        best = simd::select(wider, simd::abs(sep), best);
        along = simd::select(wider, sep * dir[k], along);
      }
      vmaski<A> const a_first = simd::to_int_mask(along >= vfloat<A>(0.f));
      alignas(64) int32_t nearc[W], farc[W], depth[W];
      simd::store(nearc, simd::select(a_first, c0, c0 + vint<A>(1)));
      simd::store(farc, simd::select(a_first, c0 + vint<A>(1), c0));
      simd::store(depth, sp);
      for (uint32_t ib = simd::movemask(descend); ib; ib &= ib - 1) {
        int const l = __builtin_ctz(ib);
        stack[depth[l]][l] = farc[l];
        stack[depth[l] + 1][l] = nearc[l];
      }
      sp = simd::select(descend_i, sp + vint<A>(2), sp);
    }
    vmask<A> const leaf = m && !is_inner;
    if (simd::none(leaf)) continue;
    vint<A> const count = simd::select(simd::to_int_mask(leaf), raw_count & vint<A>(0xFF), vint<A>(0));
    auto const counts = simd::to_array<A>(count);
    int const kmax = *std::max_element(counts.begin(), counts.end());
    for (int k = 0; k < kmax; ++k) {
      vmask<A> const mk = leaf && simd::to_float_mask(vint<A>(k) < count);
      q.leaf_items(first + vint<A>(k), mk);
    }
    if (q.done()) return;
  }
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
