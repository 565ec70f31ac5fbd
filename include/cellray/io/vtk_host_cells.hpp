#pragma once
// split_vtk_cells: a host's cells in VTK 9's layout (vtkCellArray's offsets
// and connectivity, vtkUnstructuredGrid's cell types) as the index arrays
// the kernels read, for TetMesh / HexMesh views over the host's own points
// and point arrays (nothing but the indices is copied).
//
// The kernels read homogeneous cells: 4 ids per tetrahedron, 8 per
// hexahedron with wedges, pyramids and voxels as hexahedra (mesh/
// vtk_cells.hpp), so a mixed mesh becomes a tet part and a hex part over the
// same points, split exactly as the file readers split one. A mesh of
// tetrahedra only (or hexahedra only) needs no split: its connectivity is
// already the index array, and a view of it copies nothing.
//
// Polyhedra (VTK 42) need their faces (either of VTK 9's layouts) and the
// points: each becomes tetrahedra and pyramids around a new centre point,
// exactly as the readers split a file's (io/polyhedra.hpp), so the host's
// points and point arrays gain one entry per polyhedron.

#include <algorithm>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../error.hpp"
#include "../mesh/span.hpp"
#include "detail.hpp"
#include "grid.hpp"
#include "polyhedra.hpp"

namespace cellray {

/// What split_vtk_cells returns: index arrays for TetMesh / HexMesh views,
/// and for each of their cells the host cell it came from (to carry cell
/// data along), in host order; the cells of split polyhedra come last.
struct SplitCells {
  std::vector<uint32_t> tets;        ///< 4 point ids per tetrahedron (VTK order)
  std::vector<uint32_t> hexes;       ///< 8 per hexahedron (wedges, pyramids, voxels: mesh/vtk_cells.hpp)
  std::vector<uint64_t> tet_cells;   ///< host cell id of each tetrahedron
  std::vector<uint64_t> hex_cells;   ///< host cell id of each hexahedron
  uint64_t point_count = 0;          ///< the host's points
  /// Polyhedra only: the centre point of polyhedron k is point
  /// point_count + k, at centres[3k, 3k + 3), split from host cell
  /// polyhedron_cells[k]. Empty without polyhedra.
  std::vector<float> centres;
  std::vector<uint64_t> polyhedron_cells;
  ReadReport report;                 ///< cells per VTK type, skipped and reduced to linear ones, polyhedra split
};

namespace io {
template <class T> constexpr NumType num_type_of() {
  if constexpr (std::is_same_v<T, uint8_t>) return NumType::u8;
  else if constexpr (std::is_same_v<T, int32_t>) return NumType::i32;
  else if constexpr (std::is_same_v<T, uint32_t>) return NumType::u32;
  else if constexpr (std::is_same_v<T, int64_t>) return NumType::i64;
  else {
    static_assert(std::is_same_v<T, uint64_t>, "cell arrays of uint8, int32, uint32, int64 or uint64");
    return NumType::u64;
  }
}
template <class T> NumArray viewing_span(Span<T> s) {
  return NumArray::viewing(num_type_of<std::remove_cv_t<T>>(), s.size, reinterpret_cast<unsigned char const*>(s.data),
                           false);
}
}  // namespace io

/// The faces of a host's polyhedra as VTK 9.0-9.3 hold them
/// (vtkUnstructuredGrid::GetFaces / GetFaceLocations; a .vtu's `faces`
/// stream): cell c's face stream `[nfaces, n0, ids..., n1, ids..., ...]`
/// starts at faces[locations[c]]; -1 for a cell that is no polyhedron.
template <class Location, class Id> struct FaceStreams {
  Span<Location> locations;  ///< one per cell
  Span<Id> faces;
};

/// The faces of a host's polyhedra as VTK 9.4 holds them, each vtkCellArray
/// as its offsets and connectivity: GetPolyhedronFaces (face f's point ids
/// are face_points[face_offsets[f], face_offsets[f + 1])) and
/// GetPolyhedronFaceLocations (cell c's face ids are
/// cell_faces[cell_face_offsets[c], cell_face_offsets[c + 1]), none for a
/// cell that is no polyhedron).
template <class FaceOffset, class FacePoint, class CellFaceOffset, class CellFace> struct FaceCellArrays {
  Span<FaceOffset> face_offsets;
  Span<FacePoint> face_points;
  Span<CellFaceOffset> cell_face_offsets;  ///< one more than the cells
  Span<CellFace> cell_faces;
};

namespace io {

inline std::string host_cell(uint64_t c) { return "split_vtk_cells: cell " + std::to_string(c) + ": "; }

/// The shared part of split_vtk_cells: the cells into `grid` (its tets and
/// hexes), checked; the kind of each cell (build_cells).
template <class Type, class Offset, class Id>
CellKinds split_host_cells(Span<Type> types, Span<Offset> offsets, Span<Id> connectivity, uint64_t point_count,
                           ReadOptions const& opts, bool polyhedra, UnstructuredGrid& grid) {
  uint64_t const ncells = types.size;
  if (offsets.size != ncells + 1)
    throw InvalidMesh("split_vtk_cells: " + std::to_string(ncells) + " cell types need " + std::to_string(ncells + 1) +
                      " offsets, got " + std::to_string(offsets.size));
  if (!point_count_fits(point_count))
    throw InvalidMesh("split_vtk_cells: " + std::to_string(point_count) + " points: ids are 32-bit (at most 2^32-1 points)");
  for (uint64_t c = 0; c < ncells; ++c) {
    int64_t const b = int64_t(offsets[c]), e = int64_t(offsets[c + 1]);
    if (b < 0 || e < b || uint64_t(e) > connectivity.size)
      throw InvalidMesh(host_cell(c) + "offsets [" + std::to_string(b) + ", " + std::to_string(e) +
                        ") do not lie in the connectivity's " + std::to_string(connectivity.size) + " ids");
  }
  NumArray const t = viewing_span(types), conn = viewing_span(connectivity);
  CellLocator where;
  where.type = [](uint64_t c) { return host_cell(c); };
  where.conn = [](uint64_t k) { return "split_vtk_cells: connectivity[" + std::to_string(k) + "]: "; };
  grid.report.file = "host cells";
  grid.report.format = "VTK 9 cell arrays";
  try {
    return build_cells(
        ncells, t, conn,
        [&offsets](uint64_t c) { return std::pair<uint64_t, uint64_t>(uint64_t(offsets[c]), uint64_t(offsets[c + 1])); },
        point_count, opts, grid, where, polyhedra);
  } catch (IoError const& e) {
    throw InvalidMesh(e.what());  // the host's arrays, not a file
  }
}

/// The split's result from `grid` (whose cells after the host's own came
/// from polyhedra: each has its polyhedron's centre, point_count + k, as
/// its largest id).
inline SplitCells split_result(UnstructuredGrid& grid, CellKinds const& kinds, uint64_t point_count,
                               std::vector<uint64_t> polyhedron_cells) {
  SplitCells out;
  out.tets = std::move(grid.tets);
  out.hexes = std::move(grid.hexes);
  out.report = std::move(grid.report);
  out.point_count = point_count;
  if (grid.xyz.size() > 3 * point_count) out.centres.assign(grid.xyz.begin() + long(3 * point_count), grid.xyz.end());
  out.tet_cells.reserve(out.tets.size() / 4);
  out.hex_cells.reserve(out.hexes.size() / 8);
  for (uint64_t c = 0; c < kinds.size(); ++c) {
    if (kinds[c] == 0) out.tet_cells.push_back(c);
    else if (kinds[c] == 1) out.hex_cells.push_back(c);
  }
  auto centre_of = [&](uint32_t const* v, int n) { return *std::max_element(v, v + n) - point_count; };
  for (uint64_t i = out.tet_cells.size(); i < out.tets.size() / 4; ++i)
    out.tet_cells.push_back(polyhedron_cells[centre_of(out.tets.data() + 4 * i, 4)]);
  for (uint64_t i = out.hex_cells.size(); i < out.hexes.size() / 8; ++i)
    out.hex_cells.push_back(polyhedron_cells[centre_of(out.hexes.data() + 8 * i, 8)]);
  out.polyhedron_cells = std::move(polyhedron_cells);
  return out;
}

/// Splits the polyhedra of `kinds` (kind 3), whose face streams `plan`
/// locates in `faces`, around centres appended to a copy of the host's
/// points (transient: 12 bytes per point).
inline SplitCells split_host_polyhedra(UnstructuredGrid& grid, CellKinds const& kinds, Span<float> points,
                                uint64_t point_count, NumArray const& faces, PolyPlan const& plan, bool whole) {
  grid.xyz.assign(points.begin(), points.end());  // into reserve_split's room
  if (PolySplitError const e = split_polyhedra(grid, faces, plan, {}, whole)) {
    if (e.too_many) throw InvalidMesh("split_vtk_cells: the polyhedra's centre points pass 2^32 - 1 points");
    throw InvalidMesh("split_vtk_cells: polyhedron cell " + std::to_string(plan.polys[e.at].cell) +
                      e.what);
  }
  std::vector<uint64_t> cells(plan.polys.size());
  for (size_t k = 0; k < cells.size(); ++k) cells[k] = plan.polys[k].cell;
  return split_result(grid, kinds, point_count, std::move(cells));
}

/// Reserves `grid`'s arrays for the host's cells and what the polyhedra of
/// `plan` add (at most), before any is stored, so that the split appends
/// without copying them (on the flange no faster: the time is the split's
/// own work and the output's first-write faults).
inline void reserve_split(UnstructuredGrid& grid, NumArray const& types, NumArray const& faces, PolyPlan& plan,
                          uint64_t point_count) {
  count_polyhedron_cells(faces, plan);
  FileCellCounts const n = count_file_cells(types);
  grid.tets.reserve(4 * (n.tets + plan.new_tets()));
  grid.hexes.reserve(8 * (n.hexes + plan.new_hexes()));
  grid.xyz.reserve(3 * (point_count + plan.polys.size()));
}

inline void check_points(Span<float> points) {
  if (points.size % 3 != 0)
    throw InvalidMesh("split_vtk_cells: " + std::to_string(points.size) +
                      " coordinates are not 3 per point (x, y, z floats)");
}

}  // namespace io

/// Splits `types.size` cells -- cell c has VTK type `types[c]` and point ids
/// `connectivity[offsets[c], offsets[c + 1])` -- into tetrahedra and
/// hexahedra, as the file readers do: quadratic and higher-order cells keep
/// their corners; a cell with repeated ids is the shape it really is.
/// Polyhedra (42), 2D and other cells are an error naming the first, or
/// with `opts.skip_unsupported_cells` a counted skip (polyhedra need their
/// faces and points: the overloads below). Parallel (TBB) over the cells.
/// @throws InvalidMesh naming the cell and the problem: offsets that
///         decrease or run past the connectivity, a point id outside
///         [0, point_count), too few ids for the type, an unknown type, a
///         cell with fewer than 4 distinct points.
template <class Type, class Offset, class Id>
SplitCells split_vtk_cells(Span<Type> types, Span<Offset> offsets, Span<Id> connectivity, uint64_t point_count,
                           ReadOptions const& opts = {}) {
  UnstructuredGrid grid;
  io::CellKinds const kinds = io::split_host_cells(types, offsets, connectivity, point_count, opts, false, grid);
  return io::split_result(grid, kinds, point_count, {});
}

/// As above, with polyhedra (VTK 42) split as the file readers split them
/// (io/polyhedra.hpp): tetrahedra and pyramids around one centre point per
/// polyhedron, its volume centroid. The centres are new points: the views
/// need the host's points followed by `SplitCells::centres`, and each point
/// array followed by polyhedron_centre_values (below). `points`: 3 floats
/// per point. Faces in VTK 9.0-9.3's layout.
/// @throws InvalidMesh as above, and for a polyhedron's faces: a location
///         outside the faces, a stream that ends early, a face of fewer than
///         3 points, a point id out of range, faces that do not close
///         (every edge used by exactly two faces), naming the cell.
template <class Type, class Offset, class Id, class Location, class FaceId>
SplitCells split_vtk_cells(Span<Type> types, Span<Offset> offsets, Span<Id> connectivity, Span<float> points,
                           FaceStreams<Location, FaceId> const& faces, ReadOptions const& opts = {}) {
  io::check_points(points);
  uint64_t const point_count = points.size / 3;
  if (faces.locations.size != types.size)
    throw InvalidMesh("split_vtk_cells: " + std::to_string(types.size) + " cells need as many face locations, got " +
                      std::to_string(faces.locations.size));
  io::PolyPlan plan;
  for (uint64_t c = 0; c < types.size; ++c) {
    if (int64_t(types[c]) != vtk_polyhedron) continue;
    int64_t const at = int64_t(faces.locations[c]);
    if (at < 0 || uint64_t(at) >= faces.faces.size)
      throw InvalidMesh("split_vtk_cells: polyhedron cell " + std::to_string(c) + " has face location " +
                        std::to_string(at) + " outside the " + std::to_string(faces.faces.size) + " face entries");
    plan.polys.push_back({c, uint64_t(at), faces.faces.size});
  }
  io::NumArray const all = io::viewing_span(faces.faces);
  UnstructuredGrid grid;
  io::reserve_split(grid, io::viewing_span(types), all, plan, point_count);
  io::CellKinds const kinds = io::split_host_cells(types, offsets, connectivity, point_count, opts, true, grid);
  return io::split_host_polyhedra(grid, kinds, points, point_count, all, plan, false);
}

/// As above, faces in VTK 9.4's layout (FaceCellArrays).
template <class Type, class Offset, class Id, class FaceOffset, class FacePoint, class CellFaceOffset, class CellFace>
SplitCells split_vtk_cells(Span<Type> types, Span<Offset> offsets, Span<Id> connectivity, Span<float> points,
                           FaceCellArrays<FaceOffset, FacePoint, CellFaceOffset, CellFace> const& faces,
                           ReadOptions const& opts = {}) {
  io::check_points(points);
  uint64_t const point_count = points.size / 3;
  if (faces.cell_face_offsets.size != types.size + 1)
    throw InvalidMesh("split_vtk_cells: " + std::to_string(types.size) + " cells need " +
                      std::to_string(types.size + 1) + " cell face offsets, got " +
                      std::to_string(faces.cell_face_offsets.size));
  uint64_t const nfaces = faces.face_offsets.size ? faces.face_offsets.size - 1 : 0;
  // Each polyhedron's faces as one stream of VTK 9.0's layout (transient),
  // so that both layouts are checked and split by the same code.
  std::vector<int64_t> stream;
  io::PolyPlan plan;
  for (uint64_t c = 0; c < types.size; ++c) {
    if (int64_t(types[c]) != vtk_polyhedron) continue;
    int64_t const b = int64_t(faces.cell_face_offsets[c]), e = int64_t(faces.cell_face_offsets[c + 1]);
    if (b < 0 || e < b || uint64_t(e) > faces.cell_faces.size)
      throw InvalidMesh("split_vtk_cells: polyhedron cell " + std::to_string(c) + ": cell face offsets [" +
                        std::to_string(b) + ", " + std::to_string(e) + ") do not lie in the " +
                        std::to_string(faces.cell_faces.size) + " cell faces");
    uint64_t const begin = stream.size();
    stream.push_back(e - b);
    for (int64_t j = b; j < e; ++j) {
      int64_t const f = int64_t(faces.cell_faces[uint64_t(j)]);
      int64_t const fb = f >= 0 && uint64_t(f) < nfaces ? int64_t(faces.face_offsets[uint64_t(f)]) : -1;
      int64_t const fe = fb >= 0 ? int64_t(faces.face_offsets[uint64_t(f) + 1]) : -1;
      if (fb < 0 || fe < fb || uint64_t(fe) > faces.face_points.size)
        throw InvalidMesh("split_vtk_cells: polyhedron cell " + std::to_string(c) + " names face " +
                          std::to_string(f) + ", which is not one of the " + std::to_string(nfaces) +
                          " faces or whose offsets do not lie in the face points");
      stream.push_back(fe - fb);
      for (int64_t q = fb; q < fe; ++q) stream.push_back(int64_t(faces.face_points[uint64_t(q)]));
    }
    plan.polys.push_back({c, begin, stream.size()});
  }
  io::NumArray const all = io::viewing_span(Span<int64_t>(stream));
  UnstructuredGrid grid;
  io::reserve_split(grid, io::viewing_span(types), all, plan, point_count);
  io::CellKinds const kinds = io::split_host_cells(types, offsets, connectivity, point_count, opts, true, grid);
  return io::split_host_polyhedra(grid, kinds, points, point_count, all, plan, true);
}

/// The values of a point array at the split's centre points (point
/// point_count + k for polyhedron k), as the file readers set them: the
/// polyhedron's own value where the host has one (`cell_values`, one per
/// host cell, foamToVTK's choice for a quantity it holds per cell), else
/// the mean of its points' values.
template <class T>
std::vector<float> polyhedron_centre_values(SplitCells const& s, Span<T> point_values, Span<T> cell_values = {}) {
  uint64_t const npoly = s.polyhedron_cells.size();
  std::vector<float> out(npoly);
  if (!cell_values.empty()) {
    for (uint64_t k = 0; k < npoly; ++k) out[k] = float(cell_values[s.polyhedron_cells[k]]);
    return out;
  }
  // A polyhedron's cells come in its order within the tets and within the
  // hexes, after the host's own cells: a piece's largest id is its centre,
  // point_count + k, and its ids below point_count are its points. Blocks
  // of polyhedra in parallel, each finding its first pieces by bisection.
  uint64_t const np = s.point_count;
  auto centre_of = [](std::vector<uint32_t> const& ids, int n, uint64_t i) {
    return uint64_t(*std::max_element(ids.data() + uint64_t(n) * i, ids.data() + uint64_t(n) * (i + 1)));
  };
  // The first piece whose centre is point `centre` or a later one.
  auto first_piece = [&](std::vector<uint32_t> const& ids, int n, uint64_t centre) {
    uint64_t lo = 0, hi = ids.size() / uint64_t(n);
    while (lo < hi) {
      uint64_t const mid = lo + (hi - lo) / 2;
      // The host's cells (all ids below np) come first: order them as centre np - 1.
      if (std::max(centre_of(ids, n, mid), np - 1) < centre) lo = mid + 1;
      else hi = mid;
    }
    return lo;
  };
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, npoly, 64), [&](tbb::blocked_range<uint64_t> const& r) {
    uint64_t ti = first_piece(s.tets, 4, np + r.begin()), hi = first_piece(s.hexes, 8, np + r.begin());
    std::vector<uint64_t> verts;
    for (uint64_t k = r.begin(); k < r.end(); ++k) {
      verts.clear();
      auto take = [&](std::vector<uint32_t> const& ids, int n, uint64_t& i) {
        for (; i < ids.size() / uint64_t(n) && centre_of(ids, n, i) == np + k; ++i)
          for (int q = 0; q < n; ++q)
            if (uint32_t const v = ids[uint64_t(n) * i + uint64_t(q)]; v < np) verts.push_back(v);
      };
      take(s.tets, 4, ti);
      take(s.hexes, 8, hi);
      std::sort(verts.begin(), verts.end());
      verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
      double sum = 0;
      for (uint64_t v : verts) sum += double(point_values[v]);
      out[k] = float(sum / double(verts.size()));
    }
  });
  return out;
}

}  // namespace cellray
