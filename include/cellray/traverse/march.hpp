#pragma once
// Marching rays from cell to cell through face neighbours (mesh/neighbours.hpp),
// one ray per lane: cell-segment DVR (CellMarch: tets, and hexahedra with the
// wedges and pyramids read as collapsed ones) and the occlusion of short
// rays that start in known cells (march_occluded, ambient occlusion). Not in
// the paper. ISA units only.
//
// A packet traversal clips every cell of every leaf the packet reaches; on a
// fine tet mesh most lanes miss most of those cells (component8: 18% of the
// clip lanes hit). A march clips one cell per lane per step, the one the
// ray is in, and moves each lane across the face it leaves through. The BVH
// still finds where a march starts: the first visible cell past t for the
// lanes that have none (at the start, after leaving the mesh through a
// boundary face, after `max_faint` cells in a row with no visible segment,
// where the min-max tree skips empty space faster than a march, and where a
// step makes no progress: a ray through an edge or vertex may leave into a
// cell that does not contain its continuation).
//
// The segments are the packet clip's up to rounding (CellOps::
// march_clip_window: the same kernel, but for parallelepipeds, which a
// march clips as slabs in the cell's own coordinates, not face by face; and
// a tet after the first, which it clips onward from the face it entered by,
// CellOps::march_clip_onward), so a march integrates what a traversal
// would, cell for cell. A march goes on
// from where the last cell ended (a piece starts at max(t_in, t)), so faces
// seen from two sides need not agree bit for bit; the locate clips with the
// march's clip, so a located cell always lets its lane progress. A hex
// clip's exit face is the face of the crossing at its t_out: near an edge
// that may be the wrong one of two, and the neighbour across it then makes
// no progress, which sends the lane back to the tree (as for a tet ray
// through an edge).

#include <algorithm>
#include <cstdint>
#include <limits>

#include "../mesh/neighbours.hpp"
#include "cell_ops.hpp"
#include "traverse.hpp"
#include "tree_view.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

/// Lanes whose cell may have opacity on the ray: a field linear along it
/// (CellOps::linear_on_ray, or a folded tet's clip: Clip::linear) is
/// bounded by its end values; any other by the corner values (the shape
/// functions are a convex combination).
template <class A, int N>
inline vmask<A> visible_values(ValueWindows const& w, CellCorners<A, N> const& c,
                               typename CellOps<A, N>::Clip const& k) {
  if constexpr (CellOps<A, N>::linear_on_ray)
    return windows_overlap<A>(w, simd::min(k.s_in, k.s_out), simd::max(k.s_in, k.s_out));
  vfloat<A> vmin = c.s[0], vmax = c.s[0];
  for (int i = 1; i < N; ++i) vmin = simd::min(vmin, c.s[i]), vmax = simd::max(vmax, c.s[i]);
  if constexpr (CellOps<A, N>::holds_folded_tets) {
    vmin = simd::select(k.linear, simd::min(k.s_in, k.s_out), vmin);
    vmax = simd::select(k.linear, simd::max(k.s_in, k.s_out), vmax);
  }
  return windows_overlap<A>(w, vmin, vmax);
}

/// Traverses `tree` with query q for the lanes of `ask`, as `how` says.
template <class A, class Q>
inline void traverse_query(TreeView const& tree, RayPacket<A> const& r, vmask<A> const& ask, Q& q, Traversal how,
                           int threshold) {
  switch (how) {
    case Traversal::packet: traverse_packet<A>(tree, r, ask, q); break;
    case Traversal::hybrid: traverse_packet<A>(tree, r, ask, q, 0, threshold); break;
    case Traversal::spmd: traverse_spmd<A>(tree, r, ask, q); break;
  }
}

