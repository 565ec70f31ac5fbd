#pragma once
// UnstructuredGrid: what the mesh readers return. It owns the arrays that
// TetMesh / HexMesh views point at, plus a report of what was read, reduced,
// skipped or ignored.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "../error.hpp"
#include "../mesh/cell_mesh.hpp"
#include "../mesh/span.hpp"
#include "../mesh/vtk_cells.hpp"

namespace cellray {

/// What the readers may do beyond the defaults.
struct ReadOptions {
  /// Cells other than tetrahedra and hexahedra (and their quadratic and
  /// higher-order forms, read as their corner cells) are an error naming the
  /// type and count. When true they are dropped instead, with their cell-array
  /// values, and counted in `ReadReport::cells_skipped`.
  bool skip_unsupported_cells = false;
};

/// One per-vertex array, converted to float whatever the file stored.
/// Arrays with several components (vectors, tensors) keep their Euclidean
/// magnitude per vertex under the array's own name (`components` says how many
/// the file had); the report says so too.
struct PointArray {
  std::string name;
  int components = 1;         ///< components in the file (values hold 1 per vertex)
  std::vector<float> values;  ///< one per vertex; NaN/inf kept as read
};

/// One per-cell array, split like the cells: one value per kept tetrahedron
/// (in `UnstructuredGrid::tets` order) and one per kept hexahedron. Values of
/// skipped cells are dropped. Multi-component arrays keep their magnitude.
struct CellArray {
  std::string name;
  int components = 1;
  std::vector<float> tet_values;  ///< one per kept tet
  std::vector<float> hex_values;  ///< one per kept hex
};

/// VTK's name for a VTK cell type id ("tetra", "wedge", "quadratic_tetra"...),
/// or "unknown" for an id VTK does not define.
inline char const* vtk_cell_type_name(int type) noexcept {
  switch (type) {
    case 0: return "empty_cell";
    case 1: return "vertex";
    case 2: return "poly_vertex";
    case 3: return "line";
    case 4: return "poly_line";
    case 5: return "triangle";
    case 6: return "triangle_strip";
    case 7: return "polygon";
    case 8: return "pixel";
    case 9: return "quad";
    case 10: return "tetra";
    case 11: return "voxel";
    case 12: return "hexahedron";
    case 13: return "wedge";
    case 14: return "pyramid";
    case 15: return "pentagonal_prism";
    case 16: return "hexagonal_prism";
    case 21: return "quadratic_edge";
    case 22: return "quadratic_triangle";
    case 23: return "quadratic_quad";
    case 24: return "quadratic_tetra";
    case 25: return "quadratic_hexahedron";
    case 26: return "quadratic_wedge";
    case 27: return "quadratic_pyramid";
    case 28: return "biquadratic_quad";
    case 29: return "triquadratic_hexahedron";
    case 30: return "quadratic_linear_quad";
    case 31: return "quadratic_linear_wedge";
    case 32: return "biquadratic_quadratic_wedge";
    case 33: return "biquadratic_quadratic_hexahedron";
    case 34: return "biquadratic_triangle";
    case 35: return "cubic_line";
    case 36: return "quadratic_polygon";
    case 37: return "triquadratic_pyramid";
    case 41: return "convex_point_set";
    case 42: return "polyhedron";
    case 51: return "parametric_curve";
    case 52: return "parametric_surface";
    case 53: return "parametric_tri_surface";
    case 54: return "parametric_quad_surface";
    case 55: return "parametric_tetra_region";
    case 56: return "parametric_hex_region";
    case 60: return "higher_order_edge";
    case 61: return "higher_order_triangle";
    case 62: return "higher_order_quad";
    case 63: return "higher_order_polygon";
    case 64: return "higher_order_tetrahedron";
    case 65: return "higher_order_wedge";
    case 66: return "higher_order_pyramid";
    case 67: return "higher_order_hexahedron";
    case 68: return "lagrange_curve";
    case 69: return "lagrange_triangle";
    case 70: return "lagrange_quadrilateral";
    case 71: return "lagrange_tetrahedron";
    case 72: return "lagrange_hexahedron";
    case 73: return "lagrange_wedge";
    case 74: return "lagrange_pyramid";
    case 75: return "bezier_curve";
    case 76: return "bezier_triangle";
    case 77: return "bezier_quadrilateral";
    case 78: return "bezier_tetrahedron";
    case 79: return "bezier_hexahedron";
    case 80: return "bezier_wedge";
    case 81: return "bezier_pyramid";
    default: return "unknown";
  }
}

/// What a reader did with a file. Everything not read is listed, nothing is
/// dropped silently.
struct ReadReport {
  std::string file;    ///< the name used in error messages
  std::string format;  ///< e.g. "legacy VTK 5.1 BINARY", "VTK XML 1.0 (appended raw, zlib)"
  std::map<int, uint64_t> cells_read;     ///< VTK cell type id -> cells of that type in the file
  std::map<int, uint64_t> cells_skipped;  ///< VTK cell type id -> cells dropped (skip option)
  uint64_t reduced_to_linear = 0;  ///< quadratic / higher-order / voxel cells kept as linear corner cells
  /// Polyhedra (VTU) decomposed around an added centre point each: into
  /// this many tetrahedra (triangle faces) and pyramids (quad faces; the
  /// pyramids are among the hexahedra, collapsed). Wedges and pyramids of
  /// the file are hexahedra too (mesh/vtk_cells.hpp).
  uint64_t polyhedra_split = 0, polyhedron_tets = 0, polyhedron_pyramids = 0;
  std::vector<std::string> arrays_read;     ///< "point 'T'", "cell 'EQPS'", "point 'DISPL' (3 components, magnitude)"
  std::vector<std::string> arrays_ignored;  ///< with the reason, e.g. "field 'TimeValue' (dataset field data)"
  /// Whatever else a reader passed over, with the reason: e.g. a gmsh file's
  /// "15976 triangle elements (gmsh type 2): not volume cells".
  std::vector<std::string> other_ignored;
  /// Cells of a non-VTK format's types dropped by the skip option (VTK
  /// types are counted in `cells_skipped`); listed in `other_ignored` too.
  uint64_t other_cells_skipped = 0;

