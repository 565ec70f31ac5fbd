#pragma once
// Writes a grid as a ParaView-style .pvtu with k .vtu pieces, for the .pvtu
// reader's tests and tests/tools/split_pvtu.cpp (the MPI tests' inputs).
//
//   test::write_pvtu_pieces(grid, 3, "/tmp/x/mesh");  // mesh.pvtu, mesh_0.vtu .. mesh_2.vtu
//
// The cells, tetrahedra first then hexahedra, in the grid's order, are cut
// into k blocks of near-equal size, one per piece. A piece holds only the
// points its cells use (ascending original order), so points on piece
// borders are written once per piece, as ParaView writes them. Every point
// and cell array is written as one Float32 component ("ascii", %.9g: floats
// read back bitwise equal). With more pieces than cells some pieces are
// empty (0 points, 0 cells), still valid files.

#include <algorithm>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <cellray/error.hpp>
#include <cellray/io/grid.hpp>

namespace cellray::test {

namespace write_vtu_detail {

/// fopen/fclose with errors that name the file.
struct File {
  std::string path;
  std::FILE* f;
  explicit File(std::string p) : path(std::move(p)), f(std::fopen(path.c_str(), "w")) {
    if (!f) throw IoError(path + ": cannot open for writing");
  }
  File(File const&) = delete;
  File& operator=(File const&) = delete;
  ~File() {
    if (f) std::fclose(f);
  }
  void close() {
    bool const bad = std::ferror(f) != 0;
    int const rc = std::fclose(f);
    f = nullptr;
    if (bad || rc != 0) throw IoError(path + ": write failed");
  }
};

/// `s` with XML's five special characters escaped (array names, file names).
inline std::string xml_escaped(std::string const& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      case '\'': o += "&apos;"; break;
      default: o += c;
    }
  }
  return o;
}

inline void write_floats(std::FILE* f, std::vector<float> const& v) {
  for (size_t i = 0; i < v.size(); ++i) std::fprintf(f, (i % 9 == 8) ? "%.9g\n" : "%.9g ", double(v[i]));
  std::fputc('\n', f);
}

inline void float_array(std::FILE* f, char const* name, int ncomp, std::vector<float> const& v) {
  std::fprintf(f, "        <DataArray type=\"Float32\"");
  if (name) std::fprintf(f, " Name=\"%s\"", xml_escaped(name).c_str());
  std::fprintf(f, " NumberOfComponents=\"%d\" format=\"ascii\">\n", ncomp);
  write_floats(f, v);
  std::fprintf(f, "        </DataArray>\n");
}

}  // namespace write_vtu_detail

/// Writes `stem`.pvtu and `stem`_0.vtu .. `stem`_{pieces-1}.vtu (see above).
/// @throws InvalidArgument when pieces < 1; IoError when a file cannot be written.
inline void write_pvtu_pieces(UnstructuredGrid const& g, int pieces, std::string const& stem) {
  using namespace write_vtu_detail;
  if (pieces < 1) throw InvalidArgument("write_pvtu_pieces: pieces must be at least 1, not " + std::to_string(pieces));
  uint64_t const nt = g.tet_count(), nc = nt + g.hex_count();
  std::string const base = std::filesystem::path(stem).filename().string();
  uint64_t const k = uint64_t(pieces);
  std::vector<uint32_t> new_id(g.vertex_count(), UINT32_MAX);
  for (uint64_t p = 0; p < k; ++p) {
    uint64_t const c0 = nc * p / k, c1 = nc * (p + 1) / k;
    auto corners = [&](uint64_t c) { return c < nt ? 4 : 8; };
    auto corner = [&](uint64_t c, int j) { return c < nt ? g.tets[4 * c + uint64_t(j)] : g.hexes[8 * (c - nt) + uint64_t(j)]; };
    // Points of this piece: the ones its cells use, ascending.
    std::vector<uint32_t> used;
    for (uint64_t c = c0; c < c1; ++c)
      for (int j = 0; j < corners(c); ++j) {
        uint32_t const v = corner(c, j);
        if (new_id[v] == UINT32_MAX) {
          new_id[v] = 0;
          used.push_back(v);
        }
      }
    std::sort(used.begin(), used.end());
    for (size_t i = 0; i < used.size(); ++i) new_id[used[i]] = uint32_t(i);

    File out(stem + "_" + std::to_string(p) + ".vtu");
    std::FILE* f = out.f;
    std::fprintf(f, "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n");
    std::fprintf(f, "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%" PRIu64 "\">\n", used.size(), c1 - c0);
    std::fprintf(f, "      <PointData>\n");
    std::vector<float> vals;
    for (auto const& a : g.point_arrays) {
      vals.clear();
      for (uint32_t v : used) vals.push_back(a.values[v]);
      float_array(f, a.name.c_str(), 1, vals);
    }
    std::fprintf(f, "      </PointData>\n      <CellData>\n");
    for (auto const& a : g.cell_arrays) {
      vals.clear();
      for (uint64_t c = c0; c < c1; ++c) vals.push_back(c < nt ? a.tet_values[c] : a.hex_values[c - nt]);
      float_array(f, a.name.c_str(), 1, vals);
    }
    std::fprintf(f, "      </CellData>\n      <Points>\n");
    vals.clear();
    for (uint32_t v : used)
      for (int d = 0; d < 3; ++d) vals.push_back(g.xyz[3 * uint64_t(v) + uint64_t(d)]);
    float_array(f, nullptr, 3, vals);
    std::fprintf(f, "      </Points>\n      <Cells>\n");
    std::fprintf(f, "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for (uint64_t c = c0; c < c1; ++c) {
      for (int j = 0; j < corners(c); ++j) std::fprintf(f, "%" PRIu32 " ", new_id[corner(c, j)]);
      std::fputc('\n', f);
    }
    std::fprintf(f, "        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    uint64_t off = 0;
    for (uint64_t c = c0; c < c1; ++c) std::fprintf(f, "%" PRIu64 "\n", off += uint64_t(corners(c)));
    std::fprintf(f, "        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    for (uint64_t c = c0; c < c1; ++c) std::fprintf(f, "%d\n", c < nt ? 10 : 12);
    std::fprintf(f, "        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
    out.close();
    for (uint32_t v : used) new_id[v] = UINT32_MAX;
  }

  File out(stem + ".pvtu");
  std::FILE* f = out.f;
  std::fprintf(f, "<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n");
  std::fprintf(f, "  <PUnstructuredGrid GhostLevel=\"0\">\n    <PPointData>\n");
  for (auto const& a : g.point_arrays) std::fprintf(f, "      <PDataArray type=\"Float32\" Name=\"%s\"/>\n", xml_escaped(a.name).c_str());
  std::fprintf(f, "    </PPointData>\n    <PCellData>\n");
  for (auto const& a : g.cell_arrays) std::fprintf(f, "      <PDataArray type=\"Float32\" Name=\"%s\"/>\n", xml_escaped(a.name).c_str());
  std::fprintf(f, "    </PCellData>\n    <PPoints>\n      <PDataArray type=\"Float32\" NumberOfComponents=\"3\"/>\n    </PPoints>\n");
  for (uint64_t p = 0; p < k; ++p) std::fprintf(f, "    <Piece Source=\"%s_%" PRIu64 ".vtu\"/>\n", xml_escaped(base).c_str(), p);
  std::fprintf(f, "  </PUnstructuredGrid>\n</VTKFile>\n");
  out.close();
}

}  // namespace cellray::test
