// 01: the smallest host program. A tetrahedral mesh with a per-vertex scalar
// (here generated; in a host, spans over its own arrays), validated, one
// BVH, two nested isosurfaces, a PNG. Usage: 01_tet_iso [out.png]
#include <iostream>

#include <cellray/bvh/build.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/render/render.hpp>

int main(int argc, char** argv) try {
  // Owning arrays: positions, 4 vertex ids per tet, one value per vertex.
  cellray::GeneratedMesh<4> data = cellray::generate_tets(50000);
  // The view points at them; nothing is copied.
  cellray::TetMesh mesh{cellray::view(data.xyz), cellray::view(data.cells), cellray::view(data.field)};
  if (auto rep = cellray::validate(mesh); !rep.ok()) {
    std::cerr << rep << "\n";
    return 1;
  }
  cellray::MinMaxBvh bvh = cellray::build_minmax_bvh(mesh);
  cellray::Scene scene{mesh, bvh};

  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  cellray::Camera cam = cellray::fit_camera(lo, hi, 640, 480);
  // The outer surface half transparent so the inner one shows (paper Fig. 1).
  cellray::IsoParams iso;
  iso.surfaces = {{0.3f, {0.31f, 0.57f, 0.85f}, 0.4f}, {0.5f, {0.96f, 0.62f, 0.25f}, 1.f}};
  cellray::Image image = cellray::render_iso(scene, cam, iso);  // best ISA, all cores
  cellray::write_image(argc > 1 ? argv[1] : "01_tet_iso.png", image);
  return 0;
} catch (std::exception const& e) {
  std::cerr << "01_tet_iso: " << e.what() << "\n";
  return 1;
}
