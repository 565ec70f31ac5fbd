#pragma once
// Per-vertex gradients of the active point array, for smooth isosurface
// normals (issue #25): at each vertex, the volume-weighted average of the
// gradients of the cells around it (tets: the cell's constant gradient,
// weighted by the cell's volume; hexes: the trilinear gradient at that
// corner, weighted by the corner's share of the volume, |det J| / 8; a tet
// folded into a hexahedron as the tet it is), as
// VTK's gradient filter averages cell derivatives at a point. The renderer
// interpolates them inside the hit cell with the cell's own shape functions
// (GradientMethod::smooth), so normals vary smoothly across cells where the
// per-cell analytic gradient is constant in a tet (facets). Computed in
// double, accumulated and stored as float; 12 bytes per vertex (plus 4 while
// building, and 16 more for the second range of the parallel pass).
// A new time step (another array) needs them again: build_vertex_gradients
// on the new view.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../memory.hpp"
#include "../mesh/cell_mesh.hpp"

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

/// The gradient of the linear field through corner `o` and its three
/// neighbours `a`, `b`, `c` (positions xyz, values val), times the weight
/// |det of the edges| added to `acc` (gx, gy, gz) and `w`. For a tet this is
/// the cell's own gradient (weight 6 x volume); for a hex corner, the
/// trilinear field's gradient at that corner (its Jacobian's columns are the
/// corner's three edges; weight 8 x its share of the volume, for a regular
/// hex). Double: float input is exact there. Flat corners add nothing.
inline void add_corner_gradient(float const* xyz, float const* val, uint64_t o, uint64_t a, uint64_t b, uint64_t c,
                                double scale, float* acc, float& w) {
  auto p = [xyz](uint64_t v) { return glm::dvec3(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]); };
  glm::dvec3 const p0 = p(o), e1 = p(a) - p0, e2 = p(b) - p0, e3 = p(c) - p0;
  glm::dvec3 const c23 = glm::cross(e2, e3), c31 = glm::cross(e3, e1), c12 = glm::cross(e1, e2);
  double const det = glm::dot(e1, c23);
  if (!(det != 0) || !std::isfinite(det)) return;
  double const s0 = val[o];
  // The gradient is this over det and its weight |det| x scale: their
  // product needs no division (flange hexahedra: 20.2 -> 18.9 ms).
  glm::dvec3 const weighted_g = ((double(val[a]) - s0) * c23 + (double(val[b]) - s0) * c31 + (double(val[c]) - s0) * c12) *
                                (det > 0 ? scale : -scale);
  for (int k = 0; k < 3; ++k) acc[k] += float(weighted_g[k]);
  w += float(std::abs(det) * scale);
}

}  // namespace detail