/// Per lane, the visible cell the ray is in or enters first after `lo`: the
/// smallest t_in of the cells whose clip interval ends past lo (strictly, so
/// a march from it progresses) and starts by `hi`, with no NaN corner value
/// and field values along the ray that meet a value window, other than
/// `skip` (the cell the lane has just left, or -1). -1: none.
template <class A, int N> struct FirstCellQuery {
  TreeView const* tree_;
  CellMesh<N> const* mesh_;
  RayPacket<A> const& r;
  ValueWindows const& windows;
  vfloat<A> lo, hi;
  vint<A> skip;
  vfloat<A> best_t = vfloat<A>(std::numeric_limits<float>::infinity());  ///< t_in of `cell`
  vint<A> cell = vint<A>(-1);

  FirstCellQuery(TreeView const& t, CellMesh<N> const& m, RayPacket<A> const& rays, ValueWindows const& w,
                 vfloat<A> const& t_lo, vfloat<A> const& t_hi, vint<A> const& skip_cell = vint<A>(-1))
      : tree_(&t), mesh_(&m), r(rays), windows(w), lo(t_lo), hi(t_hi), skip(skip_cell) {}
  TreeView const& tree() const { return *tree_; }

  bool done() const { return false; }
  bool node_relevant(float vmin, float vmax) const { return vmin <= vmax && windows.overlaps(vmin, vmax); }
  vmask<A> relevant(vfloat<A> const& vmin, vfloat<A> const& vmax) const { return windows_overlap<A>(windows, vmin, vmax); }
  vfloat<A> t_lo() const { return lo; }
  vfloat<A> t_hi() const { return simd::min(hi, best_t); }  // a cell entered past the best cannot be better

  void visit(CellCorners<A, N> const& c, vmask<A> const& m, vint<A> const& cells) {
    visit_clipped(c, CellOps<A, N>::march_clip_window(ray_batch(r), c, m, lo, t_hi(), nullptr), cells);
  }
  /// visit with the cell's march clip `k` to [lo, t_hi()] for its lanes.
  void visit_clipped(CellCorners<A, N> const& c, typename CellOps<A, N>::Clip const& k, vint<A> const& cells) {
    vmask<A> ok = k.hit && k.t_out > lo && k.t_in < best_t && !has_nan_value(c) && simd::to_float_mask(!(cells == skip));
    if (simd::none(ok)) return;
    ok = ok && visible_values<A, N>(windows, c, k);
    best_t = simd::select(ok, k.t_in, best_t);
    cell = simd::select(simd::to_int_mask(ok), cells, cell);
  }
  void leaf(uint64_t first, uint32_t n, vmask<A> const& m) {  // as SegmentQuery::leaf
    for_each_leaf_cell<A, N>(
        *tree_, *mesh_, r, first, n, m, lo, [this](float vmin, float vmax) { return windows.overlaps(vmin, vmax); },
        [this] { return t_hi(); },
        [this](CellCorners<A, N> const& c, vmask<A> const& in_box, uint64_t, uint64_t id) {
          visit(c, in_box, vint<A>(int32_t(id)));
        });
  }
  void leaf_items(vint<A> const& slots, vmask<A> const& m) {
    vint<A> const cv = slot_cells<A>(*tree_, slots, m);
    visit(gather_corners<A, N>(*mesh_, cv, m), m, cv);
  }
};

