// Generates a small tet mesh, builds its BVH, renders one isosurface, writes a
// PPM. Built with the SSE4.2 and AVX-512 units only: asking for AVX2 must
// throw InvalidArgument and best_isa() must never pick it.
#include <cstdio>

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
  cellray::write_ppm(argc > 1 ? argv[1] : "consumer.ppm", cellray::render_iso(scene, cam, iso));
}
