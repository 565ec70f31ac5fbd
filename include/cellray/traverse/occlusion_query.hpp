#pragma once
// Occlusion (any-hit) queries over a min-max BVH, dispatched per ISA: is a
// ray's segment crossed by an isosurface at all? What shadow and ambient-
// occlusion rays ask (the renderer's own use is render/occlusion_impl.hpp);
// hosts with their own renderer call it for theirs.

#include <cstdint>
#include <vector>

#include "../dispatch/dispatch.hpp"
#include "../mesh/cell_mesh.hpp"
#include "../mesh/cell_types.hpp"
#include "queries.hpp"
#include "ray.hpp"
#include "tree_view.hpp"

namespace cellray {

/// For ray i, occluded[i] = 1 if one of `q.isos` crosses its segment
/// [tmin, tmax] in a cell of `mesh`, else 0: exactly whether first_hits
/// finds a hit (same kernels, same window), but each packet stops at its
/// first crossings. NaN cells are never crossed. Rays go in consecutive
/// packets of W (the ISA's width) with `q.traversal`; with `grouped`, 4
/// consecutive packets (4 W rays) share one packet traversal (q.traversal
/// unused), which pays when they sweep the same nodes (rays leaving one
/// neighbourhood, e.g. one pixel block's AO rays, ordered by direction).
/// Reads the mesh, tree and rays; writes `occluded[0..n)`. Single-threaded.
template <class Arch> struct OcclusionEntry {
  static void run(TreeView const& tree, AnyCellMesh mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                  bool grouped, uint8_t* occluded);
};
CELLRAY_EXTERN_ENTRY(OcclusionEntry)

/// Baseline-callable: one byte per ray (see OcclusionEntry), on `isa`.
template <int N>
std::vector<uint8_t> occluded_rays(TreeView const& tree, CellMesh<N> const& mesh, std::vector<Ray> const& rays,
                                   IsoQuery const& q, bool grouped = false, Isa isa = default_isa()) {
  std::vector<uint8_t> out(rays.size());
  dispatch<OcclusionEntry>(isa, tree, mesh, rays.data(), uint64_t(rays.size()), q, grouped, out.data());
  return out;
}

}  // namespace cellray