/// K first-cell queries, one per packet, traversed together
/// (traverse_packets): a leaf's cells are read, filtered by value and boxed
/// once for all packets; each packet with lanes in a cell's box clips it
/// for those lanes, as FirstCellQuery::leaf does, so each finds the cells
/// it would alone (packets from one origin from one clip setup per cell,
/// where the type's march clips as its window clip: tets).
template <class A, int N, int K> struct FirstCellGroup {
  FirstCellQuery<A, N>* q;  ///< K queries, packet k's in q[k]
  RayPacket<A> const* r;    ///< the K packets
  /// The packets' one origin, if they have one (one_origin): cells that can
  /// share their clip setup (CellOps::shares_window_setup) set it up once.
  Vec3<A> origin{};
  bool shared_origin;

  FirstCellGroup(FirstCellQuery<A, N>* queries, RayPacket<A> const* rays, vmask<A> const (&lanes)[K])
      : q(queries), r(rays), shared_origin(one_origin<A, K>(rays, lanes, origin)) {}

  bool node_relevant(float vmin, float vmax) const { return q[0].node_relevant(vmin, vmax); }
  vfloat<A> t_lo(int k) const { return q[k].t_lo(); }
  vfloat<A> t_hi(int k) const { return q[k].t_hi(); }

  void leaf(uint64_t first, uint32_t count, vmask<A> const (&lanes)[K], uint32_t packets) {
    CellMesh<N> const& mesh = *q[0].mesh_;
    TreeView const& tree = *q[0].tree_;
    ValueWindows const& windows = q[0].windows;
    float const* xyz = mesh.positions();
    for (uint64_t i = first; i < first + count; ++i) {
      uint64_t const cell = tree.item(i);
      ScalarCorners<N> k;
      read_corner_values(mesh, cell, k);
      if (!windows.overlaps(k.lo, k.hi)) continue;
      float lo[3], hi[3];
      corner_box(xyz, k, lo, hi);
      vmask<A> in[K];
      uint32_t any = 0;  // packets with a lane in the cell's box
      for (int p = 0; p < K; ++p) {
        if (!((packets >> p) & 1u)) continue;
        vfloat<A> tn;
        in[p] = lanes[p] && box_hit(r[p], lo, hi, q[p].lo, q[p].t_hi(), tn);
        if (simd::any(in[p])) any |= 1u << p;
      }
      if (!any) continue;
      order_corners(mesh.vertex_count(), k);
      CellCorners<A, N> const c = broadcast<A, N>(mesh, k);
      vint<A> const id = vint<A>(int32_t(cell));
      if constexpr (CellOps<A, N>::shares_window_setup && CellOps<A, N>::march_clips_window) {
        if (shared_origin && (any & (any - 1))) {  // two packets or more
          auto const set = CellOps<A, N>::window_setup(c, origin);
          for (uint32_t b = any; b; b &= b - 1) {
            int const p = __builtin_ctz(b);
            q[p].visit_clipped(
                c, CellOps<A, N>::clip_window_set(ray_batch(r[p]), c, set, in[p], q[p].lo, q[p].t_hi()), id);
          }
          continue;
        }
      }
      for (uint32_t b = any; b; b &= b - 1) {
        int const p = __builtin_ctz(b);
        q[p].visit(c, in[p], id);
      }
    }
  }
};

