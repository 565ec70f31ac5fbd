#pragma once
// Query entry points over a min-max BVH, dispatched per ISA. Rays are taken
// in consecutive groups of W (the packet width of the ISA): callers that
// want coherent packets order rays by pixel blocks (render/ does).

#include <cstdint>
#include <vector>

#include "../dispatch/dispatch.hpp"
#include "../mesh/cell_mesh.hpp"
#include "ray.hpp"
#include "tree_view.hpp"

namespace cellray {

/// What a first-hit query looks for and how it traverses.
struct IsoQuery {
  IsoSet isos;
  CellIsoOptions method;                           ///< exact roots (default) or Neubauer N steps
  GradientMethod normals = GradientMethod::analytic;
  Traversal traversal = Traversal::packet;
  /// Hybrid only: a subtree reached by fewer active lanes than this is
  /// finished one ray at a time (0: a quarter of the packet width).
  int hybrid_threshold = 0;
};

/// First isosurface hit of every ray in [tmin, tmax] (Rathke 2015 §6).
/// Reads the mesh, tree and rays; writes `hits[0..n)`. Single-threaded:
/// callers split rays across threads. NaN cells are never hit.
template <class Arch> struct FirstHitEntry {
  static void run(TreeView const& tree, TetMesh const& mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                  SurfaceHit* hits);
  static void run(TreeView const& tree, HexMesh const& mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                  SurfaceHit* hits);
};
CELLRAY_EXTERN_ENTRY(FirstHitEntry)

/// Baseline-callable: dispatches to `isa` (default: `default_isa()`).
template <int N>
std::vector<SurfaceHit> first_hits(TreeView const& tree, CellMesh<N> const& mesh, std::vector<Ray> const& rays,
                                   IsoQuery const& q, Isa isa = default_isa()) {
  std::vector<SurfaceHit> hits(rays.size());
  dispatch<FirstHitEntry>(isa, tree, mesh, rays.data(), uint64_t(rays.size()), q, hits.data());
  return hits;
}

}  // namespace cellray
