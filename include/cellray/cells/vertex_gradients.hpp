#pragma once
// Per-vertex gradients of the active point array, for smooth isosurface
// normals (issue #25): at each vertex, the volume-weighted average of the
// gradients of the cells around it (tets: the cell's constant gradient,
// weighted by the cell's volume; hexes: the trilinear gradient at that
// corner, weighted by the corner's share of the volume, |det J| / 8), as
// VTK's gradient filter averages cell derivatives at a point. The renderer
// interpolates them inside the hit cell with the cell's own shape functions
// (GradientMethod::smooth), so normals vary smoothly across cells where the
// per-cell analytic gradient is constant in a tet (facets). Computed in
// double, stored as float; 12 bytes per vertex. A new time step (another
// array) needs them again: build_vertex_gradients on the new view.

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../mesh/cell_mesh.hpp"
#include "reference.hpp"

namespace cellray {

/// Gradients per vertex of a mesh view's active array: xyz per vertex, world
/// units (value per length). NaN at vertices whose cells all have a NaN or
/// infinite value or no volume. Owned by the host, like the BVH; topology
/// and values must stay those it was built from (`fits` checks counts).
class VertexGradients {
 public:
  VertexGradients() = default;

  float const* data() const noexcept { return g_.data(); }
  uint64_t vertex_count() const noexcept { return g_.size() / 3; }
  uint64_t memory_bytes() const noexcept { return g_.size() * sizeof(float); }
  template <int N> bool fits(CellMesh<N> const& mesh) const noexcept { return vertex_count() == mesh.vertex_count(); }

  template <int N> friend VertexGradients build_vertex_gradients(CellMesh<N> const& mesh);

 private:
  std::vector<float> g_;
};

namespace detail {

/// Gradient and weight of corner k of cell `cell`, or weight 0 (a NaN or
/// infinite value, a flat cell).
template <int N> inline double corner_gradient(CellMesh<N> const& mesh, uint64_t cell, int k, glm::dvec3& g) {
  ref::Cell<N> const c = ref::load(mesh, cell);
  if (ref::has_nan(c)) return 0.0;
  if constexpr (N == 4) {
    (void)k;
    glm::dvec3 const e1 = c.p[1] - c.p[0], e2 = c.p[2] - c.p[0], e3 = c.p[3] - c.p[0];
    double const vol = std::abs(glm::dot(e1, glm::cross(e2, e3))) / 6.0;
    g = ref::gradient(c);
    return std::isfinite(vol) && vol > 0 ? vol : 0.0;
  } else {
    glm::dvec3 const u(ref::detail::hex_uvw[k][0], ref::detail::hex_uvw[k][1], ref::detail::hex_uvw[k][2]);
    glm::dvec3 ju, jv, jw;
    ref::detail::trilerp_grad(c.p, u, ju, jv, jw);
    double const vol = std::abs(glm::dot(ju, glm::cross(jv, jw))) / 8.0;
    g = ref::gradient(c, u);
    return std::isfinite(vol) && vol > 0 ? vol : 0.0;
  }
}

}  // namespace detail

/// Builds the per-vertex gradients of `mesh`'s active array (TBB-parallel:
/// a vertex-to-corner list by counting sort, then one task per vertex range).
/// Vertex ids must be valid (validate() first). Thread-safe.
template <int N> VertexGradients build_vertex_gradients(CellMesh<N> const& mesh) {
  uint64_t const nv = mesh.vertex_count(), nc = mesh.cell_count();
  VertexGradients out;
  out.g_.assign(3 * nv, std::numeric_limits<float>::quiet_NaN());
  if (!mesh.has_values() || nc == 0) return out;
  // Corners (cell * N + k) grouped by vertex.
  std::vector<uint64_t> start(nv + 1, 0);
  for (uint64_t c = 0; c < nc; ++c)
    for (int k = 0; k < N; ++k) ++start[mesh.vertex(c, k) + 1];
  for (uint64_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<uint64_t> corner(nc * N);
  {
    std::vector<uint64_t> fill(start.begin(), start.end() - 1);
    for (uint64_t c = 0; c < nc; ++c)
      for (int k = 0; k < N; ++k) corner[fill[mesh.vertex(c, k)]++] = c * N + uint64_t(k);
  }
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nv, 1024), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t v = r.begin(); v < r.end(); ++v) {
      glm::dvec3 sum(0.0);
      double weight = 0.0;
      for (uint64_t i = start[v]; i < start[v + 1]; ++i) {
        glm::dvec3 g(0.0);
        double const w = detail::corner_gradient(mesh, corner[i] / N, int(corner[i] % N), g);
        if (w > 0 && std::isfinite(g.x + g.y + g.z)) sum += w * g, weight += w;
      }
      if (weight > 0)
        for (int a = 0; a < 3; ++a) out.g_[3 * v + uint64_t(a)] = float(sum[a] / weight);
    }
  });
  return out;
}

}  // namespace cellray