/// The march of one packet (see the file comment; the renderer checks the
/// mesh fits 32-bit gather offsets). The renderer drives it:
/// locate() for lanes without a cell, step() for the others, integrating
/// each step's segments, until its lanes are done.
template <class A, int N> struct CellMarch {
  static constexpr int faces = FaceNeighbours<N>::faces;
  /// Every step's field is linear along the ray (Step::gradient is set).
  static constexpr bool linear_on_ray = CellOps<A, N>::linear_on_ray;
  using Clip = typename CellOps<A, N>::Clip;
  TreeView const& tree;
  CellMesh<N> const& mesh;
  int32_t const* across;  ///< FaceNeighbours<N>::data()
  RayPacket<A> const& r;
  ValueWindows const& windows;
  /// Cells in a row without a visible segment before a lane asks the tree
  /// for its next visible cell instead.
  int max_faint = 4;

  vfloat<A> t;      ///< per lane: where the ray has got to
  vfloat<A> t_end;  ///< per lane: where it stops
  vint<A> cell = vint<A>(-1);  ///< the cell the lane steps through next; -1: locate first
  vint<A> faint = vint<A>(0);  ///< cells in a row without a visible segment
  /// Onward steps in a row that ended where they began (see step).
  vint<A> stalled = vint<A>(0);
  static constexpr int max_stalled = 16;
  /// The cell each lane left for the tree (through a boundary face or after
  /// `max_faint` faint cells; -1 after a step that could not go on): its locate
  /// skips it. A line crosses a cell once, but an onward clip's exit t
  /// (CellOps::march_clip_onward) may round a little short of the cell's
  /// own clip, which would find the cell again and step it twice.
  vint<A> left = vint<A>(-1);
  /// t at each lane's last locate: a lane that needs another at the same t
  /// cannot progress (a defensive end; the clip of the located cell
  /// progresses by construction, see FirstCellQuery).
  vfloat<A> located_at = vfloat<A>(std::numeric_limits<float>::quiet_NaN());
  /// The corners of every lane's last cell, written in place by each step
  /// (a Step points at them: copied out, 1280 bytes a tet step went by `rep
  /// movsq`, 9% of the 2.4M-tet DVR frame's march). Tets: valid for
  /// next_corners after a step, until the next locate: a lane's next cell
  /// shares three of them.
  CellCorners<A, N> last;
  vint<A> last_exit = vint<A>(0);  ///< tets: the face each lane left its last cell through
  vfloat<A> last_s_out;            ///< tets: the value where each lane left it
  /// The neighbour across each lane's last exit (0 where none), which is
  /// `cell` in the lanes that go on: while `follow`, a step gathers from it
  /// (see step).
  vint<A> ahead = vint<A>(0);
  /// Every lane with a cell went on to it from its own last step (false
  /// after a locate, or when lanes arrive from a mixed mesh's other part).
  bool follow = false;
  /// 1 / (d . d) per lane: the onward clip's t (CellOps::march_clip_onward).
  vfloat<A> const inv_dd = vfloat<A>(1.f) / dot(ray_batch(r).dir(), ray_batch(r).dir());
  bool last_valid = false;  ///< tets: `last` holds each lane's last cell, and follow
  /// next_corners applies: a type that shares a face's corners with its
  /// neighbour (tets), 32-bit indices whose ids are the corners' keys, and
  /// offsets 3 x vertex in 31 bits (as gather_corners needs them).
  bool const reuse_ok = CellOps<A, N>::march_reuses_corners && mesh.has_32bit_indices() &&
                        mesh.vertex_count() * 3 < uint64_t(std::numeric_limits<int32_t>::max());

  /// What a step found per lane: the cell's clip and the piece [a, e] of it
  /// the ray has not integrated yet; `visible` where that piece may have
  /// opacity (no NaN corner, values meeting a window, e > a).
  struct Step {
    CellCorners<A, N> const* corners = nullptr;  ///< the march's `last`: valid until its next step
    CellCorners<A, N> const& c() const { return *corners; }
    Clip k;
    vfloat<A> a, e;
    vmask<A> visible;
    Vec3<A> gradient;  ///< linear_on_ray: the cell's (constant) field gradient, when asked for
  };

  CellMarch(TreeView const& tr, CellMesh<N> const& m, FaceNeighbours<N> const& nb, RayPacket<A> const& rays,
            ValueWindows const& w, vfloat<A> const& t_start, vfloat<A> const& t_stop)
      : tree(tr), mesh(m), across(nb.data()), r(rays), windows(w), t(t_start), t_end(t_stop) {}

  vmask<A> has_cell() const { return simd::to_float_mask(cell >= vint<A>(0)); }

  /// The next visible cell for the lanes in `need` (one traversal). Returns
  /// the lanes that have none: their rays are done.
  vmask<A> locate(vmask<A> const& need, Traversal how, int threshold) {
    vmask<A> const stuck = need && t == located_at;
    vmask<A> const ask = need && !stuck;
    FirstCellQuery<A, N> q(tree, mesh, r, windows, t, t_end, left);
    traverse_query<A>(tree, r, ask, q, how, threshold);
    return need && !take_located(ask, q.cell);
  }

  /// A locate's answer (FirstCellQuery::cell) for the lanes in `asked`,
  /// found here or for a group of packets at once (FirstCellGroup): the
  /// lanes go on from those cells. Returns the lanes that found one.
  vmask<A> take_located(vmask<A> const& asked, vint<A> const& found_cell) {
    vmask<A> const found = asked && simd::to_float_mask(found_cell >= vint<A>(0));
    cell = simd::select(simd::to_int_mask(found), found_cell, cell);
    faint = simd::select(simd::to_int_mask(found), vint<A>(0), faint);
    located_at = simd::select(asked, t, located_at);
    last_valid = follow = false;
    return found;
  }

  /// One cell for each lane in `lanes` (all with a cell): its clip and the
  /// piece past t, then on to the neighbour across the exit face (-1 where
  /// there is none, the step made no progress (an onward step: more than
  /// `max_stalled` in a row) or the lane has had `max_faint` invisible
  /// cells in a row). t advances to the exit, never back. Forced
  /// inline: see march_step in render/dvr_integrators_impl.hpp.
  CELLRAY_FORCE_INLINE Step step(vmask<A> const& lanes, bool want_gradient) {
    Step s;
    s.corners = &last;
    CellCorners<A, N>& c = last;
    vint<A> exit_face(0);
    using Ops = CellOps<A, N>;
    bool onward = false;
    if constexpr (Ops::march_reuses_corners) {
      onward = last_valid;
      if (onward) {
        vint<A> entry;
        next_corners(entry);
        s.k = Ops::march_clip_onward(ray_batch(r), c, lanes, entry, t, last_s_out, inv_dd, exit_face);
      }
    }
    // The cells' addresses, from the last step where it holds them for
    // every lane (see below).
    vint<A> const at = follow ? ahead : simd::select(simd::to_int_mask(lanes), cell, vint<A>(0));
    if (!onward) {
      gather_corners_into<A, N>(c, mesh, at, simd::all_lanes<A>());
      s.k = Ops::march_clip_window(ray_batch(r), c, lanes, t, t_end, &exit_face);
    }
    // A field linear on every ray has one gradient per cell.
    if constexpr (Ops::linear_on_ray)
      if (want_gradient) s.gradient = Ops::gradient_at(c, Vec3<A>{});
    vmask<A> const progress = s.k.hit && s.k.t_out > t;
    // An onward clip takes t at the exit from the exit face's weights, t at
    // the entry from the last cell's: a line through a cell close to an
    // edge or vertex can leave before it entered after rounding. Such a
    // lane goes on across the exit face with nothing to integrate, at most
    // `max_stalled` cells in a row, rather than ask the tree (it would wait
    // for its whole packet: the 2.4M-tet DVR frame was 1.2x slower so).
    stalled = simd::select(simd::to_int_mask(progress), vint<A>(0), stalled + vint<A>(1));
    vmask<A> moves = progress;
    if (onward) moves = s.k.hit && (progress || simd::to_float_mask(stalled <= vint<A>(max_stalled)));
    s.a = simd::max(s.k.t_in, t), s.e = simd::min(s.k.t_out, t_end);
    s.visible = progress && s.e > s.a && !has_nan_value(c) && visible_values<A, N>(windows, c, s.k);
    vmaski<A> const mi = simd::to_int_mask(moves);
    // The neighbour's address depends on the exit face alone, not on
    // whether the lane goes on: the next step's gathers then need not wait
    // for this step's t and values, nor for its integration (component8
    // DVR, with the onward clip: 1.06x).
    vint<A> const next = simd::gather(across, at * vint<A>(faces) + exit_face);
    // A cell left where it was entered is no transparent stretch.
    faint = simd::select(simd::to_int_mask(s.visible), vint<A>(0),
                         simd::select(simd::to_int_mask(progress), faint + vint<A>(1), faint));
    t = simd::select(progress, s.e, t);
    vmaski<A> const go_on = mi && faint <= vint<A>(max_faint);
    left = simd::select(simd::to_int_mask(lanes), simd::select(mi, cell, vint<A>(-1)), left);
    cell = simd::select(simd::to_int_mask(lanes), simd::select(go_on, next, vint<A>(-1)), cell);
    ahead = simd::select(next < vint<A>(0), vint<A>(0), next), follow = true;
    if constexpr (Ops::march_reuses_corners) last_exit = exit_face, last_s_out = s.k.s_out, last_valid = reuse_ok;
    return s;
  }

  /// gather_corners for lanes whose tet is the neighbour of their last one
  /// across face `last_exit`: the three corners of that face are the last
  /// cell's others, already in ascending id order; the new cell's fourth id
  /// is the xor of its four ids with those three (the one it does not
  /// share), its position and value the only ones gathered (4 gathers
  /// instead of 16), and it goes where its id sorts among the three. The
  /// same corners, bit for bit, as gather_corners (equal ids: the same
  /// vertex, wherever it sorts). `entry` gets the index of the face the
  /// lane enters through: the one opposite the unshared corner. Written
  /// over `last` (read first).
  void next_corners(vint<A>& entry) {
    static_assert(N == 4);
    CellCorners<A, 4>& c = last;
    vint<A> const& cl = ahead;  // == cell in `lanes`
    auto const* idx = reinterpret_cast<int32_t const*>(mesh.indices32());
    vint<A> ids[4];
    simd::gather_quads(idx, cl * vint<A>(4), ids);  // the cell's row: one 16-byte load a lane
    vint<A> fresh_id = (ids[0] ^ ids[1]) ^ (ids[2] ^ ids[3]);
    // The shared face: the last corners but the one opposite it.
    vint<A> sid[3];
    vfloat<A> sx[3], sy[3], sz[3], ss[3];
    for (int k = 0; k < 3; ++k) {
      vmaski<A> const after = last_exit <= vint<A>(k);
      vmask<A> const af = simd::to_float_mask(after);
      sid[k] = simd::select(after, last.id[k + 1], last.id[k]);
      sx[k] = simd::select(af, last.x[k + 1], last.x[k]), sy[k] = simd::select(af, last.y[k + 1], last.y[k]);
      sz[k] = simd::select(af, last.z[k + 1], last.z[k]), ss[k] = simd::select(af, last.s[k + 1], last.s[k]);
      fresh_id = fresh_id ^ sid[k];
    }
    // Lanes outside `lanes` xor another cell's ids with stale corners (no
    // mask: the gathers' addresses do not wait for the lanes), and so would
    // neighbours that do not fit the mesh (FaceNeighbours::fits samples it):
    // vertex 0 there, wrong pixels at worst, never a read outside the arrays.
    vint<A> const last_vertex(int32_t(mesh.vertex_count() - 1));  // reuse_ok: 3 x vertex < 2^31
    vmaski<A> const readable = fresh_id >= vint<A>(0) && fresh_id <= last_vertex;
    fresh_id = simd::select(readable, fresh_id, vint<A>(0));
    float const* xyz = mesh.positions();
    float const* val = mesh.values();
    vint<A> const v3 = fresh_id * vint<A>(3);
    vfloat<A> fx, fy, fz;
    simd::gather_xyz(xyz, v3, int32_t(3 * (mesh.vertex_count() - 1)), fx, fy, fz);
    vfloat<A> const fs =
        val ? simd::finite_or_nan(simd::gather(val, fresh_id)) : vfloat<A>(std::numeric_limits<float>::quiet_NaN());
    // before[k]: the shared corner k sorts before the fresh one (they are
    // ascending, so before[0] >= before[1] >= before[2]).
    vmaski<A> before[3];
    for (int k = 0; k < 3; ++k) before[k] = sid[k] < fresh_id;
    auto place = [&](auto& out, auto const (&shared)[3], auto const& fresh, auto const& mask_of) {
      out[0] = simd::select(mask_of(before[0]), shared[0], fresh);
      out[1] = simd::select(mask_of(before[1]), shared[1], simd::select(mask_of(before[0]), fresh, shared[0]));
      out[2] = simd::select(mask_of(before[2]), shared[2], simd::select(mask_of(before[1]), fresh, shared[1]));
      out[3] = simd::select(mask_of(before[2]), fresh, shared[2]);
    };
    auto as_int = [](vmaski<A> const& m) { return m; };
    auto as_float = [](vmaski<A> const& m) { return simd::to_float_mask(m); };
    place(c.id, sid, fresh_id, as_int);
    vint<A> const one(1), zero(0);
    entry = (simd::select(before[0], one, zero) + simd::select(before[1], one, zero)) + simd::select(before[2], one, zero);
    place(c.x, sx, fx, as_float), place(c.y, sy, fy, as_float), place(c.z, sz, fz, as_float), place(c.s, ss, fs, as_float);
  }
};

