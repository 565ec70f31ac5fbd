#pragma once
// VTK's linear cells as the kernels' cells (issue #21, first stage).
//
// VTK interpolates a wedge and a pyramid with exactly the trilinear map of a
// hexahedron whose corners repeat: vtkPyramid's shape functions are
// (1-r)(1-s)(1-t), r(1-s)(1-t), rs(1-t), (1-r)s(1-t) and t, the trilinear
// ones with the top quad collapsed onto the apex; vtkWedge's are the
// triangle's barycentrics times (1-t) and t, which the trilinear map with
// one bottom and one top edge collapsed produces (r = v, s = u (1 - v)).
// Geometry and field use the same functions, so the value at every point
// is VTK's, bit for bit in exact arithmetic: a wedge or a pyramid is a
// hexahedron with repeated vertex ids, rendered by the hex kernels, whose
// faces are bilinear patches (a triangle face is a patch with two equal
// corners: the flat triangle). Tetrahedra keep their own, faster kernels.
//
// The price, until wedges and pyramids get kernels of their own: 8 indices
// per cell where 6 or 5 would do, and trilinear inversions where the map is
// simpler. The hex kernels' Newton inversion is singular only at a
// collapsed edge or apex (a set of zero volume).
//
// Polyhedra (VTK 42) are decomposed around one added centre vertex, as
// `foamToVTK -poly-decomp` and ParaView do: a triangle face and the centre
// make a tetrahedron, a quad face and the centre a pyramid; a face of more
// corners is fanned into triangles from its lowest vertex id (the same
// triangles from both cells that share it).

#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "../error.hpp"