  /// Cells dropped in total (all types).
  uint64_t skipped_count() const {
    uint64_t n = other_cells_skipped;
    for (auto const& [type, count] : cells_skipped) n += count;
    return n;
  }

  /// A few human-readable lines (for logs and the example renderer).
  std::string summary() const {
    std::ostringstream s;
    s << file << ": " << format << "\n  cells:";
    for (auto const& [type, count] : cells_read) s << " " << count << " " << vtk_cell_type_name(type);
    if (reduced_to_linear) s << "\n  " << reduced_to_linear << " higher-order cells read as linear corner cells";
    if (polyhedra_split)
      s << "\n  " << polyhedra_split << " polyhedra split into " << polyhedron_tets << " tetrahedra and "
        << polyhedron_pyramids << " pyramids around " << polyhedra_split << " added centre points";
    for (auto const& [type, count] : cells_skipped) s << "\n  skipped " << count << " " << vtk_cell_type_name(type);
    for (auto const& a : arrays_read) s << "\n  read " << a;
    for (auto const& a : arrays_ignored) s << "\n  ignored " << a;
    for (auto const& a : other_ignored) s << "\n  ignored " << a;
    return s.str();
  }
};

/// The result of reading a mesh file: vertex positions, the tetrahedra and
/// hexahedra it holds (a file mixing both gives two homogeneous meshes over
/// the same vertices), and its point and cell arrays, all owned. Vertex ids
/// are always 32-bit: a file with more than 2^32-1 points is rejected by the
/// readers with an IoError. Every vertex id is checked against the vertex
/// count by the reader. Views from `tet_mesh()` / `hex_mesh()` point into this
/// object: keep it alive and do not modify its arrays while they exist.
struct UnstructuredGrid {
  std::vector<float> xyz;          ///< 3 floats per vertex
  std::vector<uint32_t> tets;      ///< 4 vertex ids per tetrahedron (VTK order)
  std::vector<uint32_t> hexes;     ///< 8 vertex ids per hexahedron (VTK order)
  std::vector<PointArray> point_arrays;
  std::vector<CellArray> cell_arrays;
  ReadReport report;
  /// The file's cell id of each tetrahedron and hexahedron kept, so that
  /// messages can name the cell a user looks up: its position among the
  /// file's cells, as VTK and ParaView number them, or a gmsh file's
  /// element tag. Filled by the readers where it differs from the cell's
  /// index in `tets` / `hexes`: a file mixing tetrahedra with other cells,
  /// skipped cells, split polyhedra (each piece has its polyhedron's id),
  /// tets folded into the hexahedra, gmsh files. Empty: the index is the
  /// id (one cell type, nothing skipped), or there is no file (or an id
  /// past 2^32 - 1). See tet_file_cell / hex_file_cell.
  std::vector<uint32_t> tet_file_cells, hex_file_cells;

  /// Vertices (all of the file's points, used by a kept cell or not).
  uint64_t vertex_count() const noexcept { return xyz.size() / 3; }
  /// Kept tetrahedra (linear, quadratic and higher-order ones as corner cells).
  uint64_t tet_count() const noexcept { return tets.size() / 4; }
  /// Kept hexahedra (linear, voxels, quadratic and higher-order ones as corner cells).
  uint64_t hex_count() const noexcept { return hexes.size() / 8; }
  /// True when the grid has no cell at all.
  bool empty() const noexcept { return tets.empty() && hexes.empty(); }
  /// The file's cell id of tetrahedron / hexahedron `i` (tet_file_cells).
  uint64_t tet_file_cell(uint64_t i) const noexcept { return i < tet_file_cells.size() ? tet_file_cells[i] : i; }
  uint64_t hex_file_cell(uint64_t i) const noexcept { return i < hex_file_cells.size() ? hex_file_cells[i] : i; }

