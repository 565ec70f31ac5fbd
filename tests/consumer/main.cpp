// A host of the installed package. Part 1 (cellray::cellray): generates a
// small tet mesh, builds its BVH, renders one isosurface, writes a PPM. Built
// with the SSE4.2 and AVX-512 units only: asking for AVX2 must throw
// InvalidArgument and best_isa() must never pick it. Part 2 (cellray::io):
// reads a one-tet legacy VTK file and the same tet as VTU from memory
// (pugixml; zlib is linked for compressed VTU), renders it and writes a PNG
// (zlib).
// usage: consumer [out.ppm] [out.png] [scratch.vtk]
#include <cstdio>
#include <fstream>
#include <string>

#include <cellray/bvh/build.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/render.hpp>

namespace {

char const* const tet_vtk = R"(# vtk DataFile Version 3.0
one tet
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 4 float
0 0 0  1 0 0  0 1 0  0 0 1
CELLS 1 5
4 0 1 2 3
CELL_TYPES 1
10
POINT_DATA 4
SCALARS T float 1
LOOKUP_TABLE default
0 1 2 3
)";

char const* const tet_vtu = R"(<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt32">
<UnstructuredGrid><Piece NumberOfPoints="4" NumberOfCells="1">
<PointData><DataArray type="Float32" Name="T" NumberOfComponents="1" format="ascii">0 1 2 3</DataArray></PointData>
<Points><DataArray type="Float32" Name="Points" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>
<Cells>
<DataArray type="Int64" Name="connectivity" NumberOfComponents="1" format="ascii">0 1 2 3</DataArray>
<DataArray type="Int64" Name="offsets" NumberOfComponents="1" format="ascii">4</DataArray>
<DataArray type="UInt8" Name="types" NumberOfComponents="1" format="ascii">10</DataArray>
</Cells>
</Piece></UnstructuredGrid></VTKFile>
)";

bool is_the_tet(cellray::UnstructuredGrid const& g, char const* what) {
  cellray::PointArray const* t = g.point_array("T");
  if (g.tet_count() == 1 && g.vertex_count() == 4 && t && t->values.size() == 4 && t->values[3] == 3.f) return true;
  std::fprintf(stderr, "FAIL: %s: expected one tet with 4 values of T\n", what);
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  std::string const ppm = argc > 1 ? argv[1] : "consumer.ppm";
  std::string const png = argc > 2 ? argv[2] : "consumer.png";
  std::string const vtk = argc > 3 ? argv[3] : "consumer_tet.vtk";

  cellray::GeneratedMesh<4> data = cellray::generate_tets(20000);
  cellray::TetMesh mesh = data.mesh();
  cellray::MinMaxBvh bvh = cellray::build_minmax_bvh(mesh);
  cellray::Scene scene{mesh, bvh};
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  cellray::IsoParams iso;
  iso.surfaces = {cellray::IsoSurface{0.4f}};
  cellray::Camera const cam = cellray::fit_camera(lo, hi, 64, 48);
  if (cellray::best_isa() == cellray::Isa::avx2 || cellray::isa_compiled(cellray::Isa::avx2)) {
    std::fprintf(stderr, "FAIL: AVX2 counts as compiled in a build without its unit\n");
    return 1;
  }
  try {
    cellray::RenderOptions avx2;
    avx2.isa = cellray::Isa::avx2;
    cellray::render_iso(scene, cam, iso, avx2);
    std::fprintf(stderr, "FAIL: rendering with the AVX2 units left out did not throw\n");
    return 1;
  } catch (cellray::InvalidArgument const& e) {
    std::printf("ok: %s\n", e.what());
  }
  cellray::write_ppm(ppm, cellray::render_iso(scene, cam, iso));

  // cellray::io: the readers and the PNG writer.
  std::ofstream(vtk) << tet_vtk;
  cellray::UnstructuredGrid const from_file = cellray::read_mesh(vtk);
  cellray::UnstructuredGrid const from_memory = cellray::read_mesh_from_memory(tet_vtu, "tet.vtu");
  if (!is_the_tet(from_file, vtk.c_str()) || !is_the_tet(from_memory, "tet.vtu")) return 1;
  cellray::TetMesh const tet = from_memory.tet_mesh();
  cellray::MinMaxBvh const tet_bvh = cellray::build_minmax_bvh(tet);
  cellray::Scene const tet_scene{tet, tet_bvh};
  tet_scene.bounds(lo, hi);
  cellray::IsoParams tet_iso;
  tet_iso.surfaces = {cellray::IsoSurface{1.5f}};
  cellray::write_image(png, cellray::render_iso(tet_scene, cellray::fit_camera(lo, hi, 32, 24), tet_iso));
  std::printf("ok: read %s and tet.vtu, wrote %s\n", vtk.c_str(), png.c_str());
}
