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

#include <array>
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

/// Weighted gradients of one cell: tets one (the cell's, weight its
/// volume), hexes one per corner (at the corner, weight |det J| / 8); each
/// as gx, gy, gz, weight (weight 0: a NaN or infinite value, a flat cell).
template <int N> inline constexpr int gradients_per_cell = N == 4 ? 1 : 8;

template <int N> inline void cell_gradients(CellMesh<N> const& mesh, uint64_t cell, std::array<float, 4>* out) {
  ref::Cell<N> const c = ref::load(mesh, cell);
  bool const nan = ref::has_nan(c);
  auto put = [&](int k, glm::dvec3 const& g, double w) {
    bool const ok = !nan && w > 0 && std::isfinite(w) && std::isfinite(g.x + g.y + g.z);
    out[k][0] = ok ? float(w * g.x) : 0.f, out[k][1] = ok ? float(w * g.y) : 0.f;
    out[k][2] = ok ? float(w * g.z) : 0.f, out[k][3] = ok ? float(w) : 0.f;
  };
  if constexpr (N == 4) {
    glm::dvec3 const e1 = c.p[1] - c.p[0], e2 = c.p[2] - c.p[0], e3 = c.p[3] - c.p[0];
    put(0, nan ? glm::dvec3(0) : ref::gradient(c), std::abs(glm::dot(e1, glm::cross(e2, e3))) / 6.0);
  } else {
    for (int k = 0; k < 8; ++k) {
      glm::dvec3 const u(ref::detail::hex_uvw[k][0], ref::detail::hex_uvw[k][1], ref::detail::hex_uvw[k][2]);
      glm::dvec3 ju, jv, jw;
      ref::detail::trilerp_grad(c.p, u, ju, jv, jw);
      put(k, nan ? glm::dvec3(0) : ref::gradient(c, u), std::abs(glm::dot(ju, glm::cross(jv, jw))) / 8.0);
    }
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
  constexpr int per = detail::gradients_per_cell<N>;
  // Each cell's weighted gradients once, in parallel (16 bytes each, freed
  // at the end), then per vertex the sum over its corners.
  std::vector<std::array<float, 4>> cell(nc * per);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nc, 4096), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t c = r.begin(); c < r.end(); ++c) detail::cell_gradients(mesh, c, &cell[c * per]);
  });
  // Corners (cell * N + k) grouped by vertex: a counting sort.
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
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nv, 4096), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t v = r.begin(); v < r.end(); ++v) {
      double sum[4] = {0, 0, 0, 0};
      for (uint64_t i = start[v]; i < start[v + 1]; ++i) {
        std::array<float, 4> const& e = cell[N == 4 ? corner[i] / N : corner[i]];  // hexes: per = N, so the corner index itself
        for (int a = 0; a < 4; ++a) sum[a] += double(e[a]);
      }
      if (sum[3] > 0)
        for (int a = 0; a < 3; ++a) out.g_[3 * v + uint64_t(a)] = float(sum[a] / sum[3]);
    }
  });
  return out;
}

}  // namespace cellray