  /// The point array called `name`, or nullptr.
  PointArray const* point_array(std::string_view name) const noexcept {
    for (auto const& a : point_arrays)
      if (a.name == name) return &a;
    return nullptr;
  }
  /// The cell array called `name`, or nullptr.
  CellArray const* cell_array(std::string_view name) const noexcept {
    for (auto const& a : cell_arrays)
      if (a.name == name) return &a;
    return nullptr;
  }

  /// A view of the tetrahedra (possibly none) with every point array added;
  /// the first point array is active.
  TetMesh tet_mesh() const { return with_arrays(TetMesh(view(xyz), view(tets))); }
  /// A view of the hexahedra (possibly none) with every point array added;
  /// the first point array is active.
  HexMesh hex_mesh() const { return with_arrays(HexMesh(view(xyz), view(hexes))); }

  /// Adds a point array averaging the cell array `cell_name` over the kept
  /// cells (tets and hexes) around each vertex, unweighted, as VTK's
  /// vtkCellDataToPointData does. It is named `point_name`, or like the cell
  /// array when that is empty. A vertex no kept cell uses gets NaN; a NaN cell
  /// value makes its vertices NaN. Not thread-safe (modifies the grid, and
  /// views made before may dangle if `point_arrays` reallocates: make views
  /// after converting).
  /// @throws InvalidArgument when there is no such cell array, or a point
  ///         array with the target name exists already.
  void cell_to_point(std::string_view cell_name, std::string point_name = {}) {
    CellArray const* c = cell_array(cell_name);
    if (!c) {
      std::string known;
      for (auto const& a : cell_arrays) known += (known.empty() ? "" : ", ") + a.name;
      throw InvalidArgument("no cell array '" + std::string(cell_name) + "' (cell arrays: " +
                            (known.empty() ? "none" : known) + ")");
    }
    if (point_name.empty()) point_name = std::string(cell_name);
    if (point_array(point_name))
      throw InvalidArgument("a point array '" + point_name + "' exists already; pass another name to cell_to_point");
    uint64_t const nv = vertex_count();
    // Double sums: 10^5 float terms around a vertex would lose digits in float.
    std::vector<double> sum(nv, 0.0);
    std::vector<uint32_t> count(nv, 0);
    // A cell counts once at each of its vertices, however often it lists
    // one (a wedge, pyramid or tet stored as a hexahedron), as VTK counts it.
    auto accumulate = [&](std::vector<uint32_t> const& ids, int corners, std::vector<float> const& vals) {
      uint64_t const cells = ids.size() / uint64_t(corners);
      for (uint64_t i = 0; i < cells; ++i) {
        uint32_t const* c = ids.data() + i * uint64_t(corners);
        for (int k = 0; k < corners; ++k) {
          if (std::find(c, c + k, c[k]) != c + k) continue;
          sum[c[k]] += double(vals[i]);
          ++count[c[k]];
        }
      }
    };
    accumulate(tets, 4, c->tet_values);
    accumulate(hexes, 8, c->hex_values);
    PointArray p;
    p.name = std::move(point_name);
    p.components = c->components;
    p.values.resize(nv);
    for (uint64_t v = 0; v < nv; ++v)
      p.values[v] = count[v] ? float(sum[v] / double(count[v])) : std::numeric_limits<float>::quiet_NaN();
    report.arrays_read.push_back("point '" + p.name + "' (averaged from cell array '" + c->name + "')");
    point_arrays.push_back(std::move(p));
  }

  /// Stores every tetrahedron as a collapsed hexahedron (mesh/
  /// vtk_cells.hpp's tet_as_hex), after the hexahedra, with its cell-array
  /// values: a mixed mesh becomes one part, under one BVH, through whose
  /// face neighbours DVR can march across all its cell types. The field and
  /// the crossings are the tet's; the price is 16 more index bytes per tet
  /// and the hexahedron kernels' cost for it. The file cell ids follow
  /// (hex_file_cells). Returns how many were folded. Views made before dangle.
  uint64_t fold_tets_into_hexes() {
    uint64_t const n = tet_count();
    if (hexes.empty()) hex_file_cells = std::move(tet_file_cells);
    else if (n && !tet_file_cells.empty() && !hex_file_cells.empty())
      hex_file_cells.insert(hex_file_cells.end(), tet_file_cells.begin(), tet_file_cells.end());
    else if (n) hex_file_cells.clear();  // no file ids to go on: the folded view's own indices
    tet_file_cells.clear();
    tet_file_cells.shrink_to_fit();
    hexes.reserve(hexes.size() + 8 * n);
    for (uint64_t c = 0; c < n; ++c)
      for (int k : tet_as_hex) hexes.push_back(tets[4 * c + uint64_t(k)]);
    for (CellArray& a : cell_arrays) {
      a.hex_values.insert(a.hex_values.end(), a.tet_values.begin(), a.tet_values.end());
      a.tet_values.clear();
      a.tet_values.shrink_to_fit();
    }
    tets.clear();
    tets.shrink_to_fit();
    return n;
  }

 private:
  template <class Mesh> Mesh with_arrays(Mesh m) const {
    for (auto const& a : point_arrays) m.add_array(a.name, view(a.values));
    return m;
  }
};

}  // namespace cellray
