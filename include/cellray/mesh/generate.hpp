#pragma once
// Generated unstructured meshes: the built-in default scene and a source of
// test meshes of any size. A lattice over [-1,1]^3 whose interior vertices are
// jittered (so no face is axis-aligned and hex faces are not planar), carrying
// an analytic scalar field with nested isosurfaces.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "cell_mesh.hpp"

namespace cellray {

/// The generated field at `p`, in about [0, 1]: three Gaussian blobs (nested
/// isosurfaces around 0.2 to 0.8) plus a weak wave. `time` moves the blobs,
/// so `field_t1` is a second time step over the same geometry.
inline float analytic_field(glm::vec3 p, float time = 0.f) {
  glm::vec3 const c1(-0.35f + 0.15f * time, -0.2f, 0.1f);
  glm::vec3 const c2(0.4f, 0.3f - 0.1f * time, -0.25f);
  glm::vec3 const c3(0.05f, 0.45f, 0.5f - 0.2f * time);
  auto blob = [&](glm::vec3 c, float r2) { return std::exp(-glm::dot(p - c, p - c) / r2); };
  float f = 0.6f * blob(c1, 0.35f) + 0.55f * blob(c2, 0.25f) + 0.45f * blob(c3, 0.15f);
  f += 0.08f * std::sin(3.f * p.x + time) * std::sin(2.5f * p.y) * std::cos(2.f * p.z);
  return f + 0.1f;
}

/// An owning generated mesh; `mesh()` is the view (arrays "field", "field_t1").
template <int Corners> struct GeneratedMesh {
  std::vector<float> xyz;        ///< 3 floats per vertex
  std::vector<uint32_t> cells;   ///< Corners ids per cell (VTK order)
  std::vector<float> field;      ///< analytic_field(p, 0) per vertex
  std::vector<float> field_t1;   ///< analytic_field(p, 1) per vertex
  int lattice = 0;               ///< lattice cells per axis

  CellMesh<Corners> mesh() const {
    CellMesh<Corners> m{view(xyz), view(cells), view(field), "field"};
    m.add_array("field_t1", view(field_t1));
    return m;
  }
};

namespace detail {

/// splitmix64: a fixed, platform-independent sequence (std distributions vary).
inline uint64_t mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
inline float unit_random(uint64_t seed, uint64_t i) {  // in [-0.5, 0.5)
  return float(mix64(seed * 0x100000001b3ull + i) >> 40) / float(1 << 24) - 0.5f;
}

template <int Corners>
GeneratedMesh<Corners> generate_lattice(int n, uint64_t seed, float jitter) {
  GeneratedMesh<Corners> g;
  g.lattice = n;
  int const p = n + 1;
  float const h = 2.f / float(n);
  g.xyz.resize(size_t(p) * p * p * 3);
  for (int k = 0; k < p; ++k)
    for (int j = 0; j < p; ++j)
      for (int i = 0; i < p; ++i) {
        size_t const v = (size_t(k) * p + j) * p + i;
        int const ijk[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          // Boundary vertices move only within their boundary plane, so the
          // domain stays the cube [-1,1]^3.
          bool const on_boundary = ijk[a] == 0 || ijk[a] == n;
          float const d = on_boundary ? 0.f : jitter * h * unit_random(seed, v * 3 + size_t(a));
          g.xyz[v * 3 + size_t(a)] = -1.f + h * float(ijk[a]) + d;
        }
      }
  g.field.resize(g.xyz.size() / 3);
  g.field_t1.resize(g.xyz.size() / 3);
  for (size_t v = 0; v < g.field.size(); ++v) {
    glm::vec3 const q(g.xyz[3 * v], g.xyz[3 * v + 1], g.xyz[3 * v + 2]);
    g.field[v] = analytic_field(q, 0.f);
    g.field_t1[v] = analytic_field(q, 1.f);
  }
  auto id = [p](int i, int j, int k) { return uint32_t((size_t(k) * p + j) * p + i); };
  g.cells.reserve(size_t(n) * n * n * (Corners == 8 ? 8 : 24));
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        uint32_t const c[8] = {id(i, j, k),         id(i + 1, j, k),         id(i + 1, j + 1, k),
                               id(i, j + 1, k),     id(i, j, k + 1),         id(i + 1, j, k + 1),
                               id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)};
        if constexpr (Corners == 8) {
          g.cells.insert(g.cells.end(), c, c + 8);
        } else {
          // Freudenthal split along the 0-6 diagonal: the same in every lattice
          // cell, hence conforming; each tet is a path 0 -> 6 through the cube.
          static constexpr int paths[6][2] = {{1, 2}, {1, 5}, {3, 2}, {3, 7}, {4, 5}, {4, 7}};
          for (auto const& path : paths) {
            uint32_t t[4] = {c[0], c[path[0]], c[path[1]], c[6]};
            // Orient positively: (v1-v0) x (v2-v0) . (v3-v0) > 0.
            auto pos = [&](uint32_t v) { return glm::vec3(g.xyz[3 * v], g.xyz[3 * v + 1], g.xyz[3 * v + 2]); };
            glm::vec3 const a = pos(t[1]) - pos(t[0]), b = pos(t[2]) - pos(t[0]), e = pos(t[3]) - pos(t[0]);
            if (glm::dot(glm::cross(a, b), e) < 0.f) std::swap(t[1], t[2]);
            g.cells.insert(g.cells.end(), t, t + 4);
          }
        }
      }
  return g;
}

}  // namespace detail