/// The tet march (cell-segment DVR and AO rays of tet meshes).
template <class A> using TetMarch = CellMarch<A, 4>;

/// The march of a mixed mesh's two parts, tets and hexahedra (wedges and
/// pyramids as collapsed ones) over one vertex array, with face neighbours
/// linked across them (link_face_neighbours): each lane is in a cell of one
/// part and steps with that part's kernel; a lane that leaves through a
/// triangle shared with the other part goes on there. A boundary-layer mesh
/// (prisms on a wall, tets beyond) marches as a whole instead of clipping
/// every cell of both trees' leaves. Locating asks both trees and takes the
/// nearer cell. The segments are each part's own, so the image is the
/// two-part tree's up to rounding.
template <class A> struct MixedMarch {
  static constexpr bool linear_on_ray = false;  ///< see CellMarch's
  CellMarch<A, 4> tets;   ///< lanes with tets.cell >= 0 are in a tet
  CellMarch<A, 8> hexes;  ///< lanes with hexes.cell >= 0 in a hexahedron; never both
  vfloat<A> t;            ///< per lane: where the ray has got to (both parts' t)
  vfloat<A> located_at = vfloat<A>(std::numeric_limits<float>::quiet_NaN());  ///< as CellMarch's

  struct Step {
    typename CellMarch<A, 4>::Step tet;
    typename CellMarch<A, 8>::Step hex;
    vmask<A> in_tet, in_hex;  ///< the lanes each part stepped
  };

  MixedMarch(TreeView const& tet_tree, TetMesh const& tm, TetNeighbours const& tn, TreeView const& hex_tree,
             HexMesh const& hm, HexNeighbours const& hn, RayPacket<A> const& rays, ValueWindows const& w,
             vfloat<A> const& t_start, vfloat<A> const& t_stop)
      : tets(tet_tree, tm, tn, rays, w, t_start, t_stop), hexes(hex_tree, hm, hn, rays, w, t_start, t_stop), t(t_start) {}

  vmask<A> has_cell() const { return tets.has_cell() || hexes.has_cell(); }

  /// As CellMarch::locate, over both trees: the hexahedra's query only looks
  /// for cells entered before the tet it found.
  vmask<A> locate(vmask<A> const& need, Traversal how, int threshold) {
    vmask<A> const stuck = need && t == located_at;
    vmask<A> const ask = need && !stuck;
    FirstCellQuery<A, 4> qt(tets.tree, tets.mesh, tets.r, tets.windows, t, tets.t_end, tets.left);
    traverse_query<A>(tets.tree, tets.r, ask, qt, how, threshold);
    FirstCellQuery<A, 8> qh(hexes.tree, hexes.mesh, hexes.r, hexes.windows, t, simd::min(tets.t_end, qt.best_t),
                            hexes.left);
    traverse_query<A>(hexes.tree, hexes.r, ask, qh, how, threshold);
    vmask<A> const found_tet = ask && simd::to_float_mask(qt.cell >= vint<A>(0));
    vmask<A> const found_hex = ask && simd::to_float_mask(qh.cell >= vint<A>(0)) && (!found_tet || qh.best_t < qt.best_t);
    vmask<A> const in_tet = found_tet && !found_hex;
    tets.cell = simd::select(simd::to_int_mask(in_tet), qt.cell, simd::select(simd::to_int_mask(found_hex), vint<A>(-1), tets.cell));
    hexes.cell = simd::select(simd::to_int_mask(found_hex), qh.cell, simd::select(simd::to_int_mask(in_tet), vint<A>(-1), hexes.cell));
    vmaski<A> const found = simd::to_int_mask(in_tet || found_hex);
    tets.faint = hexes.faint = simd::select(found, vint<A>(0), tets.faint);
    located_at = simd::select(ask, t, located_at);
    tets.last_valid = tets.follow = hexes.follow = false;
    return need && !(in_tet || found_hex);
  }

  /// One cell for each lane in `lanes` (all with a cell), with its part's
  /// kernel (CellMarch::step); lanes that leave across a link go on in the
  /// other part.
  CELLRAY_FORCE_INLINE Step step(vmask<A> const& lanes, bool want_gradient) {
    Step s;
    s.in_tet = lanes && tets.has_cell();
    s.in_hex = lanes && hexes.has_cell();
    vint<A> const faint = tets.faint;
    if (simd::any(s.in_tet)) s.tet = tets.step(s.in_tet, want_gradient);
    else s.tet.visible = simd::no_lanes<A>();
    if (simd::any(s.in_hex)) s.hex = hexes.step(s.in_hex, want_gradient);
    else s.hex.visible = simd::no_lanes<A>();
    // Each step moved t and counted faint cells for its own lanes only.
    vmaski<A> const hi = simd::to_int_mask(s.in_hex), ti = simd::to_int_mask(s.in_tet);
    t = simd::select(s.in_hex, hexes.t, tets.t);
    tets.t = hexes.t = t;
    tets.faint = hexes.faint = simd::select(hi, hexes.faint, simd::select(ti, tets.faint, faint));
    // Links (<= -2) move a lane to the other part.
    vint<A> const minus_two(-2);
    vmaski<A> const to_hex = tets.cell <= minus_two, to_tet = hexes.cell <= minus_two;
    vint<A> const next_hex = simd::select(to_hex, minus_two - tets.cell, simd::select(to_tet, vint<A>(-1), hexes.cell));
    tets.cell = simd::select(to_tet, minus_two - hexes.cell, simd::select(to_hex, vint<A>(-1), tets.cell));
    hexes.cell = next_hex;
    // next_corners needs the lane's last tet, and `ahead` its own last step.
    if (simd::any(simd::to_float_mask(to_tet))) tets.last_valid = tets.follow = false;
    if (simd::any(simd::to_float_mask(to_hex))) hexes.follow = false;
    return s;
  }
};

