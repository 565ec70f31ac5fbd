#pragma once
// ParaView's parallel VTK XML unstructured grid (".pvtu"): a small XML index
// naming one .vtu file per piece (<Piece Source="...">) and the point and
// cell arrays every piece holds (PPointData / PCellData). read_pvtu_index()
// reads the index alone, read_pvtu_piece() one piece (a distributed reader
// takes its own pieces), read_pvtu() every piece merged into one grid.
// Needs pugixml and zlib at link time, like vtu.hpp.

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <pugixml.hpp>

#include "detail.hpp"
#include "grid.hpp"
#include "vtu.hpp"

namespace cellray {

/// What a .pvtu file says, without reading its pieces.
struct PvtuIndex {
  std::string path;                       ///< the .pvtu file, as given
  std::vector<std::string> pieces;        ///< each <Piece Source=...>, relative ones resolved against the .pvtu's folder; file order
  std::vector<std::string> point_arrays;  ///< PPointData/PDataArray names (numeric types only), file order
  std::vector<std::string> cell_arrays;   ///< PCellData/PDataArray names (numeric types only), file order
};

namespace io {

/// Names of the numeric PDataArrays under `parent`; unnamed ones are called
/// like the .vtu reader calls them ("unnamed_point_K"). Other types (String)
/// are not arrays cellray reads, so the index does not promise them.
inline std::vector<std::string> pvtu_array_names(pugi::xml_node parent, char const* where) {
  std::vector<std::string> names;
  size_t k = 0;
  for (pugi::xml_node a : parent.children("PDataArray")) {
    NumType t{};
    bool const numeric = xml_type(a.attribute("type").value(), t);
    std::string name = a.attribute("Name").value();
    if (name.empty()) name = std::string("unnamed_") + where + "_" + std::to_string(k);
    if (numeric) {
      names.push_back(std::move(name));
      ++k;
    }
  }
  return names;
}

inline std::string join_names(std::vector<std::string> const& names) {
  std::string s;
  for (auto const& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "none" : s;
}

/// Keeps the arrays `declared` names, in that order; any other is moved to
/// the report's ignored list. Throws naming the first declared array missing.
template <class Array>
void match_declared(std::vector<Array>& arrays, std::vector<std::string> const& declared, char const* where,
                    char const* section, std::string const& context, ReadReport& report) {
  std::vector<Array> kept;
  kept.reserve(declared.size());
  for (auto const& name : declared) {
    auto it = std::find_if(arrays.begin(), arrays.end(), [&](Array const& a) { return a.name == name; });
    if (it == arrays.end())
      throw IoError(context + " does not match the .pvtu: no " + where + " array '" + name + "' (" + section +
                    " declares " + join_names(declared) + ")");
    kept.push_back(std::move(*it));
    arrays.erase(it);
  }
  for (auto const& a : arrays)
    report.arrays_ignored.push_back(std::string(where) + " '" + a.name + "' (not declared in the .pvtu)");
  arrays = std::move(kept);
}

/// Drops the cells a piece holds as ghosts of another piece's cells: those
/// whose cell array vtkGhostType has bit 0 (vtkDataSetAttributes::
/// DUPLICATECELL) set, with their cell-array values. A .pvtu written with
/// GhostLevel > 0 has them; merged, they would be there twice (and a volume
/// rendering would integrate them twice). Returns how many were dropped.
inline uint64_t drop_ghost_cells(UnstructuredGrid& g) {
  CellArray const* ghost = g.cell_array("vtkGhostType");
  if (!ghost) return 0;
  auto duplicate = [](float v) { return v >= 0.f && v < 256.f && (int(v) & 1) != 0; };
  std::vector<uint8_t> drop_tet(g.tet_count()), drop_hex(g.hex_count());
  uint64_t dropped = 0;
  for (size_t i = 0; i < drop_tet.size(); ++i) dropped += drop_tet[i] = duplicate(ghost->tet_values[i]);
  for (size_t i = 0; i < drop_hex.size(); ++i) dropped += drop_hex[i] = duplicate(ghost->hex_values[i]);
  if (!dropped) return 0;
  auto keep = [](auto& v, std::vector<uint8_t> const& drop, size_t per) {
    size_t o = 0;
    for (size_t c = 0; c < drop.size(); ++c)
      if (!drop[c]) {
        for (size_t k = 0; k < per; ++k) v[o * per + k] = v[c * per + k];
        ++o;
      }
    v.resize(o * per);
  };
  // The cells kept keep their file cell ids: spelled out where each was its index.
  auto spell_out = [](std::vector<uint32_t>& ids, uint64_t n) {
    if (!ids.empty() || n > std::numeric_limits<uint32_t>::max()) return;
    ids.resize(n);
    for (uint64_t i = 0; i < n; ++i) ids[i] = uint32_t(i);
  };
  spell_out(g.tet_file_cells, g.tet_count());
  spell_out(g.hex_file_cells, g.hex_count());
  if (g.tet_file_cells.size() == g.tet_count()) keep(g.tet_file_cells, drop_tet, 1);
  if (g.hex_file_cells.size() == g.hex_count()) keep(g.hex_file_cells, drop_hex, 1);
  keep(g.tets, drop_tet, 4);
  keep(g.hexes, drop_hex, 8);
  for (auto& a : g.cell_arrays) {
    keep(a.tet_values, drop_tet, 1);
    keep(a.hex_values, drop_hex, 1);
  }
  return dropped;
}

}  // namespace io

/// Reads the index of a .pvtu file: its pieces and the arrays it declares.
/// Each piece file must exist (a missing one is named with the .pvtu line of
/// its Piece); nothing else of the pieces is read. Thread-safe.
/// @throws IoError starting with `path` when the file cannot be read, is not
///         XML, its root is not <VTKFile type="PUnstructuredGrid">, it has no
///         PUnstructuredGrid element or no Piece, a Piece has no Source, or a
///         piece file is missing.
inline PvtuIndex read_pvtu_index(std::string const& path) {
  std::string const bytes = io::naming_out_of_memory(path, [&] { return io::read_file_bytes(path); });
  io::Source const src{bytes, path};
  auto at = [](pugi::xml_node n) { return uint64_t(std::max<ptrdiff_t>(n.offset_debug(), 0)); };
  pugi::xml_document doc;
  pugi::xml_parse_result const r = doc.load_buffer(bytes.data(), bytes.size(), pugi::parse_default, pugi::encoding_utf8);
  if (!r) src.fail_line(uint64_t(std::max<ptrdiff_t>(r.offset, 0)), std::string("XML error: ") + r.description());
  pugi::xml_node const root = doc.child("VTKFile");
  if (!root) src.fail_line(0, "not a VTK XML file (no VTKFile element)");
  std::string_view const type = root.attribute("type").value();
  if (type != "PUnstructuredGrid")
    src.fail_line(at(root), "VTK XML type " + io::in_quotes(type) +
                                " is not a parallel unstructured grid (a .pvtu has type=\"PUnstructuredGrid\")");
  pugi::xml_node const pug = root.child("PUnstructuredGrid");
  if (!pug) src.fail_line(at(root), "no PUnstructuredGrid element");

  PvtuIndex index;
  index.path = path;
  index.point_arrays = io::pvtu_array_names(pug.child("PPointData"), "point");
  index.cell_arrays = io::pvtu_array_names(pug.child("PCellData"), "cell");
  std::filesystem::path const folder = std::filesystem::path(path).parent_path();
  for (pugi::xml_node p : pug.children("Piece")) {
    std::string const k = std::to_string(index.pieces.size());
    std::string_view const source = p.attribute("Source").value();
    if (source.empty()) src.fail_line(at(p), "Piece " + k + " has no Source attribute (the .vtu file of the piece)");
    std::filesystem::path const s(source);
    std::string const file = (s.is_absolute() || folder.empty()) ? s.string() : (folder / s).string();
    std::error_code ec;
    if (!std::filesystem::exists(file, ec))
      src.fail_line(at(p), "piece " + k + ": " + file + " does not exist (Source=" + io::in_quotes(source) + ")");
    index.pieces.push_back(file);
  }
  if (index.pieces.empty()) src.fail_line(at(pug), "no Piece element");
  return index;
}

/// Reads piece `i` of `index` with read_vtu() and checks it against the
/// index: the piece must be a .vtu file holding every array the index
/// declares. The result keeps the declared arrays in the index's order (the
/// first point array, the active one, is the same in every piece); arrays
/// the index does not declare are dropped and listed in
/// `report.arrays_ignored`. Cells that cell array vtkGhostType marks as
/// duplicates (ghost cells of a file written with GhostLevel > 0) are
/// dropped: the piece that owns them holds them too. Thread-safe.
/// @throws InvalidArgument when `i` is not below `index.pieces.size()`.
/// @throws IoError starting with the piece's path and naming the piece
///         number and the .pvtu: the piece is not a .vtu, cannot be read (the
///         read_vtu() message), or lacks a declared array (named, with the
///         arrays the index declares).
inline UnstructuredGrid read_pvtu_piece(PvtuIndex const& index, size_t i, ReadOptions const& opts = {}) {
  if (i >= index.pieces.size())
    throw InvalidArgument(index.path + ": no piece " + std::to_string(i) + " (it has " +
                          std::to_string(index.pieces.size()) + ")");
  std::string const& file = index.pieces[i];
  std::string const context = file + " (piece " + std::to_string(i) + " of " + index.path + ")";
  std::string_view const ext = std::string_view(file).substr(std::min(file.size(), file.find_last_of("./")));
  if (!io::iequals(ext, ".vtu")) throw IoError(context + ": a .pvtu piece must be a .vtu file");
  UnstructuredGrid grid;
  try {
    grid = read_vtu(file, opts);
  } catch (IoError const& e) {
    throw IoError(std::string(e.what()) + " (piece " + std::to_string(i) + " of " + index.path + ")");
  }
  if (uint64_t const ghosts = io::drop_ghost_cells(grid))
    grid.report.arrays_ignored.push_back("cell 'vtkGhostType' flags " + std::to_string(ghosts) +
                                         " duplicate ghost cells: dropped, another piece owns them");
  io::match_declared(grid.point_arrays, index.point_arrays, "point", "PPointData", context, grid.report);
  io::match_declared(grid.cell_arrays, index.cell_arrays, "cell", "PCellData", context, grid.report);
  grid.report.arrays_read.clear();
  for (auto const& a : grid.point_arrays) grid.report.arrays_read.push_back(io::describe_array("point", a.name, a.components));
  for (auto const& a : grid.cell_arrays) grid.report.arrays_read.push_back(io::describe_array("cell", a.name, a.components));
  return grid;
}

/// One grid holding all of `grids`, in order: vertices appended (the ids of
/// grid k offset by the vertices before it), tetrahedra and hexahedra
/// appended, point arrays matched by name in the first grid's order. An
/// array some grid lacks is not defined everywhere and is dropped (listed in
/// `report.arrays_ignored`); a grid with no vertices (no cells) does not
/// count against a point (cell) array. ReadReport counts are summed, the
/// ignored lists joined; `report.file` is the first grid's file.
/// Vertices are not welded: points on piece borders, which a .pvtu holds once
/// per piece, stay separate vertices. The renderer treats piece borders as
/// ordinary interior faces for everything but face-neighbour marching, which
/// re-locates the ray there. Each input is freed once appended: peak memory
/// is about the inputs plus the result. File cell ids (tet_file_cells)
/// number the cells of grid k after those of the grids before it (the
/// cells of its file: ReadReport::cells_read), as ParaView numbers the
/// cells of a .pvtu.
/// @throws IoError when the merged grid would have more than 2^32-1 vertices.
inline UnstructuredGrid merge_grids(std::vector<UnstructuredGrid> grids) {
  UnstructuredGrid out;
  if (grids.empty()) return out;
  // A grid's file cells: those its reader counted, else (no reader) its own.
  auto file_cells = [](UnstructuredGrid const& g) {
    uint64_t n = 0;
    for (auto const& [type, count] : g.report.cells_read) n += count;
    return n ? n : g.tet_count() + g.hex_count();
  };
  uint64_t nv = 0, nt = 0, nh = 0, nfile = 0;
  bool ids_differ = false;  // from the cells' indices in the merged grid
  for (auto const& g : grids) {
    nv += g.vertex_count(), nt += g.tet_count(), nh += g.hex_count(), nfile += file_cells(g);
    ids_differ = ids_differ || !g.tet_file_cells.empty() || !g.hex_file_cells.empty();
  }
  ids_differ = (ids_differ || (nt && nh)) && nfile <= std::numeric_limits<uint32_t>::max();
  if (!io::point_count_fits(nv))
    throw IoError(grids[0].report.file + " and " + std::to_string(grids.size() - 1) + " more: merged, they hold " +
                  std::to_string(nv) + " vertices; cellray uses 32-bit vertex ids (at most 4294967295)");

  // Arrays every grid that has vertices (cells) defines, in the first grid's order.
  auto everywhere = [&](auto names_of, auto has, auto counts) {
    std::vector<std::string> names;
    UnstructuredGrid const* first = nullptr;
    for (auto const& g : grids)
      if (counts(g)) {
        first = &g;
        break;
      }
    if (!first) first = &grids[0];
    for (auto const& n : names_of(*first)) {
      bool all = true;
      for (auto const& g : grids) all = all && (!counts(g) || has(g, n));
      if (all) names.push_back(n);
    }
    return names;
  };
  auto point_names = [](UnstructuredGrid const& g) {
    std::vector<std::string> n;
    for (auto const& a : g.point_arrays) n.push_back(a.name);
    return n;
  };
  auto cell_names = [](UnstructuredGrid const& g) {
    std::vector<std::string> n;
    for (auto const& a : g.cell_arrays) n.push_back(a.name);
    return n;
  };
  std::vector<std::string> const pnames = everywhere(
      point_names, [](UnstructuredGrid const& g, std::string const& n) { return g.point_array(n) != nullptr; },
      [](UnstructuredGrid const& g) { return g.vertex_count() > 0; });
  std::vector<std::string> const cnames = everywhere(
      cell_names, [](UnstructuredGrid const& g, std::string const& n) { return g.cell_array(n) != nullptr; },
      [](UnstructuredGrid const& g) { return !g.empty(); });

  out.report.file = grids[0].report.file;
  out.xyz.reserve(3 * nv);
  out.tets.reserve(4 * nt);
  out.hexes.reserve(8 * nh);
  for (auto const& n : pnames) {
    PointArray a;
    a.name = n;
    a.values.reserve(nv);
    out.point_arrays.push_back(std::move(a));
  }
  for (auto const& n : cnames) {
    CellArray a;
    a.name = n;
    a.tet_values.reserve(nt);
    a.hex_values.reserve(nh);
    out.cell_arrays.push_back(std::move(a));
  }
  std::set<std::string> formats, ignored_seen, dropped_seen;
  std::vector<std::string> dropped;
  uint64_t cell_base = 0;
  if (ids_differ) out.tet_file_cells.reserve(nt), out.hex_file_cells.reserve(nh);
  for (auto& g : grids) {
    if (ids_differ) {
      for (uint64_t i = 0; i < g.tet_count(); ++i) out.tet_file_cells.push_back(uint32_t(cell_base + g.tet_file_cell(i)));
      for (uint64_t i = 0; i < g.hex_count(); ++i) out.hex_file_cells.push_back(uint32_t(cell_base + g.hex_file_cell(i)));
      cell_base += file_cells(g);
    }
    uint64_t const base = out.vertex_count();
    out.xyz.insert(out.xyz.end(), g.xyz.begin(), g.xyz.end());
    for (uint32_t v : g.tets) out.tets.push_back(uint32_t(base + v));
    for (uint32_t v : g.hexes) out.hexes.push_back(uint32_t(base + v));
    for (auto& a : out.point_arrays) {
      if (PointArray const* s = g.point_array(a.name)) {
        a.components = std::max(a.components, s->components);
        a.values.insert(a.values.end(), s->values.begin(), s->values.end());
      }
    }
    for (auto& a : out.cell_arrays) {
      if (CellArray const* s = g.cell_array(a.name)) {
        a.components = std::max(a.components, s->components);
        a.tet_values.insert(a.tet_values.end(), s->tet_values.begin(), s->tet_values.end());
        a.hex_values.insert(a.hex_values.end(), s->hex_values.begin(), s->hex_values.end());
      }
    }
    for (auto const& a : g.point_arrays)
      if (std::find(pnames.begin(), pnames.end(), a.name) == pnames.end() && dropped_seen.insert("p" + a.name).second)
        dropped.push_back("point '" + a.name + "' (not in every merged grid)");
    for (auto const& a : g.cell_arrays)
      if (std::find(cnames.begin(), cnames.end(), a.name) == cnames.end() && dropped_seen.insert("c" + a.name).second)
        dropped.push_back("cell '" + a.name + "' (not in every merged grid)");
    ReadReport const& r = g.report;
    if (!r.format.empty()) formats.insert(r.format);
    for (auto const& [type, count] : r.cells_read) out.report.cells_read[type] += count;
    for (auto const& [type, count] : r.cells_skipped) out.report.cells_skipped[type] += count;
    out.report.reduced_to_linear += r.reduced_to_linear;
    for (auto const& s : r.arrays_ignored)
      if (ignored_seen.insert(s).second) out.report.arrays_ignored.push_back(s);
    g = UnstructuredGrid{};  // free it now: the result is growing
  }
  // Vertices that no array covers cannot happen: an array is kept only when
  // every grid with vertices has it.
  for (auto const& a : out.point_arrays) out.report.arrays_read.push_back(io::describe_array("point", a.name, a.components));
  for (auto const& a : out.cell_arrays) out.report.arrays_read.push_back(io::describe_array("cell", a.name, a.components));
  out.report.arrays_ignored.insert(out.report.arrays_ignored.end(), dropped.begin(), dropped.end());
  for (auto const& f : formats) out.report.format += (out.report.format.empty() ? "" : "; ") + f;
  return out;
}

/// Reads a .pvtu file: its index, then every piece (read_pvtu_piece()),
/// merged with merge_grids() (piece-border vertices are not welded, see
/// there). `report.file` is `path`; `report.format` says how many pieces
/// and their formats. Thread-safe.
/// @throws IoError as read_pvtu_index() and read_pvtu_piece(), or starting
///         with `path` when the pieces hold more than 2^32-1 vertices in all.
inline UnstructuredGrid read_pvtu(std::string const& path, ReadOptions const& opts = {}) {
  PvtuIndex const index = read_pvtu_index(path);
  std::vector<UnstructuredGrid> grids;
  grids.reserve(index.pieces.size());
  uint64_t nv = 0;
  for (size_t i = 0; i < index.pieces.size(); ++i) {
    grids.push_back(read_pvtu_piece(index, i, opts));
    nv += grids.back().vertex_count();
    if (!io::point_count_fits(nv))
      throw IoError(path + ": pieces 0 to " + std::to_string(i) + " hold " + std::to_string(nv) +
                    " vertices in all; cellray uses 32-bit vertex ids (at most 4294967295)");
  }
  UnstructuredGrid grid = merge_grids(std::move(grids));
  grid.report.file = path;
  grid.report.format = "VTK XML PUnstructuredGrid, " + std::to_string(index.pieces.size()) + " piece" +
                       (index.pieces.size() == 1 ? "" : "s") + " (" + grid.report.format + ")";
  return grid;
}

}  // namespace cellray
