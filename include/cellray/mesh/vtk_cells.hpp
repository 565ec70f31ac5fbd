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
// corners is split into triangles and quads as OpenFOAM splits it
// (face::trianglesQuads, which foamToVTK uses), each then a tetrahedron or a
// pyramid: the same cells as foamToVTK's output, and both cells that share
// a face split it alike (split_face).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
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
/// A tetrahedron's (VTK order 0-3) as a hexahedron: triangle 0 1 2 at the
/// bottom, the top collapsed onto 3. Its trilinear map interpolates
/// linearly, as the tet does (the weights of a point are its barycentric
/// coordinates), and its four faces are triangles that the hexahedron
/// kernels cross as the tet kernel does, bit for bit (cells/hex.hpp):
/// UnstructuredGrid::fold_tets_into_hexes puts a mixed mesh under one BVH.
inline constexpr std::array<int, 8> tet_as_hex{0, 1, 2, 2, 3, 3, 3, 3};
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
  // Each edge as (lower id, higher id * 2 + 1 if it runs downwards): an
  // edge and its reverse sort next to each other. One buffer per thread: a
  // reader checks every polyhedron of a file (a fresh vector, a sort of
  // (from, to) pairs and a binary search per edge were 20% of the
  // snappyHexMesh flange's load).
  thread_local std::vector<std::pair<uint64_t, uint64_t>> edges;
  edges.clear();
  for (size_t i = 0; i < nf; ++i) {
    uint64_t const b = f.offsets[i], e = f.offsets[i + 1];
    if (e < b + 3) return "face " + std::to_string(i) + " has " + std::to_string(e - b) + " vertices (at least 3)";
    for (uint64_t k = b; k < e; ++k) {
      uint64_t const v = f.ids[k], w = f.ids[k + 1 < e ? k + 1 : b];
      if (v >= vertex_count)
        return "face " + std::to_string(i) + " uses vertex id " + std::to_string(v) + ", outside [0, " +
               std::to_string(vertex_count) + ")";
      if (v == w) return "face " + std::to_string(i) + " repeats vertex " + std::to_string(v);
      edges.push_back(v < w ? std::pair{v, w << 1} : std::pair{w, (v << 1) | 1});
    }
  }
  // Closed and consistently oriented: every edge appears exactly twice,
  // once in each direction. (Either orientation of all faces is accepted.)
  std::sort(edges.begin(), edges.end());
  auto const from = [](std::pair<uint64_t, uint64_t> const& k) { return k.second & 1 ? k.second >> 1 : k.first; };
  auto const to = [](std::pair<uint64_t, uint64_t> const& k) { return k.second & 1 ? k.first : k.second >> 1; };
  for (size_t k = 0; k < edges.size(); k += 2) {
    auto const& a = edges[k];
    if (k + 1 == edges.size() || edges[k + 1].first != a.first || edges[k + 1].second >> 1 != a.second >> 1)
      return "does not close: edge " + std::to_string(from(a)) + "-" + std::to_string(to(a)) +
             " belongs to one face only";
    if (edges[k + 1].second == a.second || (k + 2 < edges.size() && edges[k + 2].first == a.first &&
                                            edges[k + 2].second >> 1 == a.second >> 1))
      return "uses edge " + std::to_string(from(a)) + "-" + std::to_string(to(a)) +
             " twice in the same direction (faces not consistently oriented)";
  }
  return {};
}