/// Occlusion (any hit, traverse/occlusion.hpp) of short rays that start in
/// known cells (ambient-occlusion rays leave an isosurface hit in its hit
/// cell), of any cell type: lanes of `active` march from `start` over
/// [r.tmin, r.tmax], each cell tested with the occlusion query's kernel
/// (iso_in_clip) on the march's clip. Returns the occluded lanes;
/// `undecided` gets the lanes the march could not finish (left the mesh
/// through a boundary face before r.tmax, or made no progress: an origin
/// just outside its start cell, a hexahedron's exit face picked wrong next
/// to an edge) and `t_done` how far each lane got without a crossing: the
/// caller asks the tree for [t_done, r.tmax] of those.
template <class A, int N>
inline vmask<A> march_occluded(TreeView const& tree, CellMesh<N> const& mesh, FaceNeighbours<N> const& nb,
                               RayPacket<A> const& r, vmask<A> const& active, vint<A> const& start,
                               IsoSet const& isos, CellIsoOptions const& method, vmask<A>& undecided,
                               vfloat<A>& t_done) {
  ValueWindows const all;
  CellMarch<A, N> m(tree, mesh, nb, r, all, r.tmin, r.tmax);
  m.max_faint = std::numeric_limits<int32_t>::max() - 1;  // no value filter: every cell is tested
  m.cell = simd::select(simd::to_int_mask(active), start, vint<A>(-1));
  vmask<A> occluded = simd::no_lanes<A>(), live = active;
  RayBatch<A> const ray = ray_batch(r);
  while (true) {
    vmask<A> const has = live && m.has_cell();
    if (simd::none(has)) break;
    typename CellMarch<A, N>::Step const st = m.step(has, false);
    vmask<A> const nan = has_nan_value(st.c());
    CellIsoHit<A> const h = iso_in_clip<A, N>(ray, st.k, st.c(), r.tmin, r.tmax, isos.values, isos.count, method);
    vmask<A> const found = h.hit && has && !nan;
    occluded = occluded || found;
    live = live && !found && m.t < r.tmax;
  }
  undecided = live;
  t_done = m.t;
  return occluded;
}

