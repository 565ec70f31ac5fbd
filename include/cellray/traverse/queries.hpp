#pragma once
// Query entry points over a min-max BVH, dispatched per ISA. Rays are taken
// in consecutive groups of W (the packet width of the ISA): callers that
// want coherent packets order rays by pixel blocks (render/ does).

#include <cstdint>
#include <vector>

#include "../dispatch/dispatch.hpp"
#include "../mesh/cell_mesh.hpp"
#include "../mesh/cell_types.hpp"
#include "point_order.hpp"
#include "ray.hpp"
#include "sample.hpp"
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
  static void run(TreeView const& tree, AnyCellMesh mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                  SurfaceHit* hits);
};
CELLRAY_EXTERN_ENTRY(FirstHitEntry)

/// Volume samples: for ray i, the value at rays[i].tmin + k * step for
/// k in [0, samples_per_ray), written to out[i * samples_per_ray + k]; NaN
/// where the point lies in no cell (or in a cell with a NaN value, or, with
/// `windows`, in a subtree whose values lie outside every window). The
/// samples of a ray are located `group` at a time (1..32) per traversal.
template <class Arch> struct SampleEntry {
  static void run(TreeView const& tree, AnyCellMesh mesh, Ray const* rays, uint64_t n, float step,
                  int samples_per_ray, int group, Traversal how, ValueWindows const& windows, float* out);
};
CELLRAY_EXTERN_ENTRY(SampleEntry)

/// Point location (traverse/probe.hpp): fills the NaN entries of
/// values[0, n) with the mesh's field at the points xyz[3i, 3i + 3); the
/// other entries are kept and their points skipped (so several parts fill
/// one array, the first part that holds a point winning). A point in no
/// cell, or only in cells with a NaN (or infinite) corner value, stays NaN;
/// a point exactly on a face, edge or vertex shared by cells takes the value
/// of one of them (the field is continuous there). Packets of W consecutive
/// points share one descent: callers order the points along a space-filling
/// curve first (detail::probe_in_order). Single-threaded; reads only.
template <class Arch> struct ProbeEntry {
  static void run(TreeView const& tree, AnyCellMesh mesh, float const* xyz, uint64_t n, float* values);
};
CELLRAY_EXTERN_ENTRY(ProbeEntry)

/// Baseline-callable: dispatches to `isa` (default: `default_isa()`).
template <int N>
std::vector<SurfaceHit> first_hits(TreeView const& tree, CellMesh<N> const& mesh, std::vector<Ray> const& rays,
                                   IsoQuery const& q, Isa isa = default_isa()) {
  std::vector<SurfaceHit> hits(rays.size());
  dispatch<FirstHitEntry>(isa, tree, mesh, rays.data(), uint64_t(rays.size()), q, hits.data());
  return hits;
}

}  // namespace cellray

namespace cellray {

/// Baseline-callable: `samples_per_ray` samples per ray (see SampleEntry).
template <int N>
std::vector<float> sample_rays(TreeView const& tree, CellMesh<N> const& mesh, std::vector<Ray> const& rays, float step,
                               int samples_per_ray, int group = 16, Traversal how = Traversal::packet,
                               Isa isa = default_isa()) {
  if (group < 1 || group > max_sample_group)
    throw InvalidArgument("sample group size " + std::to_string(group) + " outside 1..32");
  std::vector<float> out(rays.size() * size_t(samples_per_ray));
  dispatch<SampleEntry>(isa, tree, mesh, rays.data(), uint64_t(rays.size()), step, samples_per_ray, group, how,
                        ValueWindows{}, out.data());
  return out;
}

/// The value of the mesh at each point (xyz triples): NaN outside the mesh
/// and in cells with a NaN value (see ProbeEntry). The points are sorted
/// along a Morton curve of the tree's bounds, located in that order on TBB
/// (the caller's arena) and returned in input order.
template <int N>
std::vector<float> sample_points(TreeView const& tree, CellMesh<N> const& mesh, std::vector<float> const& xyz,
                                 Isa isa = default_isa()) {
  uint64_t const n = xyz.size() / 3;
  std::vector<float> out(n);
  glm::vec3 lo(0.f), hi(0.f);
  if (!tree.empty()) lo = glm::vec3(tree.nodes[0].lo[0], tree.nodes[0].lo[1], tree.nodes[0].lo[2]),
                     hi = glm::vec3(tree.nodes[0].hi[0], tree.nodes[0].hi[1], tree.nodes[0].hi[2]);
  detail::probe_in_order(xyz.data(), n, out.data(), lo, hi, true, [&](float const* p, uint64_t m, float* v) {
    dispatch<ProbeEntry>(isa, tree, mesh, p, m, v);
  });
  return out;
}

}  // namespace cellray
