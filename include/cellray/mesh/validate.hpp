#pragma once
// validate(mesh): what is wrong with a mesh view, found before any kernel
// runs. Errors (bad indices, non-finite positions) make `ok()` false and stop
// rendering; warnings (non-finite values, zero-volume or inverted cells) are
// reported and rendered with a documented outcome: a cell with a NaN value
// is invisible; a zero-volume cell is never hit; an inverted cell renders
// like its mirror image (the kernels do not depend on orientation).
//
// A hexahedron (or a wedge or pyramid stored as one) whose volume is
// positive but whose Jacobian is negative at some corner is not inverted:
// a concave or warped cell, common in real meshes (snappyHexMesh's pyramids
// over warped faces, crushed shells). Its trilinear map folds near that
// corner, in VTK as here; it is reported as a note (`distorted`), not a
// warning, with the kinds of cell a hexahedral view holds (collapsed
// hexahedra: wedges, pyramids, tetrahedra).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <ostream>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "cell_mesh.hpp"

namespace cellray {

/// A count of offending items and the smallest id among them (or none).
struct Finding {
  uint64_t count = 0;
  uint64_t first = std::numeric_limits<uint64_t>::max();  ///< vertex id, or cell id (validate's `cell_ids`)

  void add(uint64_t id) {
    ++count;
    first = std::min(first, id);
  }
  void merge(Finding const& o) {
    count += o.count;
    first = std::min(first, o.first);
  }
  explicit operator bool() const { return count != 0; }
};

/// What a hexahedral view's cells are, by the shapes of their six faces
/// (VTK hexahedron faces: 4 distinct ids a quad, 3 with one repeated pair
/// of neighbours a triangle, 2 or 1 collapsed): a hexahedron has 6 quads, a
/// wedge 3 quads and 2 triangles, a pyramid 1 quad and 4 triangles, a
/// tetrahedron 4 triangles (the last three as the readers store them, or
/// any other listing of the same shape). Any other collapse (an edge of a
/// hexahedron, OpenFOAM's tet-wedge) is `other`; under 4 distinct ids,
/// `fewer` (no volume).
enum class CollapsedKind : int { hexahedron, wedge, pyramid, tetrahedron, other, fewer, count };

inline char const* collapsed_kind_name(CollapsedKind k, bool plural) {
  static char const* const one[] = {"hexahedron", "wedge", "pyramid", "tetrahedron", "other collapsed hexahedron",
                                    "cell of under 4 distinct vertices"};
  static char const* const many[] = {"hexahedra", "wedges", "pyramids", "tetrahedra", "other collapsed hexahedra",
                                     "cells of under 4 distinct vertices"};
  return (plural ? many : one)[int(k)];
}

/// The kind of a hexahedral cell from its 8 vertex ids (VTK order). One
/// bit per pair of corners with equal ids, then bit tests: branch-free for
/// the usual cells (validation runs on every cell of a first image).
inline CollapsedKind collapsed_kind(uint64_t const (&v)[8]) {
  auto bit = [](int i, int j) { return i * 8 + j; };  // i < j
  uint64_t eq = 0;
  for (int i = 0; i < 8; ++i)
    for (int j = i + 1; j < 8; ++j) eq |= uint64_t(v[i] == v[j]) << bit(i, j);
  if (eq == 0) return CollapsedKind::hexahedron;
  auto same = [&](int i, int j) { return int((eq >> (i < j ? bit(i, j) : bit(j, i))) & 1u); };
  int distinct = 8;
  for (int k = 1; k < 8; ++k) {
    int seen = 0;
    for (int j = 0; j < k; ++j) seen |= same(j, k);
    distinct -= seen;
  }
  if (distinct < 4) return CollapsedKind::fewer;
  static constexpr int faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                      {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
  int quads = 0, triangles = 0;
  for (auto const& f : faces) {
    int const neighbours = same(f[0], f[1]) + same(f[1], f[2]) + same(f[2], f[3]) + same(f[3], f[0]);
    int const opposite = same(f[0], f[2]) + same(f[1], f[3]);
    quads += neighbours == 0 && opposite == 0;
    triangles += neighbours == 1 && opposite == 0;
  }
  if (quads == 3 && triangles == 2 && distinct == 6) return CollapsedKind::wedge;
  if (quads == 1 && triangles == 4 && distinct == 5) return CollapsedKind::pyramid;
  if (quads == 0 && triangles == 4 && distinct == 4) return CollapsedKind::tetrahedron;
  return CollapsedKind::other;
}

/// Cells counted per CollapsedKind.
struct KindCounts {
  uint64_t n[int(CollapsedKind::count)] = {};
  uint64_t operator[](CollapsedKind k) const { return n[int(k)]; }
  void add(CollapsedKind k) { ++n[int(k)]; }
  void merge(KindCounts const& o) {
    for (int k = 0; k < int(CollapsedKind::count); ++k) n[k] += o.n[k];
  }
  uint64_t total() const {
    uint64_t t = 0;
    for (uint64_t c : n) t += c;
    return t;
  }
  /// "69115 hexahedra, 9246 wedges, 109178 pyramids" (kinds present only).
  std::string list() const {
    std::string s;
    for (int k = 0; k < int(CollapsedKind::count); ++k)
      if (n[k])
        s += (s.empty() ? "" : ", ") + std::to_string(n[k]) + " " + collapsed_kind_name(CollapsedKind(k), n[k] != 1);
    return s;
  }
};

/// What `validate()` found. Cheap to copy; `message()` is one line per finding.
struct ValidationReport {
  CellType cell_type = CellType::tet;
  uint64_t cells = 0, vertices = 0;
  Finding bad_index;           ///< error: a cell names a vertex id >= vertex count (cell ids)
  Finding nonfinite_position;  ///< error: NaN or inf coordinate of a vertex a cell uses (vertex ids)
  Finding unused_nonfinite_position;  ///< warning: NaN or inf coordinate of a vertex no cell uses (ignored)
  Finding nonfinite_value;     ///< warning: NaN or inf in the active array at a vertex a cell uses (vertex ids)
  Finding zero_volume;         ///< warning: flat or collapsed cells (cell ids)
  Finding inverted;            ///< warning: negative volume, turned inside out (cell ids)
  /// Note, not a warning: positive volume but a negative Jacobian at some
  /// corner (hexahedral views: a concave or twisted cell; cell ids).
  Finding distorted;
  /// Hexahedral views (all zero for tetrahedra): the cells of each kind,
  /// and the flat, inverted and distorted ones among them.
  KindCounts kinds, zero_volume_kinds, inverted_kinds, distorted_kinds;
  float value_min = std::numeric_limits<float>::infinity();   ///< finite values only
  float value_max = -std::numeric_limits<float>::infinity();

  /// False when rendering must not proceed.
  bool ok() const { return !bad_index && !nonfinite_position; }
  bool has_warnings() const {
    return bool(nonfinite_value) || bool(zero_volume) || bool(inverted) || bool(unused_nonfinite_position);
  }

  /// True when a hexahedral view holds collapsed cells too.
  bool mixed() const { return kinds.total() != kinds[CollapsedKind::hexahedron]; }

  std::string message() const {
    std::ostringstream s;
    char const* what = cell_type == CellType::tet ? "tetrahedra" : "hexahedra";
    if (mixed()) {
      s << cells << " cells (" << kinds.list() << ")";
    } else {
      s << cells << " " << what;
    }
    s << ", " << vertices << " vertices";
    if (value_min <= value_max) s << ", values [" << value_min << ", " << value_max << "]";
    auto line = [&](Finding const& f, char const* level, char const* text, char const* id,
                    KindCounts const* by_kind = nullptr) {
      if (!f) return;
      s << "\n  " << level << ": " << f.count << " " << text << " (";
      if (by_kind && mixed()) s << by_kind->list() << "; ";
      s << "first " << id << " " << f.first << ")";
    };
    line(bad_index, "error", "cells with a vertex index out of range", "cell");
    line(nonfinite_position, "error", "vertices with a non-finite position", "vertex");
    line(unused_nonfinite_position, "warning", "vertices no cell uses with a non-finite position (ignored)", "vertex");
    line(nonfinite_value, "warning", "vertices with a non-finite value (their cells are invisible)", "vertex");
    line(zero_volume, "warning", "cells of zero volume (never hit)", "cell", &zero_volume_kinds);
    line(inverted, "warning", "inverted cells (negative volume)", "cell", &inverted_kinds);
    line(distorted, "note", "cells with a negative Jacobian at a corner (positive volume: concave or warped)", "cell",
         &distorted_kinds);
    return s.str();
  }
  friend std::ostream& operator<<(std::ostream& os, ValidationReport const& r) { return os << r.message(); }
};

namespace detail {

inline glm::dvec3 dpos(float const* xyz, uint64_t v) {
  return {double(xyz[3 * v]), double(xyz[3 * v + 1]), double(xyz[3 * v + 2])};
}

/// The signed volume of the trilinear map of 8 corners (VTK hexahedron
/// order; collapsed corners allowed), relative to its longest edge cubed:
/// 2x2x2 Gauss points integrate det J exactly (it is of degree 2 in each
/// coordinate).
inline double relative_hex_volume(glm::dvec3 const (&p)[8]) {
  static constexpr int edges[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                       {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
  double longest = 0;
  for (auto const& e : edges) longest = std::max(longest, glm::length(p[e[1]] - p[e[0]]));
  if (!(longest > 0)) return 0.0;
  double const g[2] = {0.5 - 0.5 / std::sqrt(3.0), 0.5 + 0.5 / std::sqrt(3.0)};
  double volume = 0;
  for (double u : g)
    for (double v : g)
      for (double w : g) {
        double const U[2] = {1 - u, u}, V[2] = {1 - v, v}, W[2] = {1 - w, w};
        glm::dvec3 du(0.0), dv(0.0), dw(0.0);
        for (int k = 0; k < 8; ++k) {
          int const a = (k & 1) ^ ((k >> 1) & 1), b = (k >> 1) & 1, c = k >> 2;  // VTK corner k's (u, v, w)
          du += p[k] * ((a ? 1.0 : -1.0) * V[b] * W[c]);
          dv += p[k] * ((b ? 1.0 : -1.0) * U[a] * W[c]);
          dw += p[k] * ((c ? 1.0 : -1.0) * U[a] * V[b]);
        }
        volume += glm::dot(glm::cross(du, dv), dw) / 8;
      }
  return volume / (longest * longest * longest);
}

// Flatness threshold on the sine-like relative determinant: below 1e-7 the
// cell's thickness is under float resolution of its edges.
inline constexpr double flat_tolerance = 1e-7;

/// Orientation of the corner spanned by three edges: +1 or -1 when their
/// determinant, relative to the product of their lengths, is beyond
/// flat_tolerance, else 0 (flat, a zero edge, or NaN). Compared squared: no
/// roots or divisions per corner (validation runs on every cell of a first
/// image). Double precision: float input is exact, and sixth powers of
/// float edge lengths stay within double's range.
inline int corner_orientation(glm::dvec3 const& a, glm::dvec3 const& b, glm::dvec3 const& c) {
  double const d = glm::dot(glm::cross(a, b), c);
  double const lengths2 = glm::dot(a, a) * glm::dot(b, b) * glm::dot(c, c);
  if (!(d * d > flat_tolerance * flat_tolerance * lengths2)) return 0;
  return d > 0 ? 1 : -1;
}

}  // namespace detail

/// Checks indices, positions, the active values and cell shapes. Parallel
/// (TBB), deterministic; reads the mesh only. For hexahedra (and the
/// collapsed ones: wedges, pyramids, folded tetrahedra), "inverted" means
/// a negative volume, "distorted" a negative Jacobian at some corner (VTK
/// corner edge order) with a positive volume, "zero volume" that every
/// corner is flat.
///
/// `cell_ids`, when given (one per cell), are the ids findings name instead
/// of the cells' indices in the view, and "first" is the smallest of them:
/// a file's cell ids (io/grid.hpp's UnstructuredGrid::hex_file_cells, for a
/// view whose cells a reader reordered), a host's (split_vtk_cells'
/// SplitCells::hex_cells) or a rank's global ones.
/// @throws InvalidArgument when `cell_ids` is neither empty nor one per cell.
template <int N, class Id> ValidationReport validate(CellMesh<N> const& mesh, Span<Id> cell_ids) {
  static_assert(std::is_integral_v<Id>, "cell ids are integers");
  if (!cell_ids.empty() && cell_ids.size != mesh.cell_count())
    throw InvalidArgument("validate: " + std::to_string(cell_ids.size) + " cell ids for " +
                          std::to_string(mesh.cell_count()) + " cells");
  ValidationReport rep;
  rep.cell_type = CellMesh<N>::cell_type;
  rep.cells = mesh.cell_count();
  rep.vertices = mesh.vertex_count();
  float const* xyz = mesh.positions();
  float const* val = mesh.values();
  uint64_t const nv = mesh.vertex_count();

  struct VertexPart {
    Finding pos, value;
    float lo = std::numeric_limits<float>::infinity(), hi = -std::numeric_limits<float>::infinity();
  };
  auto vpart = tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, nv, 1 << 14), VertexPart{},
      [&](tbb::blocked_range<uint64_t> const& r, VertexPart acc) {
        for (uint64_t v = r.begin(); v < r.end(); ++v) {
          if (!std::isfinite(xyz[3 * v]) || !std::isfinite(xyz[3 * v + 1]) || !std::isfinite(xyz[3 * v + 2]))
            acc.pos.add(v);
          if (val) {
            if (!std::isfinite(val[v])) acc.value.add(v);
            else acc.lo = std::min(acc.lo, val[v]), acc.hi = std::max(acc.hi, val[v]);
          }
        }
        return acc;
      },
      [](VertexPart a, VertexPart const& b) {
        a.pos.merge(b.pos);
        a.value.merge(b.value);
        a.lo = std::min(a.lo, b.lo);
        a.hi = std::max(a.hi, b.hi);
        return a;
      });
  rep.nonfinite_position = vpart.pos;
  rep.nonfinite_value = vpart.value;
  if (vpart.pos || vpart.value) {
    // Rare: count only vertices a cell uses. Files keep unused points (a
    // quadratic cell read as its corners leaves its mid-edge nodes unused,
    // and a cell array averaged to the vertices gives those NaN); nothing
    // reads them. Serial, only here.
    std::vector<uint8_t> used(nv, 0);
    for (uint64_t c = 0; c < mesh.cell_count(); ++c)
      for (int k = 0; k < N; ++k)
        if (uint64_t const v = mesh.vertex(c, k); v < nv) used[v] = 1;
    rep.nonfinite_position = {}, rep.nonfinite_value = {};
    for (uint64_t v = 0; v < nv; ++v) {
      if (!std::isfinite(xyz[3 * v]) || !std::isfinite(xyz[3 * v + 1]) || !std::isfinite(xyz[3 * v + 2]))
        (used[v] ? rep.nonfinite_position : rep.unused_nonfinite_position).add(v);
      if (val && used[v] && !std::isfinite(val[v])) rep.nonfinite_value.add(v);
    }
  }
  rep.value_min = vpart.lo;
  rep.value_max = vpart.hi;

  struct CellPart {
    Finding index, flat, inverted, distorted;
    KindCounts kinds, flat_kinds, inverted_kinds, distorted_kinds;
  };
  bool const named = !cell_ids.empty();
  auto id = [&](uint64_t c) { return named ? uint64_t(cell_ids[c]) : c; };  // read only for findings
  auto cpart = tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, mesh.cell_count(), 1 << 12), CellPart{},
      [&](tbb::blocked_range<uint64_t> const& r, CellPart acc) {
        for (uint64_t c = r.begin(); c < r.end(); ++c) {
          uint64_t v[N];
          bool bad = false;
          for (int k = 0; k < N; ++k) {
            v[k] = mesh.vertex(c, k);
            bad = bad || v[k] >= nv;
          }
          if (bad) {
            acc.index.add(id(c));
            continue;
          }
          glm::dvec3 p[N];
          for (int k = 0; k < N; ++k) p[k] = detail::dpos(xyz, v[k]);
          if constexpr (N == 4) {
            int const o = detail::corner_orientation(p[1] - p[0], p[2] - p[0], p[3] - p[0]);
            if (o == 0) acc.flat.add(id(c));
            else if (o < 0) acc.inverted.add(id(c));
          } else {
            // Corner k's edges to its three neighbours, ordered so that a
            // regular VTK hexahedron gives positive determinants.
            static constexpr int nb[8][3] = {{1, 3, 4}, {2, 0, 5}, {3, 1, 6}, {0, 2, 7},
                                             {7, 5, 0}, {4, 6, 1}, {5, 7, 2}, {6, 4, 3}};
            bool all_flat = true, any_negative = false;
            for (int k = 0; k < 8; ++k) {
              int const o = detail::corner_orientation(p[nb[k][0]] - p[k], p[nb[k][1]] - p[k], p[nb[k][2]] - p[k]);
              all_flat = all_flat && o == 0;
              any_negative = any_negative || o < 0;
            }
            CollapsedKind const kind = collapsed_kind(v);
            acc.kinds.add(kind);
            if (all_flat) {
              acc.flat.add(id(c)), acc.flat_kinds.add(kind);
            } else if (any_negative) {
              // Negative at a corner: inside out only if the volume is.
              if (detail::relative_hex_volume(p) < -detail::flat_tolerance)
                acc.inverted.add(id(c)), acc.inverted_kinds.add(kind);
              else
                acc.distorted.add(id(c)), acc.distorted_kinds.add(kind);
            }
          }
        }
        return acc;
      },
      [](CellPart a, CellPart const& b) {
        a.index.merge(b.index);
        a.flat.merge(b.flat);
        a.inverted.merge(b.inverted);
        a.distorted.merge(b.distorted);
        a.kinds.merge(b.kinds), a.flat_kinds.merge(b.flat_kinds);
        a.inverted_kinds.merge(b.inverted_kinds), a.distorted_kinds.merge(b.distorted_kinds);
        return a;
      });
  rep.bad_index = cpart.index;
  rep.zero_volume = cpart.flat;
  rep.inverted = cpart.inverted;
  rep.distorted = cpart.distorted;
  rep.kinds = cpart.kinds, rep.zero_volume_kinds = cpart.flat_kinds;
  rep.inverted_kinds = cpart.inverted_kinds, rep.distorted_kinds = cpart.distorted_kinds;
  return rep;
}

/// validate() naming each cell by its index in the view.
template <int N> ValidationReport validate(CellMesh<N> const& mesh) { return validate(mesh, Span<uint32_t>{}); }

/// Throws InvalidMesh with the report's message unless `rep.ok()`.
inline void require_valid(ValidationReport const& rep, char const* what = "mesh") {
  if (!rep.ok()) throw InvalidMesh(std::string(what) + " failed validation: " + rep.message());
}

}  // namespace cellray
