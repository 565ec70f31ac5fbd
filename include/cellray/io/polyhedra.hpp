#pragma once
// Splitting a file's polyhedra (VTK 42), shared by the VTU reader (face
// streams in `faces` / `faceoffsets`) and the legacy reader (face streams
// inline in the connectivity, as VTK 9.1 writes them). Each polyhedron
// becomes tetrahedra and pyramids (collapsed hexahedra) around an added
// centre point (mesh/vtk_cells.hpp), appended after the file's cells, as
// foamToVTK -poly-decomp and ParaView do. The centre is the volume
// centroid; its value in a point array is the polyhedron's own value when a
// cell array has the same name (foamToVTK: the cell's value at the cell
// centre), else the mean of its vertices. The new cells carry the
// polyhedron's cell-array values.
//
// A reader plans the split before storing any cell (PolyPlan: at most how
// many cells each polyhedron adds), so that the cells' storage is reserved
// once for the file's cells and the polyhedra's (growing it after the file's cells
// cost a copy and the first-write faults of the first buffer, ~15% of the
// flange's load), then splits after its arrays are read (split_polyhedra).

#include <algorithm>
#include <cassert>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "../memory.hpp"
#include "../mesh/vtk_cells.hpp"
#include "detail.hpp"
#include "grid.hpp"