namespace detail {

/// Scratch of split_polygon, one per thread: a reader splits millions of
/// faces, and fresh vectors per face were most of the split's time.
struct PolygonScratch {
  std::vector<uint64_t> ids;                      // the parts still to cut, one after another
  std::vector<std::pair<size_t, size_t>> todo;    // (offset in ids, corners)
  std::vector<glm::dvec3> edge;
};

/// OpenFOAM's face split (face::split in SPLITQUAD mode, rewritten): a face
/// of more than 4 corners is cut from its corner with the largest interior
/// angle to the corner that best bisects that angle, and both parts are cut
/// again until each is a triangle or a quad. Calls emit(ids, n) for each
/// part (n = 3 or 4) of the n0 corners at `face`, in its rotation. A face
/// of more than `max_split_corners` corners (no mesh generator makes one;
/// the split costs n^2) is fanned from its first corner instead.
inline constexpr size_t max_split_corners = 1024;
template <class Emit> void split_polygon(uint64_t const* face, size_t n0, float const* xyz, Emit const& emit) {
  constexpr double pi = 3.14159265358979323846;
  // Angles this close are a tie, which the first corner (in the canonical
  // order) wins: float positions move an angle by ~1e-7, and a regular
  // polygon, or a side with several hanging nodes, must not be split by
  // that noise (a file's binary and six-digit text copies split alike).
  constexpr double tie = 1e-5;
  auto angle_between = [](glm::dvec3 const& a, glm::dvec3 const& b) {
    return std::acos(std::max(-1.0, std::min(1.0, glm::dot(a, b))));
  };
  if (n0 > max_split_corners) {
    for (size_t j = 1; j + 1 < n0; ++j) {
      uint64_t const tri[3] = {face[0], face[j], face[j + 1]};
      emit(tri, size_t(3));
    }
    return;
  }
  thread_local PolygonScratch scratch;
  std::vector<uint64_t>& ids = scratch.ids;
  std::vector<glm::dvec3>& edge = scratch.edge;
  ids.assign(face, face + n0);
  scratch.todo.assign(1, {size_t(0), n0});
  while (!scratch.todo.empty()) {
    size_t const off = scratch.todo.back().first, n = scratch.todo.back().second;
    scratch.todo.pop_back();
    if (n <= 4) {
      emit(ids.data() + off, n);
      continue;
    }
    auto id = [&](size_t i) { return ids[off + i % n]; };
    auto p = [&](size_t i) {
      uint64_t const v = id(i);
      return glm::dvec3(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]);
    };
    // Area normal from the triangles (corner, next corner, vertex mean).
    glm::dvec3 mean(0.0), normal(0.0);
    for (size_t i = 0; i < n; ++i) mean += p(i);
    mean /= double(n);
    for (size_t i = 0; i < n; ++i) normal += glm::cross(p(i) - mean, p(i + 1) - mean);
    edge.resize(n);  // unit edge i: corner i to i + 1
    for (size_t i = 0; i < n; ++i) {
      glm::dvec3 const e = p(i + 1) - p(i);
      double const len = glm::length(e);
      edge[i] = len > 0 ? e / len : e;
    }
    // The interior angle at each corner: pi -/+ the turn between its edges,
    // + where the turn is against the face's normal (a concave corner).
    size_t start = 0;
    double widest = -1;
    for (size_t i = 0; i < n; ++i) {
      glm::dvec3 const& in = edge[(i + n - 1) % n];
      glm::dvec3 const& next = edge[i];
      double const turn = angle_between(in, next);
      double const interior = glm::dot(glm::cross(next, in), normal) > 0 ? pi + turn : pi - turn;
      if (interior > widest + tie) widest = interior, start = i;
    }
    // The diagonal from `start` nearest to halving its angle (measured from
    // its outgoing edge), among the corners two or more steps away.
    size_t cut = start + 2;
    double best = pi;
    for (size_t k = 2; k + 1 < n; ++k) {
      glm::dvec3 d = p(start + k) - p(start);
      double const len = glm::length(d);
      if (len > 0) d /= len;
      double const off_angle = std::abs(angle_between(d, edge[start]) - widest / 2);
      if (off_angle < best - tie) best = off_angle, cut = start + k;
    }
    // The parts [start, cut] and [cut, start + n], appended; the first is
    // cut first, as OpenFOAM orders them.
    size_t const a = ids.size(), na = cut - start + 1, nb = n - na + 2;
    for (size_t i = start; i <= cut; ++i) ids.push_back(id(i));
    for (size_t i = cut; i <= start + n; ++i) ids.push_back(id(i));
    scratch.todo.push_back({a + na, nb});
    scratch.todo.push_back({a, na});
  }
}