namespace cellray {

/// VTK cell type ids of the linear 3D cells.
enum VtkCellType : int { vtk_tetra = 10, vtk_voxel = 11, vtk_hexahedron = 12, vtk_wedge = 13, vtk_pyramid = 14,
                         vtk_polyhedron = 42 };

/// The hexahedron corner order of a wedge (VTK order 0-5: triangle 0 1 2 at
/// the bottom, 3 4 5 above it) and of a pyramid (quad 0 1 2 3, apex 4). The
/// wedge's bottom triangle runs the other way round from a hex's bottom
/// quad (VTK: its normal points away from the top), hence 0 2 1.
inline constexpr std::array<int, 8> wedge_as_hex{0, 2, 1, 1, 3, 5, 4, 4};
inline constexpr std::array<int, 8> pyramid_as_hex{0, 1, 2, 3, 4, 4, 4, 4};
/// A voxel's corners are a pixel grid's: 0 1 3 2 / 4 5 7 6 as a hexahedron.
inline constexpr std::array<int, 8> voxel_as_hex{0, 1, 3, 2, 4, 5, 7, 6};

/// One polyhedron: faces as runs of vertex ids (VTK's face stream without
/// the counts), each face ordered with its normal pointing out of the cell
/// (VTK's convention; the other way round works too, see below).
struct PolyhedronFaces {
  std::vector<uint64_t> ids;      ///< every face's vertex ids, face after face
  std::vector<uint64_t> offsets;  ///< face f is ids[offsets[f], offsets[f+1]); size faces + 1
  size_t face_count() const noexcept { return offsets.empty() ? 0 : offsets.size() - 1; }
};

/// The result of decompose_polyhedron: the centre's position and the cells.
struct PolyhedronSplit {
  glm::dvec3 centre{0.0};
  std::vector<std::array<uint64_t, 4>> tets;   ///< 3 face corners + the centre
  std::vector<std::array<uint64_t, 8>> hexes;  ///< pyramids as collapsed hexes (quad + centre)
};

/// Checks that the faces close (every edge is used by exactly two faces,
/// once in each direction) and that every id is below `vertex_count`.
/// Returns an empty string when they do, else what is wrong (for an error
/// naming the cell).
inline std::string check_polyhedron(PolyhedronFaces const& f, uint64_t vertex_count) {
  size_t const nf = f.face_count();
  if (nf < 4) return "has " + std::to_string(nf) + " faces (a closed polyhedron needs at least 4)";
  std::vector<std::pair<uint64_t, uint64_t>> edges;
  for (size_t i = 0; i < nf; ++i) {
    uint64_t const b = f.offsets[i], e = f.offsets[i + 1];
    if (e < b + 3) return "face " + std::to_string(i) + " has " + std::to_string(e - b) + " vertices (at least 3)";
    for (uint64_t k = b; k < e; ++k) {
      uint64_t const v = f.ids[k], w = f.ids[k + 1 < e ? k + 1 : b];
      if (v >= vertex_count)
        return "face " + std::to_string(i) + " uses vertex id " + std::to_string(v) + ", outside [0, " +
               std::to_string(vertex_count) + ")";
      if (v == w) return "face " + std::to_string(i) + " repeats vertex " + std::to_string(v);
      edges.push_back({v, w});
    }
  }
  // Closed and consistently oriented: each directed edge's reverse appears
  // exactly once. (Either orientation of all faces is accepted.)
  std::sort(edges.begin(), edges.end());
  for (size_t k = 0; k < edges.size(); ++k) {
    if (k + 1 < edges.size() && edges[k] == edges[k + 1])
      return "uses edge " + std::to_string(edges[k].first) + "-" + std::to_string(edges[k].second) +
             " twice in the same direction (faces not consistently oriented)";
    std::pair<uint64_t, uint64_t> const rev{edges[k].second, edges[k].first};
    if (!std::binary_search(edges.begin(), edges.end(), rev))
      return "does not close: edge " + std::to_string(edges[k].first) + "-" + std::to_string(edges[k].second) +
             " belongs to one face only";
  }
  return {};
}

/// Decomposes a closed polyhedron (check_polyhedron) around a centre that
/// gets vertex id `centre_id`: at the volume centroid (OpenFOAM's cell
/// centre, where foamToVTK puts it), computed in double from the faces
/// fanned about the vertex mean. Faces may all point out or all point in;
/// the cells come out positively oriented either way (for a star-shaped
/// polyhedron; a face that the centre does not see makes an inverted cell,
/// as in foamToVTK's output).
/// @param xyz  3 floats per vertex (the mesh's positions).
inline PolyhedronSplit decompose_polyhedron(PolyhedronFaces const& f, float const* xyz, uint64_t centre_id) {
  auto p = [xyz](uint64_t v) { return glm::dvec3(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]); };
  size_t const nf = f.face_count();
  // Vertex mean (of the face corners, each vertex once: ids repeat across faces).
  std::vector<uint64_t> verts(f.ids.begin(), f.ids.end());
  std::sort(verts.begin(), verts.end());
  verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
  glm::dvec3 mean(0.0);
  for (uint64_t v : verts) mean += p(v);
  mean /= double(verts.size());
  // Volume centroid: the signed tets (mean, fan triangle) weighted by volume.
  double volume = 0;
  glm::dvec3 moment(0.0);
  for (size_t i = 0; i < nf; ++i) {
    uint64_t const b = f.offsets[i], e = f.offsets[i + 1];
    glm::dvec3 const a = p(f.ids[b]);
    for (uint64_t k = b + 1; k + 1 < e; ++k) {
      glm::dvec3 const q = p(f.ids[k]), r = p(f.ids[k + 1]);
      double const v6 = glm::dot(a - mean, glm::cross(q - mean, r - mean));
      volume += v6;
      moment += v6 * (mean + a + q + r) * 0.25;
    }
  }
  PolyhedronSplit out;
  out.centre = volume != 0 ? moment / volume : mean;
  // Outward faces give a positive volume: a cell's base must then run the
  // other way (a hex's bottom quad and a tet's first triangle face inward).
  bool const outward = volume > 0;
  for (size_t i = 0; i < nf; ++i) {
    uint64_t const b = f.offsets[i], e = f.offsets[i + 1];
    auto corner = [&](uint64_t k) { return f.ids[outward ? e - 1 - (k - b) : k]; };
    if (e - b == 4) {
      out.hexes.push_back({corner(b), corner(b + 1), corner(b + 2), corner(b + 3), centre_id, centre_id, centre_id,
                           centre_id});
    } else {
      // Fanned from the face's lowest vertex id: the polyhedron on the other
      // side of the face (which lists it in its own rotation) fans it the
      // same way, so the two share every triangle (no gaps, no overlaps).
      uint64_t const n = e - b;
      uint64_t m = b;
      for (uint64_t k = b; k < e; ++k)
        if (corner(k) < corner(m)) m = k;
      auto at = [&](uint64_t j) { return corner(b + (m - b + j) % n); };
      for (uint64_t j = 1; j + 1 < n; ++j) out.tets.push_back({at(0), at(j), at(j + 1), centre_id});
    }
  }
  return out;
}

}  // namespace cellray