/// About `target_cells` tetrahedra (6 per lattice cell, at least 6),
/// positively oriented, conforming. `jitter` is the largest vertex offset as
/// a fraction of the lattice spacing (0 = regular lattice; up to 0.3 keeps
/// every tet positively oriented).
inline GeneratedMesh<4> generate_tets(uint64_t target_cells, uint64_t seed = 1, float jitter = 0.3f) {
  int const n = std::max(1, int(std::lround(std::cbrt(double(target_cells) / 6.0))));
  return detail::generate_lattice<4>(n, seed, jitter);
}

/// About `target_cells` hexahedra (VTK node order), faces not planar.
inline GeneratedMesh<8> generate_hexes(uint64_t target_cells, uint64_t seed = 1, float jitter = 0.3f) {
  int const n = std::max(1, int(std::lround(std::cbrt(double(target_cells)))));
  return detail::generate_lattice<8>(n, seed, jitter);
}

namespace detail {
/// The hexahedron `c` (8 ids, VTK order) split along its 0-2-6-4 diagonal
/// plane into two wedges, as collapsed hexahedra: (0 1 2 2 4 5 6 6) and
/// (0 2 3 3 4 6 7 7), appended to `cells`.
inline void append_wedge_split(uint32_t const* c, std::vector<uint32_t>& cells) {
  uint32_t const a[8] = {c[0], c[1], c[2], c[2], c[4], c[5], c[6], c[6]};
  uint32_t const b[8] = {c[0], c[2], c[3], c[3], c[4], c[6], c[7], c[7]};
  cells.insert(cells.end(), a, a + 8);
  cells.insert(cells.end(), b, b + 8);
}
}  // namespace detail

