#pragma once
// Query entry points over a min-max BVH, dispatched per ISA. Rays are taken
// in consecutive groups of W (the packet width of the ISA): callers that
// want coherent packets order rays by pixel blocks (render/ does).

#include <cstdint>
#include <vector>

#include "../dispatch/dispatch.hpp"
#include "../mesh/cell_mesh.hpp"
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
  static void run(TreeView const& tree, TetMesh const& mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                  SurfaceHit* hits);
  static void run(TreeView const& tree, HexMesh const& mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                  SurfaceHit* hits);
};
CELLRAY_EXTERN_ENTRY(FirstHitEntry)

/// Volume samples: for ray i, the value at rays[i].tmin + k * step for
/// k in [0, samples_per_ray), written to out[i * samples_per_ray + k]; NaN
/// where the point lies in no cell (or in a cell with a NaN value, or, with
/// `windows`, in a subtree whose values lie outside every window). The
/// samples of a ray are located `group` at a time (1..32) per traversal.
template <class Arch> struct SampleEntry {
  static void run(TreeView const& tree, TetMesh const& mesh, Ray const* rays, uint64_t n, float step,
                  int samples_per_ray, int group, Traversal how, ValueWindows const& windows, float* out);
  static void run(TreeView const& tree, HexMesh const& mesh, Ray const* rays, uint64_t n, float step,
                  int samples_per_ray, int group, Traversal how, ValueWindows const& windows, float* out);
};
CELLRAY_EXTERN_ENTRY(SampleEntry)

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

/// The value of the mesh at each point (xyz triples): NaN outside the mesh.
template <int N>
std::vector<float> sample_points(TreeView const& tree, CellMesh<N> const& mesh, std::vector<float> const& xyz,
                                 Isa isa = default_isa()) {
  std::vector<Ray> rays(xyz.size() / 3);
  for (size_t i = 0; i < rays.size(); ++i)
    rays[i] = Ray{{xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]}, 0.f, {1.f, 0.f, 0.f}, 0.f};
  return sample_rays(tree, mesh, rays, 0.f, 1, 1, Traversal::packet, isa);
}

}  // namespace cellray
