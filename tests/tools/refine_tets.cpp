// refine_tets IN_MESH OUT.vtk: a tetrahedral mesh four times as fine, for
// timing the first image of a ~2M-tet real mesh (issue #23; ../shared/data
// has none that large): each tet is split at its centroid into four (the
// centroid takes each corner's place in turn, so every child keeps its
// parent's orientation), the children in their parent's place in the cell
// order, the centroids after the file's vertices. Point arrays at a
// centroid are the mean of the four corners': the linear field of the
// parent, so the refined mesh renders the parent's picture. Written as a
// legacy binary VTK 4.2 file (big-endian, as foamToVTK and gmsh write them).
// Exit 0, or 1 with a message on stderr (hexahedra, wedges, pyramids,
// polyhedra: not refined; ids or a CELLS list beyond 32 bits).

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <cellray/io/read_mesh.hpp>

namespace {

uint32_t big_endian(uint32_t v) {
  return (v >> 24) | ((v >> 8) & 0xff00u) | ((v << 8) & 0xff0000u) | (v << 24);
}

struct File {
  std::FILE* f;
  std::string path;
  void text(std::string const& s) { write(s.data(), s.size()); }
  void write(void const* p, size_t n) {
    if (std::fwrite(p, 1, n, f) != n) throw std::runtime_error("cannot write " + path);
  }
  /// 32-bit words (floats or ints) in big-endian order.
  template <class T> void words(std::vector<T> const& v) {
    static_assert(sizeof(T) == 4);
    std::vector<uint32_t> be(v.size());
    for (size_t i = 0; i < v.size(); ++i) {
      uint32_t w;
      std::memcpy(&w, &v[i], 4);
      be[i] = big_endian(w);
    }
    write(be.data(), 4 * be.size());
  }
};

void refine(cellray::UnstructuredGrid const& g, std::string const& out_path) {
  if (!g.hexes.empty()) throw std::runtime_error("refines tetrahedral meshes only (this one has other cell types)");
  uint64_t const nv = g.vertex_count(), nt = g.tets.size() / 4;
  if (4 * nt > uint64_t(std::numeric_limits<int32_t>::max()) / 5 ||
      nv + nt > uint64_t(std::numeric_limits<int32_t>::max()))
    throw std::runtime_error("too many cells for a legacy file's 32-bit CELLS list");
  // The mean over tet c's corners of value(vertex id), in double.
  auto corner_mean = [&g](uint64_t c, auto const& value) {
    double sum = 0;
    for (int k = 0; k < 4; ++k) sum += value(g.tets[4 * c + uint64_t(k)]);
    return float(sum / 4);
  };
  std::vector<float> xyz(g.xyz);
  xyz.resize(3 * (nv + nt));
  for (uint64_t c = 0; c < nt; ++c)
    for (uint64_t a = 0; a < 3; ++a)
      xyz[3 * (nv + c) + a] = corner_mean(c, [&](uint64_t v) { return g.xyz[3 * v + a]; });
  std::vector<int32_t> cells;  // count, then ids, per cell
  cells.reserve(4 * nt * 5);
  for (uint64_t c = 0; c < nt; ++c)
    for (int child = 0; child < 4; ++child) {
      cells.push_back(4);
      for (int k = 0; k < 4; ++k) cells.push_back(int32_t(k == child ? nv + c : g.tets[4 * c + uint64_t(k)]));
    }
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(out_path.c_str(), "wb"), &std::fclose);
  if (!f) throw std::runtime_error("cannot create " + out_path);
  File out{f.get(), out_path};
  out.text("# vtk DataFile Version 4.2\nrefine_tets: each tet split at its centroid\nBINARY\n"
           "DATASET UNSTRUCTURED_GRID\nPOINTS " + std::to_string(nv + nt) + " float\n");
  out.words(xyz);
  out.text("\nCELLS " + std::to_string(4 * nt) + " " + std::to_string(cells.size()) + "\n");
  out.words(cells);
  out.text("\nCELL_TYPES " + std::to_string(4 * nt) + "\n");
  out.words(std::vector<int32_t>(4 * nt, 10));
  out.text("\nPOINT_DATA " + std::to_string(nv + nt) + "\n");
  for (auto const& a : g.point_arrays) {
    std::vector<float> v(a.values);
    v.resize(nv + nt);
    for (uint64_t c = 0; c < nt; ++c) v[nv + c] = corner_mean(c, [&](uint64_t i) { return a.values[i]; });
    out.text("SCALARS " + a.name + " float 1\nLOOKUP_TABLE default\n");
    out.words(v);
    out.text("\n");
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: refine_tets IN_MESH OUT.vtk  (each tetrahedron split at its centroid into four)\n";
    return 1;
  }
  try {
    refine(cellray::read_mesh(argv[1]), argv[2]);
  } catch (std::exception const& e) {
    std::cerr << "refine_tets: " << argv[1] << ": " << e.what() << "\n";
    return 1;
  }
  return 0;
}
