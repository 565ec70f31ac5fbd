#pragma once
// Exodus II (".ex2", ".exo", ".e": Sandia's finite-element format, netCDF
// inside) for cellray-render, through the Exodus library itself (Debian
// libexodusii-dev). The library stays out of cellray's own headers: hosts
// that read Exodus have their own reader and hand cellray the arrays.
//
// read_exodus is compiled into a module of its own, libcellray-exodus.so
// (examples/exodus_module.cpp; built when the library is found), which
// cellray-render loads beside itself for an Exodus file only: Debian's
// Exodus library pulls in netCDF, HDF5, OpenMPI, curl and ~50 shared
// libraries whose loading and relocation cost every run of cellray-render
// ~30 ms of CPU and ~20 ms of wall time before main (`--help`: 36-45 ms of
// CPU linked, 9-10 without; scripts/first-image.sh's startup 39-41 ms
// linked, 17-22 without, on the team's VMs), whatever file it reads.
//
// Kept: every element block of volume elements (TETRA*, HEX*, WEDGE*,
// PYRAMID*, higher-order ones as their corner cells; the corner order is
// VTK's, as vtkExodusIIReader reads them), nodal variables as point arrays
// and element variables as cell arrays, at the first time step (ParaView
// opens a file there too). Blocks of other elements (shells, beams,
// spheres) are listed in the report as ignored; what cellray-render cannot
// read is an IoError naming the file and the block.

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include <cellray/io/detail.hpp>

#ifdef CELLRAY_WITH_EXODUS
#include <exodusII.h>
#else
#include <dlfcn.h>
#include <unistd.h>
#endif