namespace cellray {
namespace io {

/// One polyhedron of a file: file cell `cell`, face stream
/// `[nfaces, n0, ids..., n1, ids...]` at faces[begin, end).
struct PolyRange {
  uint64_t cell, begin, end;
};

/// The polyhedra of a file in file order and, for reserving storage, at
/// most how many cells each adds: polyhedron k adds at most tet_at[k+1] -
/// tet_at[k] tets (hexes likewise); sizes npoly + 1 once
/// count_polyhedron_cells ran. The split's own counts depend on the faces'
/// shapes (split_face), known once the positions are.
struct PolyPlan {
  std::vector<PolyRange> polys;
  std::vector<uint64_t> tet_at, hex_at;
  uint64_t new_tets() const { return tet_at.empty() ? 0 : tet_at.back(); }
  uint64_t new_hexes() const { return hex_at.empty() ? 0 : hex_at.back(); }
};

/// Each cell array's values of the polyhedra, in polyhedron order (filled
/// by add_cell_array's `polyhedra_values`), by array name.
using PolyhedraValues = std::vector<std::pair<std::string, std::vector<float>>>;

constexpr uint64_t poly_grain = 256;  // polyhedra per task
template <class F> void for_poly_chunks(uint64_t npoly, F const& f) {
  uint64_t const nchunks = (npoly + poly_grain - 1) / poly_grain;
  tbb::blocked_range<uint64_t> const all(0, nchunks, 1);
  if (nchunks <= 1) f(all);
  else tbb::parallel_for(all, f);
}

/// A file's tetrahedra, hexahedra (voxels included) and polyhedra by their
/// VTK types, for reserving storage before the split.
struct FileCellCounts {
  uint64_t tets = 0, hexes = 0, polyhedra = 0;
};
inline FileCellCounts count_file_cells(NumArray const& types) {
  FileCellCounts n;
  with_ints(types, [&](auto const type_of) {
    for (uint64_t c = 0; c < types.count; ++c) {
      uint64_t nodes;
      bool exact;
      CellKind const k = classify_cell(type_of(c), nodes, exact);
      n.tets += k == CellKind::tet;
      n.hexes += k == CellKind::hex || k == CellKind::voxel;
      n.polyhedra += k == CellKind::polyhedron;
    }
  });
  return n;
}

/// Fills `p.tet_at` / `p.hex_at` from `p.polys`, in parallel: bounds on
/// each polyhedron's cells from its face sizes alone (split_face makes a
/// tet of a triangle, a pyramid of a quad, and of an n-gon at most n - 2
/// triangles and at most (n - 2) / 2 quads). A malformed stream counts what
/// it can; split_polyhedra stops at it.
inline void count_polyhedron_cells(NumArray const& faces, PolyPlan& p) {
  uint64_t const npoly = p.polys.size();
  p.tet_at.assign(npoly + 1, 0);
  p.hex_at.assign(npoly + 1, 0);
  for_poly_chunks(npoly, [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t k = r.begin() * poly_grain, ke = std::min(npoly, r.end() * poly_grain); k < ke; ++k) {
      uint64_t i = p.polys[k].begin, e = p.polys[k].end, nt = 0, nh = 0;
      int64_t const nfaces = i < e ? faces.as_int(i++) : 0;
      for (int64_t j = 0; j < nfaces && i < e; ++j) {
        int64_t const n = faces.as_int(i);
        if (n < 3 || uint64_t(n) >= e - i) break;
        if (n == 4) nh += 1;
        else nt += uint64_t(n - 2), nh += uint64_t(n - 2) / 2;
        i += uint64_t(n) + 1;
      }
      p.tet_at[k + 1] = nt;
      p.hex_at[k + 1] = nh;
    }
  });
  for (uint64_t k = 0; k < npoly; ++k) {
    p.tet_at[k + 1] += p.tet_at[k];
    p.hex_at[k + 1] += p.hex_at[k];
  }
}

/// Polyhedron p's face stream into `f`; "" or what is wrong, to follow
/// "polyhedron cell C". `whole`: the stream must use its range exactly (the
/// legacy connectivity, where the range is the cell's); else entries after
/// it are ignored (VTU faceoffsets).
inline std::string parse_polyhedron(NumArray const& faces, PolyRange const& p, PolyhedronFaces& f, bool whole = false) {
  int64_t const stop = int64_t(p.end);
  uint64_t i = p.begin;
  bool ended = false;
  auto next = [&]() -> int64_t {
    if (i >= uint64_t(stop)) {
      ended = true;
      return 0;
    }
    return faces.as_int(i++);
  };
  static char const* const early = ": its face stream ends early";
  int64_t const nfaces = next();
  if (ended) return early;
  if (nfaces < 4 || nfaces > stop - int64_t(p.begin)) return " declares " + std::to_string(nfaces) + " faces";
  f.ids.clear();
  f.offsets.assign(1, 0);
  for (int64_t j = 0; j < nfaces; ++j) {
    int64_t const n = next();
    if (ended) return early;
    if (n < 3 || n > stop - int64_t(i))
      return ": face " + std::to_string(j) + " declares " + std::to_string(n) + " vertices";
    for (int64_t q = 0; q < n; ++q) f.ids.push_back(uint64_t(next()));  // negative: huge, caught by check_polyhedron
    f.offsets.push_back(f.ids.size());
  }
  if (whole && i != p.end)
    return ": its " + std::to_string(nfaces) + " faces use " + std::to_string(i - p.begin) + " of its " +
           std::to_string(p.end - p.begin) + " entries";
  return "";
}

/// What split_polyhedra found wrong: the first bad polyhedron (index into
/// PolyPlan::polys) and what is wrong with it ("polyhedron cell C" + what),
/// or `too_many` when the centre points would pass 32-bit vertex ids.
struct PolySplitError {
  uint64_t at = ~uint64_t(0);
  std::string what;
  bool too_many = false;
  explicit operator bool() const { return !what.empty() || too_many; }
};

/// Splits the polyhedra of `plan` whose face streams are in `faces`:
/// appends their cells, centre points, point values and cell values
/// (`cell_values`: those add_cell_array set apart, by name) to `grid`, whose
/// cells, positions and arrays are the file's, and counts them in its
/// report. Checks each polyhedron (parse_polyhedron with `whole`,
/// check_polyhedron) and returns the first error in file order (the grid
/// is then half written: the caller throws).
inline PolySplitError split_polyhedra(UnstructuredGrid& grid, NumArray const& faces, PolyPlan const& plan,
                                      PolyhedraValues const& cell_values, bool whole = false) {
  uint64_t const np = grid.vertex_count();
  std::vector<PolyRange> const& polys = plan.polys;
  std::vector<CellArray*> cell_arrays;  // the array each entry of cell_values fills
  for (auto const& cv : cell_values)
    for (auto& a : grid.cell_arrays)
      if (a.name == cv.first) cell_arrays.push_back(&a);
  // A point array's centre value: the same-named cell array's (its index in
  // cell_values), else -1 for the mean of the polyhedron's vertices.
  std::vector<int> centre_from(grid.point_arrays.size(), -1);
  for (size_t a = 0; a < grid.point_arrays.size(); ++a)
    for (size_t v = 0; v < cell_values.size(); ++v)
      if (cell_values[v].first == grid.point_arrays[a].name) centre_from[a] = int(v);
  bool const need_means = std::find(centre_from.begin(), centre_from.end(), -1) != centre_from.end();

  uint64_t const npoly = polys.size();
  uint64_t const nchunks = (npoly + poly_grain - 1) / poly_grain;
  constexpr uint64_t grain = poly_grain;

  // Pass 1, in parallel (each polyhedron is independent; check and
  // decompose were ~15% of the load when serial): check each polyhedron and
  // count its cells (a face of more than 5 corners is split to count its
  // parts; the split is a function of the face, so pass 2 gets the same).
  // Counting first, then writing every cell straight to its place, beat
  // keeping the cells of pass 1 (their 4 MB of fresh pages and the copy:
  // +25% on the flange's load).
  std::vector<uint64_t> tet_at(npoly + 1, 0), hex_at(npoly + 1, 0);  // counts, then prefix sums
  std::vector<PolySplitError> errors(nchunks);
  float const* const xyz_in = grid.xyz.data();
  for_poly_chunks(npoly, [&](tbb::blocked_range<uint64_t> const& r) {
    PolyhedronFaces f;
    for (uint64_t j = r.begin(); j < r.end(); ++j) {
      for (uint64_t k = j * grain, ke = std::min(npoly, k + grain); k < ke; ++k) {
        PolySplitError err;
        err.what = parse_polyhedron(faces, polys[k], f, whole);
        if (err.what.empty())
          if (std::string const bad = check_polyhedron(f, np); !bad.empty()) err.what = " " + bad;
        if (err.what.empty() && np + k > std::numeric_limits<uint32_t>::max()) err.too_many = true;
        if (err) {
          err.at = k;
          errors[j] = std::move(err);
          break;
        }
        for (size_t i = 0; i < f.face_count(); ++i) {
          size_t const n = f.offsets[i + 1] - f.offsets[i];
          if (n <= 5) {  // a pentagon's split is a triangle and a quad, whatever its shape
            tet_at[k + 1] += n != 4;
            hex_at[k + 1] += n != 3;
            continue;
          }
          cellray::detail::for_each_face_part(f.ids.data() + f.offsets[i], n, xyz_in,
                                              [&](uint64_t const*, size_t m) { ++(m == 4 ? hex_at : tet_at)[k + 1]; });
        }
      }
    }
  });
  for (PolySplitError& e : errors)
    if (e) return std::move(e);

  uint64_t const tet0 = grid.tet_count(), hex0 = grid.hex_count();
  tet_at[0] = tet0, hex_at[0] = hex0;
  for (uint64_t k = 0; k < npoly; ++k) tet_at[k + 1] += tet_at[k], hex_at[k + 1] += hex_at[k];
  uint64_t const new_tets = tet_at[npoly] - tet0, new_hexes = hex_at[npoly] - hex0;
  cellray::detail::resize_zeroed(grid.tets, 4 * tet_at[npoly]);
  cellray::detail::resize_zeroed(grid.hexes, 8 * hex_at[npoly]);
  cellray::detail::resize_zeroed(grid.xyz, 3 * (np + npoly));
  for (auto& pa : grid.point_arrays) cellray::detail::resize_zeroed(pa.values, np + npoly);
  std::vector<float*> value_tets(cell_arrays.size()), value_hexes(cell_arrays.size());  // where new values go
  for (size_t a = 0; a < cell_arrays.size(); ++a) {
    uint64_t const t0 = cell_arrays[a]->tet_values.size(), h0 = cell_arrays[a]->hex_values.size();
    cellray::detail::resize_zeroed(cell_arrays[a]->tet_values, t0 + new_tets);
    cellray::detail::resize_zeroed(cell_arrays[a]->hex_values, h0 + new_hexes);
    value_tets[a] = cell_arrays[a]->tet_values.data() + t0 - tet0;
    value_hexes[a] = cell_arrays[a]->hex_values.data() + h0 - hex0;
  }

  // Pass 2, in parallel: polyhedron k's cells, centre point (vertex np + k)
  // and values straight to their places.
  float* const xyz = grid.xyz.data();
  uint32_t* const tets = grid.tets.data();
  uint32_t* const hexes = grid.hexes.data();
  for_poly_chunks(npoly, [&](tbb::blocked_range<uint64_t> const& r) {
    PolyhedronFaces f;
    PolyhedronSplit split;
    std::vector<uint64_t> verts;
    for (uint64_t j = r.begin(); j < r.end(); ++j) {
      for (uint64_t k = j * grain, ke = std::min(npoly, k + grain); k < ke; ++k) {
        parse_polyhedron(faces, polys[k], f, whole);  // checked in pass 1
        decompose_polyhedron(f, xyz, np + k, split);
        assert(split.tets.size() == tet_at[k + 1] - tet_at[k] && split.hexes.size() == hex_at[k + 1] - hex_at[k]);
        for (int a = 0; a < 3; ++a) xyz[3 * (np + k) + uint64_t(a)] = float(split.centre[a]);
        if (need_means) {
          verts.assign(f.ids.begin(), f.ids.end());
          std::sort(verts.begin(), verts.end());
          verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
        }
        for (size_t a = 0; a < grid.point_arrays.size(); ++a) {
          float value;
          if (centre_from[a] >= 0) {
            value = cell_values[size_t(centre_from[a])].second[k];
          } else {
            std::vector<float> const& pv = grid.point_arrays[a].values;
            double sum = 0;
            for (uint64_t v : verts) sum += pv[v];
            value = float(sum / double(verts.size()));
          }
          grid.point_arrays[a].values[np + k] = value;
        }
        uint32_t* t = tets + 4 * tet_at[k];
        for (auto const& c : split.tets)
          for (uint64_t v : c) *t++ = uint32_t(v);
        uint32_t* h = hexes + 8 * hex_at[k];
        for (auto const& c : split.hexes)
          for (uint64_t v : c) *h++ = uint32_t(v);
        for (size_t a = 0; a < cell_arrays.size(); ++a) {
          float const v = cell_values[a].second[k];
          std::fill(value_tets[a] + tet_at[k], value_tets[a] + tet_at[k + 1], v);
          std::fill(value_hexes[a] + hex_at[k], value_hexes[a] + hex_at[k + 1], v);
        }
      }
    }
  });
  // Each piece has its polyhedron's file cell id. build_cells recorded the
  // ids of the other cells; a grid without them (over 2^32 - 1 cells) has none.
  if (grid.tet_file_cells.size() == tet0 && grid.hex_file_cells.size() == hex0 &&
      (npoly == 0 || polys[npoly - 1].cell <= std::numeric_limits<uint32_t>::max())) {
    grid.tet_file_cells.reserve(tet_at[npoly]);
    grid.hex_file_cells.reserve(hex_at[npoly]);
    for (uint64_t k = 0; k < npoly; ++k) {
      grid.tet_file_cells.insert(grid.tet_file_cells.end(), tet_at[k + 1] - tet_at[k], uint32_t(polys[k].cell));
      grid.hex_file_cells.insert(grid.hex_file_cells.end(), hex_at[k + 1] - hex_at[k], uint32_t(polys[k].cell));
    }
  } else {
    grid.tet_file_cells.clear();
    grid.hex_file_cells.clear();
  }
  grid.report.polyhedron_tets += new_tets;
  grid.report.polyhedron_pyramids += new_hexes;
  grid.report.polyhedra_split = npoly;
  return {};
}

}  // namespace io
}  // namespace cellray