/// Calls emit(ids, n) for each triangle and quad of split_polygon's split
/// of `face` (n0 corners), each in the face's rotation. The split is made
/// on the face in a canonical order -- from its lowest id, towards the
/// lower of that id's neighbours -- so that the two cells sharing the face,
/// which list it in opposite rotations and from any corner, get the same
/// parts, bit for bit (no gaps, no overlaps).
template <class Emit> void for_each_face_part(uint64_t const* face, size_t n0, float const* xyz, Emit const& emit) {
  if (n0 <= 4) {
    emit(face, n0);
    return;
  }
  size_t low = 0;
  for (size_t i = 1; i < n0; ++i)
    if (face[i] < face[low]) low = i;
  bool const forward = face[(low + 1) % n0] < face[(low + n0 - 1) % n0];
  thread_local std::vector<uint64_t> canonical;
  canonical.resize(n0);
  for (size_t i = 0; i < n0; ++i) canonical[i] = face[forward ? (low + i) % n0 : (low + n0 - i) % n0];
  split_polygon(canonical.data(), n0, xyz, [&](uint64_t const* q, size_t n) {
    if (forward) return emit(q, n);
    uint64_t r[4];
    for (size_t i = 0; i < n; ++i) r[i] = q[n - 1 - i];
    emit(static_cast<uint64_t const*>(r), n);
  });
}

}  // namespace detail

/// The triangles and quads a polyhedron's face is cut into
/// (detail::for_each_face_part), each in the face's rotation.
inline std::vector<std::vector<uint64_t>> split_face(std::vector<uint64_t> const& face, float const* xyz) {
  std::vector<std::vector<uint64_t>> parts;
  detail::for_each_face_part(face.data(), face.size(), xyz,
                             [&](uint64_t const* q, size_t n) { parts.emplace_back(q, q + n); });
  return parts;
}

/// Decomposes a closed polyhedron (check_polyhedron) around a centre that
/// gets vertex id `centre_id`: at the volume centroid (OpenFOAM's cell
/// centre, where foamToVTK puts it), computed in double from the faces
/// fanned about the vertex mean. Faces may all point out or all point in;
/// the cells come out positively oriented either way (for a star-shaped
/// polyhedron; a face that the centre does not see makes an inverted cell,
/// as in foamToVTK's output).
/// @param xyz  3 floats per vertex (the mesh's positions).
/// Writes to `out`, reusing its storage (a reader splits every polyhedron
/// of a file).
inline void decompose_polyhedron(PolyhedronFaces const& f, float const* xyz, uint64_t centre_id,
                                 PolyhedronSplit& out) {
  auto p = [xyz](uint64_t v) { return glm::dvec3(xyz[3 * v], xyz[3 * v + 1], xyz[3 * v + 2]); };
  size_t const nf = f.face_count();
  // Vertex mean (of the face corners, each vertex once: ids repeat across faces).
  thread_local std::vector<uint64_t> verts;
  verts.assign(f.ids.begin(), f.ids.end());
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
  out.tets.clear();
  out.hexes.clear();
  out.centre = volume != 0 ? moment / volume : mean;
  // Outward faces give a positive volume: a cell's base must then run the
  // other way (a hex's bottom quad and a tet's first triangle face inward).
  bool const outward = volume > 0;
  thread_local std::vector<uint64_t> face;
  for (size_t i = 0; i < nf; ++i) {
    uint64_t const b = f.offsets[i], e = f.offsets[i + 1];
    auto corner = [&](uint64_t k) { return f.ids[outward ? e - 1 - (k - b) : k]; };
    if (e - b == 3) {
      out.tets.push_back({corner(b), corner(b + 1), corner(b + 2), centre_id});
    } else if (e - b == 4) {
      out.hexes.push_back({corner(b), corner(b + 1), corner(b + 2), corner(b + 3), centre_id, centre_id, centre_id,
                           centre_id});
    } else {
      face.clear();
      for (uint64_t k = b; k < e; ++k) face.push_back(corner(k));
      detail::for_each_face_part(face.data(), face.size(), xyz, [&](uint64_t const* q, size_t n) {
        if (n == 4) out.hexes.push_back({q[0], q[1], q[2], q[3], centre_id, centre_id, centre_id, centre_id});
        else out.tets.push_back({q[0], q[1], q[2], centre_id});
      });
    }
  }
}

inline PolyhedronSplit decompose_polyhedron(PolyhedronFaces const& f, float const* xyz, uint64_t centre_id) {
  PolyhedronSplit out;
  decompose_polyhedron(f, xyz, centre_id, out);
  return out;
}

}  // namespace cellray