/// A conforming mesh of the hexahedron family, every cell as 8 corner ids
/// (wedges and pyramids as collapsed hexahedra, as the readers give them,
/// mesh/vtk_cells.hpp): the jittered lattice of generate_hexes with every
/// other column of cells ((i + j) even) split along its 0-2-6-4 diagonal
/// plane into two wedges, (0 1 2 2 4 5 6 6) and (0 2 3 3 4 6 7 7), and a
/// pyramid on the top face of each unsplit top cell, its apex half a
/// lattice spacing above the face's centre. Wedge ends meet wedge ends,
/// quads meet quads. About `target_cells` lattice cells (more cells after
/// the splits).
inline GeneratedMesh<8> generate_hex_family(uint64_t target_cells, uint64_t seed = 1, float jitter = 0.3f) {
  GeneratedMesh<8> g = generate_hexes(target_cells, seed, jitter);
  int const n = g.lattice;
  float const h = 2.f / float(n);
  std::vector<uint32_t> cells;
  cells.reserve(g.cells.size() * 2);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        uint32_t const* c = g.cells.data() + 8 * ((size_t(k) * size_t(n) + size_t(j)) * size_t(n) + size_t(i));
        if ((i + j) % 2 == 0) {
          detail::append_wedge_split(c, cells);
          continue;
        }
        cells.insert(cells.end(), c, c + 8);
        if (k + 1 < n) continue;
        glm::vec3 apex(0.f);
        for (int q = 4; q < 8; ++q) apex += 0.25f * glm::vec3(g.xyz[3 * c[q]], g.xyz[3 * c[q] + 1], g.xyz[3 * c[q] + 2]);
        apex.z += 0.5f * h;
        auto const v = uint32_t(g.xyz.size() / 3);
        g.xyz.insert(g.xyz.end(), {apex.x, apex.y, apex.z});
        g.field.push_back(analytic_field(apex, 0.f));
        g.field_t1.push_back(analytic_field(apex, 1.f));
        uint32_t const pyr[8] = {c[4], c[5], c[6], c[7], v, v, v, v};
        cells.insert(cells.end(), pyr, pyr + 8);
      }
  g.cells = std::move(cells);
  return g;
}

/// Wedges only, as collapsed hexahedra (mesh/vtk_cells.hpp): every cell of
/// generate_hexes' jittered lattice split along its 0-2-6-4 diagonal plane
/// into (0 1 2 2 4 5 6 6) and (0 2 3 3 4 6 7 7), as generate_hex_family's
/// split columns. About `target_cells` wedges.
inline GeneratedMesh<8> generate_wedges(uint64_t target_cells, uint64_t seed = 1, float jitter = 0.3f) {
  GeneratedMesh<8> g = generate_hexes((target_cells + 1) / 2, seed, jitter);
  std::vector<uint32_t> cells;
  cells.reserve(g.cells.size() * 2);
  for (size_t h = 0; h < g.cells.size(); h += 8) detail::append_wedge_split(g.cells.data() + h, cells);
  g.cells = std::move(cells);
  return g;
}

/// Pyramids only, as collapsed hexahedra (b0 b1 b2 b3 apex x4): every cell
/// of generate_hexes' jittered lattice split into six around an added
/// vertex at its corners' mean (the field there analytic, as at the
/// lattice's), one per face, each base turned to face its apex (positively
/// oriented, as VTK's pyramid). About `target_cells` pyramids.
inline GeneratedMesh<8> generate_pyramids(uint64_t target_cells, uint64_t seed = 1, float jitter = 0.3f) {
  GeneratedMesh<8> g = generate_hexes((target_cells + 5) / 6, seed, jitter);
  // VTK hexahedron faces with their corners listed so the base's normal
  // (right hand) points into the cell, towards the centre.
  static constexpr int base[6][4] = {{0, 1, 2, 3}, {4, 7, 6, 5}, {0, 4, 5, 1}, {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 5, 6, 2}};
  std::vector<uint32_t> cells;
  cells.reserve(g.cells.size() * 6);
  for (size_t h = 0; h < g.cells.size(); h += 8) {
    uint32_t const* c = g.cells.data() + h;
    glm::vec3 centre(0.f);
    for (int k = 0; k < 8; ++k) centre += 0.125f * glm::vec3(g.xyz[3 * c[k]], g.xyz[3 * c[k] + 1], g.xyz[3 * c[k] + 2]);
    auto const v = uint32_t(g.xyz.size() / 3);
    g.xyz.insert(g.xyz.end(), {centre.x, centre.y, centre.z});
    g.field.push_back(analytic_field(centre, 0.f));
    g.field_t1.push_back(analytic_field(centre, 1.f));
    for (auto const& f : base) {
      uint32_t const pyr[8] = {c[f[0]], c[f[1]], c[f[2]], c[f[3]], v, v, v, v};
      cells.insert(cells.end(), pyr, pyr + 8);
    }
  }
  g.cells = std::move(cells);
  return g;
}

}  // namespace cellray