/// march_occluded across a mixed mesh's two linked parts (MixedMarch): lanes
/// start in `start`, a hexahedron where `in_hex`, else a tet, and cross
/// between the parts where their neighbours are linked.
template <class A>
inline vmask<A> march_occluded(TreeView const& tet_tree, TetMesh const& tm, TetNeighbours const& tn,
                               TreeView const& hex_tree, HexMesh const& hm, HexNeighbours const& hn,
                               RayPacket<A> const& r, vmask<A> const& active, vint<A> const& start,
                               vmask<A> const& in_hex, IsoSet const& isos, CellIsoOptions const& method,
                               vmask<A>& undecided, vfloat<A>& t_done) {
  ValueWindows const all;
  MixedMarch<A> m(tet_tree, tm, tn, hex_tree, hm, hn, r, all, r.tmin, r.tmax);
  m.tets.max_faint = m.hexes.max_faint = std::numeric_limits<int32_t>::max() - 1;  // every cell is tested
  m.tets.cell = simd::select(simd::to_int_mask(active && !in_hex), start, vint<A>(-1));
  m.hexes.cell = simd::select(simd::to_int_mask(active && in_hex), start, vint<A>(-1));
  vmask<A> occluded = simd::no_lanes<A>(), live = active;
  RayBatch<A> const ray = ray_batch(r);
  while (true) {
    vmask<A> const has = live && m.has_cell();
    if (simd::none(has)) break;
    typename MixedMarch<A>::Step const st = m.step(has, false);
    vmask<A> found = simd::no_lanes<A>();
    if (simd::any(st.in_tet)) {
      CellIsoHit<A> const h =
          iso_in_clip<A, 4>(ray, st.tet.k, st.tet.c(), r.tmin, r.tmax, isos.values, isos.count, method);
      found = found || (h.hit && st.in_tet && !has_nan_value(st.tet.c()));
    }
    if (simd::any(st.in_hex)) {
      CellIsoHit<A> const h =
          iso_in_clip<A, 8>(ray, st.hex.k, st.hex.c(), r.tmin, r.tmax, isos.values, isos.count, method);
      found = found || (h.hit && st.in_hex && !has_nan_value(st.hex.c()));
    }
    occluded = occluded || found;
    live = live && !found && m.t < r.tmax;
  }
  undecided = live;
  t_done = m.t;
  return occluded;
}

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