namespace cellray::cli {

/// True for the extensions read_exodus reads.
inline bool is_exodus_path(std::string const& path) {
  size_t const dot = path.find_last_of("./");
  if (dot == std::string::npos || path[dot] != '.') return false;
  std::string const ext = path.substr(dot);
  return io::iequals(ext, ".ex2") || io::iequals(ext, ".exo") || io::iequals(ext, ".e") || io::iequals(ext, ".g");
}

#ifdef CELLRAY_WITH_EXODUS

/// VTK's linear cell type for an Exodus element type name (case-insensitive,
/// "HEX8", "hex", "TETRA10", ...), and the corners it keeps; 0 when the
/// element is not a volume cell cellray reads.
inline int exodus_vtk_type(std::string name, int& corners, bool& higher_order) {
  for (char& c : name) c = char(std::toupper(static_cast<unsigned char>(c)));
  auto starts = [&](char const* p) { return name.rfind(p, 0) == 0; };
  auto nodes = [&](size_t prefix) { return prefix < name.size() ? std::atoi(name.c_str() + prefix) : 0; };
  if (starts("TETRA")) return corners = 4, higher_order = nodes(5) > 4, 10;
  if (starts("TET")) return corners = 4, higher_order = nodes(3) > 4, 10;
  if (starts("HEX")) return corners = 8, higher_order = nodes(3) > 8, 12;
  if (starts("WEDGE")) return corners = 6, higher_order = nodes(5) > 6, 13;
  if (starts("PYRAMID")) return corners = 5, higher_order = nodes(7) > 5, 14;
  corners = 0;
  return 0;
}

/// Reads an Exodus II file (see the file comment).
/// @throws IoError naming the file (and the block) on any problem.
inline UnstructuredGrid read_exodus(std::string const& path, ReadOptions const& opts = {}) {
  io::require_regular_file(path);
  int word = int(sizeof(double)), io_word = 0;
  float version = 0.f;
  ex_opts(0);  // errors come back as return codes, not messages on stderr
  int const exo = ex_open(path.c_str(), EX_READ, &word, &io_word, &version);
  if (exo < 0) throw IoError(path + ": not an Exodus II file the Exodus library can open (error " + std::to_string(exo) + ")");
  struct Closer {
    int id;
    ~Closer() { ex_close(id); }
  } const closer{exo};
  auto check = [&](int status, std::string const& what) {
    if (status < 0) throw IoError(path + ": reading " + what + " failed (Exodus error " + std::to_string(status) + ")");
  };
  char title[MAX_LINE_LENGTH + 1] = {};
  int dim = 0, nnodes = 0, nelem = 0, nblocks = 0, nnode_sets = 0, nside_sets = 0;
  check(ex_get_init(exo, title, &dim, &nnodes, &nelem, &nblocks, &nnode_sets, &nside_sets), "the header");
  if (dim != 3) throw IoError(path + ": a " + std::to_string(dim) + "D mesh (cellray renders 3D volume meshes)");

  UnstructuredGrid grid;
  grid.report.file = path;
  grid.report.format = "Exodus II " + std::to_string(version).substr(0, 4);
  size_t const n = static_cast<size_t>(nnodes);
  std::vector<double> x(n), y(n), z(n);
  check(ex_get_coord(exo, x.data(), y.data(), z.data()), "the node coordinates");
  std::vector<double> xyz(3 * size_t(nnodes));
  for (size_t i = 0; i < size_t(nnodes); ++i) xyz[3 * i] = x[i], xyz[3 * i + 1] = y[i], xyz[3 * i + 2] = z[i];
  io::set_positions(grid, io::NumArray::owning(xyz), uint64_t(nnodes));

  std::vector<int> ids(static_cast<size_t>(nblocks));
  if (nblocks) check(ex_get_ids(exo, EX_ELEM_BLOCK, ids.data()), "the element block ids");
  int const steps = int(ex_inquire_int(exo, EX_INQ_TIME));
  int nelem_vars = 0;
  check(ex_get_variable_param(exo, EX_ELEM_BLOCK, &nelem_vars), "the element variable count");
  std::vector<int64_t> types, conn;
  std::vector<std::vector<double>> cell_values(static_cast<size_t>(nelem_vars));
  uint64_t higher_order = 0;
  // The element number map: the ids the solver gave the elements (ParaView's
  // GlobalElementId), 1..n when the file has none; by position among the
  // elements of every block, volume or not.
  std::vector<int> element_ids(static_cast<size_t>(nelem));
  if (nelem) check(ex_get_id_map(exo, EX_ELEM_MAP, element_ids.data()), "the element number map");
  std::vector<int> kept_ids;  // per entry of `types`
  size_t first_element = 0;   // of the block, among all blocks' elements
  for (int b = 0; b < nblocks; ++b) {
    char type_name[MAX_STR_LENGTH + 1] = {};
    int count = 0, per = 0, edges = 0, faces = 0, attrs = 0;
    std::string const block = "element block " + std::to_string(ids[size_t(b)]);
    check(ex_get_block(exo, EX_ELEM_BLOCK, ids[size_t(b)], type_name, &count, &per, &edges, &faces, &attrs), block);
    int corners = 0;
    bool high = false;
    int const vtk = exodus_vtk_type(type_name, corners, high);
    size_t const first = first_element;
    first_element += size_t(std::max(count, 0));
    if (first_element > element_ids.size())
      throw IoError(path + ": " + block + " holds elements past the header's " + std::to_string(nelem));
    if (!vtk || per < corners) {
      if (vtk && !opts.skip_unsupported_cells)
        throw IoError(path + ": " + block + " (" + type_name + ") has " + std::to_string(per) + " nodes per element, needs " +
                      std::to_string(corners));
      grid.report.other_ignored.push_back(block + ": " + std::to_string(count) + " " + type_name +
                                          " elements (not volume cells cellray reads)");
      continue;
    }
    std::vector<int> c(size_t(count) * size_t(per));
    if (count) check(ex_get_conn(exo, EX_ELEM_BLOCK, ids[size_t(b)], c.data(), nullptr, nullptr), block + "'s connectivity");
    for (int e = 0; e < count; ++e) {
      types.push_back(vtk);
      kept_ids.push_back(element_ids[first + size_t(e)]);
      for (int k = 0; k < corners; ++k) conn.push_back(int64_t(c[size_t(e) * size_t(per) + size_t(k)]) - 1);  // 1-based
    }
    higher_order += high ? uint64_t(count) : 0;
    for (int v = 0; v < nelem_vars; ++v) {
      std::vector<double> vals(size_t(count), std::numeric_limits<double>::quiet_NaN());
      if (steps > 0 && count) {
        // A variable a block does not have (the truth table) reads as an error: NaN there.
        if (ex_get_var(exo, 1, EX_ELEM_BLOCK, v + 1, ids[size_t(b)], count, vals.data()) < 0)
          std::fill(vals.begin(), vals.end(), std::numeric_limits<double>::quiet_NaN());
      }
      cell_values[size_t(v)].insert(cell_values[size_t(v)].end(), vals.begin(), vals.end());
    }
  }
  if (types.empty())
    throw IoError(path + ": no element block of volume elements (TETRA, HEX, WEDGE or PYRAMID)");
  uint64_t const ncells = types.size();
  std::vector<uint64_t> offsets(ncells + 1, 0);
  for (uint64_t i = 0; i < ncells; ++i) {
    uint64_t nodes;
    bool exact;
    io::classify_cell(types[i], nodes, exact);
    offsets[i + 1] = offsets[i] + nodes;
  }
  io::CellLocator where;
  where.type = [&](uint64_t c) { return path + ": cell " + std::to_string(c) + ": "; };
  where.conn = [&](uint64_t k) { return path + ": connectivity entry " + std::to_string(k) + ": "; };
  io::CellKinds const kinds = io::build_cells(
      ncells, io::NumArray::owning(types), io::NumArray::owning(conn),
      [&offsets](uint64_t c) { return std::pair<uint64_t, uint64_t>(offsets[c], offsets[c + 1]); }, uint64_t(nnodes), opts,
      grid, where);
  grid.report.reduced_to_linear += higher_order;
  // The file cell ids (UnstructuredGrid::tet_file_cells) are the element
  // numbers; none when one is not positive.
  grid.tet_file_cells.clear();
  grid.hex_file_cells.clear();
  if (std::all_of(kept_ids.begin(), kept_ids.end(), [](int id) { return id > 0; }))
    for (uint64_t c = 0; c < kinds.size(); ++c) {
      if (kinds[c] == 0) grid.tet_file_cells.push_back(uint32_t(kept_ids[c]));
      else if (kinds[c] == 1) grid.hex_file_cells.push_back(uint32_t(kept_ids[c]));
    }

  auto names = [&](ex_entity_type what, int n) {
    int const len = std::max<int>(int(ex_inquire_int(exo, EX_INQ_DB_MAX_USED_NAME_LENGTH)), MAX_STR_LENGTH);
    ex_set_max_name_length(exo, len);
    std::vector<std::vector<char>> store(size_t(n), std::vector<char>(size_t(len) + 1, '\0'));
    std::vector<char*> ptrs;
    for (auto& s : store) ptrs.push_back(s.data());
    if (n) check(ex_get_variable_names(exo, what, n, ptrs.data()), "the variable names");
    std::vector<std::string> out;
    for (auto& s : store) out.emplace_back(s.data());
    return out;
  };
  int nnode_vars = 0;
  check(ex_get_variable_param(exo, EX_NODAL, &nnode_vars), "the nodal variable count");
  std::vector<std::string> const node_names = names(EX_NODAL, nnode_vars);
  for (int v = 0; v < nnode_vars && steps > 0; ++v) {
    std::vector<double> vals(n);
    check(ex_get_var(exo, 1, EX_NODAL, v + 1, 1, nnodes, vals.data()), "nodal variable '" + node_names[size_t(v)] + "'");
    io::add_point_array(grid, node_names[size_t(v)], io::point_values(io::NumArray::owning(vals), 1, n), 1);
  }
  std::vector<std::string> const elem_names = names(EX_ELEM_BLOCK, nelem_vars);
  for (int v = 0; v < nelem_vars && steps > 0; ++v)
    io::add_cell_array(grid, elem_names[size_t(v)], io::NumArray::owning(cell_values[size_t(v)]), 1, kinds);
  if (steps > 1) grid.report.other_ignored.push_back("time steps 2 to " + std::to_string(steps) + " (the first is read)");
  if (nnode_sets || nside_sets)
    grid.report.other_ignored.push_back(std::to_string(nnode_sets) + " node sets and " + std::to_string(nside_sets) + " side sets");
  return grid;
}
#endif  // CELLRAY_WITH_EXODUS

/// The module's entry (examples/exodus_module.cpp): reads `path` into
/// `out`, or returns false with the reader's message in `error`.
using ReadExodusEntry = bool (*)(char const* path, ReadOptions const* opts, UnstructuredGrid* out, std::string* error);
inline constexpr char const* exodus_module_file = "libcellray-exodus.so";
inline constexpr char const* exodus_module_entry = "cellray_read_exodus";

#ifndef CELLRAY_WITH_EXODUS
/// Reads an Exodus II file through libcellray-exodus.so, the module in the
/// directory of the running executable, loaded on the first call.
/// @throws IoError naming the file, or the module when it cannot be loaded.
inline UnstructuredGrid read_exodus_through_module(std::string const& path, ReadOptions const& opts = {}) {
  static ReadExodusEntry entry = nullptr;
  static std::string load_error;
  static bool const loaded = [] {
    std::string dir = ".";
    std::vector<char> exe(4096, '\0');
    ssize_t const n = ::readlink("/proc/self/exe", exe.data(), exe.size() - 1);
    if (n > 0) {
      std::string const self(exe.data(), size_t(n));
      dir = self.substr(0, self.find_last_of('/'));
    }
    std::string const module = dir + "/" + exodus_module_file;
    void* handle = ::dlopen(module.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      char const* why = ::dlerror();
      load_error = "cellray-render reads Exodus II through " + module + ", which could not be loaded (" +
                   (why ? why : "unknown reason") +
                   "); it is built beside cellray-render when the Exodus II library is found (Debian libexodusii-dev; "
                   "scripts/install-deps.sh installs it)";
      return false;
    }
    entry = reinterpret_cast<ReadExodusEntry>(::dlsym(handle, exodus_module_entry));
    if (!entry) load_error = module + " has no " + exodus_module_entry + " (a module from another build?)";
    return entry != nullptr;
  }();
  if (!loaded) throw IoError(path + ": " + load_error);
  UnstructuredGrid grid;
  std::string error;
  if (!entry(path.c_str(), &opts, &grid, &error)) throw IoError(error);
  return grid;
}
#endif

}  // namespace cellray::cli
