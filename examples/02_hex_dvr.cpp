// 02: a file in, a volume rendering out. Reads a legacy .vtk or .vtu mesh
// (tets, hexes or both), picks a point array, and renders it with direct
// volume rendering through a built-in transfer function.
// Usage: 02_hex_dvr mesh.vtk [array] [out.png]
#include <iostream>
#include <string>

#include <cellray/bvh/build.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/render/render.hpp>

int main(int argc, char** argv) try {
  if (argc < 2) {
    std::cerr << "usage: 02_hex_dvr mesh.vtk|mesh.vtu [array] [out.png]\n";
    return 2;
  }
  cellray::UnstructuredGrid grid = cellray::read_mesh(argv[1]);  // owns the arrays
  if (grid.point_arrays.empty()) throw cellray::InvalidMesh("the file has no point arrays");
  std::string const array = argc > 2 ? argv[2] : grid.point_arrays.front().name;
  cellray::HexMesh hexes = grid.hex_mesh().with_array(array);  // views into `grid`
  cellray::TetMesh tets = grid.tet_mesh().with_array(array);

  // One BVH per cell type; a Scene renders both together.
  cellray::MinMaxBvh hex_bvh, tet_bvh;
  cellray::Scene scene;
  float vmin = 1e30f, vmax = -1e30f;
  if (!hexes.empty()) {
    auto rep = cellray::validate(hexes);
    cellray::require_valid(rep, "hexahedra");
    vmin = std::min(vmin, rep.value_min), vmax = std::max(vmax, rep.value_max);
    hex_bvh = cellray::build_minmax_bvh(hexes);
    scene.hexes.push_back({hexes, &hex_bvh});
  }
  if (!tets.empty()) {
    auto rep = cellray::validate(tets);
    cellray::require_valid(rep, "tetrahedra");
    vmin = std::min(vmin, rep.value_min), vmax = std::max(vmax, rep.value_max);
    tet_bvh = cellray::build_minmax_bvh(tets);
    scene.tets.push_back({tets, &tet_bvh});
  }

  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  cellray::DvrParams dvr;
  dvr.tf = cellray::transfer_function_preset("inferno", vmin, vmax);
  dvr.tf.unit_distance = glm::length(hi - lo) / 10.f;  // opacity per a tenth of the diagonal
  dvr.background = {0.1f, 0.1f, 0.12f, 1.f};
  cellray::Image image = cellray::render_dvr(scene, cellray::fit_camera(lo, hi, 640, 480), dvr);
  cellray::write_image(argc > 3 ? argv[3] : "02_hex_dvr.png", image);
  return 0;
} catch (std::exception const& e) {
  std::cerr << "02_hex_dvr: " << e.what() << "\n";
  return 1;
}
