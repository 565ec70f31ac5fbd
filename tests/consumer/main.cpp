// Generates a small tet mesh, builds its BVH, renders one isosurface, writes a PPM.
#include <cellray/bvh/build.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/render.hpp>

int main(int argc, char** argv) {
  cellray::GeneratedMesh<4> data = cellray::generate_tets(20000);
  cellray::TetMesh mesh = data.mesh();
  cellray::MinMaxBvh bvh = cellray::build_minmax_bvh(mesh);
  cellray::Scene scene{mesh, bvh};
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  cellray::IsoParams iso;
  iso.surfaces = {cellray::IsoSurface{0.4f}};
  cellray::write_ppm(argc > 1 ? argv[1] : "consumer.ppm", cellray::render_iso(scene, cellray::fit_camera(lo, hi, 64, 48), iso));
}