namespace detail {

/// Adds the gradients of cells [begin, end) of `mesh` into g (xyz per
/// vertex) and their weights into `weight`. Vertex ids must be valid.
template <int N>
void accumulate_vertex_gradients(CellMesh<N> const& mesh, uint64_t begin, uint64_t end, float* g, float* weight) {
  float const* xyz = mesh.positions();
  float const* val = mesh.values();
  for (uint64_t c = begin; c < end; ++c) {
    uint64_t v[N];
    bool finite = true;
    for (int k = 0; k < N; ++k) {
      v[k] = mesh.vertex(c, k);
      finite = finite && std::isfinite(val[v[k]]);
    }
    if (!finite) continue;  // a NaN or inf corner: the cell is invisible, its gradient too
    // A tet folded into a hexahedron (0 1 2 2 3 3 3 3: a mixed mesh as one
    // part) counts as its tet: an edge has collapsed at its corners 2 to 7,
    // where the trilinear corner gradient is undefined, so its vertices 2
    // and 3 would get nothing from it (facets in smooth normals).
    bool tet = N == 4;
    if constexpr (N == 8) tet = v[2] == v[3] && v[4] == v[5] && v[4] == v[6] && v[4] == v[7];
    if (tet) {
      uint64_t const t[4] = {v[0], v[1], v[2], v[N == 4 ? 3 : 4]};
      float acc[3] = {0.f, 0.f, 0.f}, w = 0.f;
      add_corner_gradient(xyz, val, t[0], t[1], t[2], t[3], 1.0, acc, w);
      for (uint64_t vk : t) {
        for (int a = 0; a < 3; ++a) g[3 * vk + uint64_t(a)] += acc[a];
        weight[vk] += w;
      }
    } else if constexpr (N == 8) {
      // Corner k's three edge neighbours (VTK hexahedron).
      static constexpr int nb[8][3] = {{1, 3, 4}, {2, 0, 5}, {3, 1, 6}, {0, 2, 7},
                                       {7, 5, 0}, {4, 6, 1}, {5, 7, 2}, {6, 4, 3}};
      for (int k = 0; k < 8; ++k)
        add_corner_gradient(xyz, val, v[k], v[nb[k][0]], v[nb[k][1]], v[nb[k][2]], 1.0, g + 3 * v[k], weight[v[k]]);
      // Where an edge has collapsed, the loop's corner has an edge of no
      // length and adds nothing: a wedge's two vertices on its collapsed
      // side and a pyramid's apex would get nothing from their cells (NaN
      // where no other cell adds). A wedge's corner gradient there is the
      // linear field through it, the other two corners of its triangle and
      // the corner across (its shape functions are linear along those
      // edges); a pyramid has none at its apex, which takes the four
      // tetrahedra of the apex and three consecutive base corners.
      if (v[2] == v[3] && v[6] == v[7] && v[2] != v[6]) {  // mesh/vtk_cells.hpp's wedge_as_hex
        add_corner_gradient(xyz, val, v[2], v[0], v[1], v[6], 1.0, g + 3 * v[2], weight[v[2]]);
        add_corner_gradient(xyz, val, v[6], v[4], v[5], v[2], 1.0, g + 3 * v[6], weight[v[6]]);
      } else if (v[4] == v[5] && v[4] == v[6] && v[4] == v[7]) {  // pyramid_as_hex
        for (int k = 0; k < 4; ++k)
          add_corner_gradient(xyz, val, v[4], v[k], v[(k + 1) % 4], v[(k + 3) % 4], 1.0, g + 3 * v[4], weight[v[4]]);
      }
    }
  }
}

/// Cells per part of a parallel vertex-gradient pass, and at most how many
/// parts: the second accumulates into buffers of its own (16 bytes per
/// vertex while building). Two, not more: 4 parts were 1.2x slower on one
/// thread (component8: the sums of the extra buffers), 2 cost it nothing.
inline constexpr uint64_t gradient_part_cells = uint64_t(1) << 15;
inline constexpr uint64_t gradient_max_parts = 2;

}  // namespace detail

/// Builds the per-vertex gradients of `mesh`'s active array. The cells are
/// cut into two ranges when there are 64K or more (by their count alone),
/// accumulated in parallel, each straight into a buffer of its own (no
/// per-cell or per-corner scratch: first-touch page faults, not
/// arithmetic, were most of the cost of a parallel version with a
/// vertex-to-corner list), then summed per vertex in range order: the same
/// bits on any number of threads. Vertex ids must be valid (validate()
/// first). Thread-safe.
template <int N> VertexGradients build_vertex_gradients(CellMesh<N> const& mesh) {
  uint64_t const nv = mesh.vertex_count(), nc = mesh.cell_count();
  VertexGradients out;
  constexpr float qnan = std::numeric_limits<float>::quiet_NaN();
  if (!mesh.has_values() || nc == 0) {
    out.g_.assign(3 * nv, qnan);
    return out;
  }
  uint64_t const parts = std::clamp<uint64_t>(nc / detail::gradient_part_cells, 1, detail::gradient_max_parts);
  // Part 0 accumulates into the result; parts 1.. into buffers of their own,
  // allocated and zeroed by the task that fills them.
  std::vector<std::vector<float>> g_more(parts - 1), w_more(parts - 1);
  std::vector<float> weight;
  auto accumulate = [&](uint64_t part) {
    uint64_t const begin = nc * part / parts, end = nc * (part + 1) / parts;
    std::vector<float>& g = part == 0 ? out.g_ : g_more[part - 1];
    std::vector<float>& w = part == 0 ? weight : w_more[part - 1];
    detail::resize_zeroed(g, 3 * nv);  // pages mapped in one call (memory.hpp)
    detail::resize_zeroed(w, nv);
    detail::accumulate_vertex_gradients(mesh, begin, end, g.data(), w.data());
  };
  if (parts == 1) {
    accumulate(0);
  } else {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, parts, 1), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t part = r.begin(); part != r.end(); ++part) accumulate(part);
    });
  }
  float* g = out.g_.data();
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, nv, 1 << 14), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t i = r.begin(); i != r.end(); ++i) {
      float w = weight[i];
      for (uint64_t part = 1; part < parts; ++part) {
        w += w_more[part - 1][i];
        for (int a = 0; a < 3; ++a) g[3 * i + uint64_t(a)] += g_more[part - 1][3 * i + uint64_t(a)];
      }
      for (int a = 0; a < 3; ++a) g[3 * i + uint64_t(a)] = w > 0.f ? g[3 * i + uint64_t(a)] / w : qnan;
    }
  });
  return out;
}

}  // namespace cellray
