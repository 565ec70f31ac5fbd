#pragma once
// CellOps<A, N>: what the traversals and integrators (traverse/, render/)
// call for a cell type of N corners, over its kernels. Each type's file
// specializes it (tet.hpp: CellOps<A, 4>; hex.hpp: CellOps<A, 8>, which
// also serves wedges and pyramids as hexahedra with repeated corners), so
// that code after cells/ asks about properties, never about a type.
//
// A specialization provides:
//   Clip                      the clip type (t_in/t_out, s_in/s_out, hit)
//   clip(r, c)                the ray's interval in the cell per lane
//   clip_window(r, c, lanes, t_lo, t_hi, exit_face*)
//                             narrowed to a window; the face a march leaves by
//   march_clip_window(same)   what a march step clips with: clip_window up to
//                             rounding (faces seen from two sides need not agree)
//   iso(r, k, c, isos, count, options, param*, t_from*)
//                             nearest isovalue crossing (exact or Neubauer)
//   locate(p, c[, lanes])     point location: inside, value, cell coordinates
//   nearly_inside(loc, tol)   a probe's fallback band (may be no lanes)
//   gradient(c, p, method, h), gradient_at(c, param)
//   shape_weights(param, w)   one weight per corner at cell coordinates
//   param_in_cell(param)      (keeps_param types) coordinates standing for a point
//   segment_field(r, c, k, lanes, f, g*)
//                             the field (and gradient) along a clip as cubics
// and the properties
//   linear_on_ray             the field is linear on every ray (one gradient a cell)
//   keeps_param               hits and located points keep cell coordinates
//   march_reuses_corners      a march's next cell shares a face's corners; then
//                             also march_clip_onward(r, c, lanes, entry, t_in,
//                             s_in, inv_dd, exit_face&): the clip from the face
//                             the march entered through
//   occlusion_in_pairs        grouped occlusion clips (cell, ray) pairs
//   shares_window_setup       packets with one origin can share a cell's clip setup;
//                             then also WindowSetup, window_setup(c, origin) and
//                             clip_window_set(r, c, setup, lanes, t_lo, t_hi): the bits of
//                             clip_window; and march_clips_window: march_clip_window
//                             is clip_window (a march's locate may share it too)
//   holds_folded_tets         some cells may be tets stored as this type; then also
//                             is_folded_tet(keys), broadcast_folded_tet(xyz, k) -> FoldedTet,
//                             folded_tet_param(folded, p)
// A new type adds its file here, its corner count to mesh/cell_types.hpp's
// CellTypes, its FaceNeighbours faces (mesh/neighbours.hpp), its double
// reference (cells/reference.hpp: load, clip, locate, FieldOnRay<N>), and,
// while Scene keeps one vector per type, its vector there (Scene::parts<N>,
// render.hpp) and its name in cell_type_adjective.

#include "../simd/arch.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

template <class A, int N> struct CellOps;

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
