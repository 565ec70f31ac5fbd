// 03: queries without an image. Samples the field along a line through the
// mesh (ParaView's "plot over line") and at a few probe points, through the
// BVH, and prints each sample beside the analytic value it approximates.
// Points outside the mesh come back as NaN. Usage: 03_samples [samples]
#include <cstdio>
#include <cstdlib>
#include <vector>

#include <cellray/bvh/build.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/traverse/queries.hpp>

int main(int argc, char** argv) try {
  int const samples = argc > 1 ? std::atoi(argv[1]) : 21;
  if (samples < 2) throw cellray::InvalidArgument("need at least 2 samples");
  cellray::GeneratedMesh<8> data = cellray::generate_hexes(20000);
  cellray::HexMesh mesh = data.mesh();  // active array "field"
  cellray::MinMaxBvh bvh = cellray::build_minmax_bvh(mesh);
  cellray::TreeView tree(bvh);  // what the queries read: nodes, items, value ranges

  // A line a little longer than the mesh [-1,1]^3: its ends are outside.
  glm::vec3 const a(-1.2f, 0.1f, 0.2f), b(1.2f, 0.1f, 0.2f);
  cellray::Ray line{a, 0.f, b - a, 1.f};  // t in [0, 1] spans the line
  float const step = 1.f / float(samples - 1);
  std::vector<float> values = cellray::sample_rays(tree, mesh, {line}, step, samples);
  std::printf("%8s %12s %12s\n", "x", "sampled", "analytic");
  for (int k = 0; k < samples; ++k) {
    glm::vec3 const p = a + (float(k) * step) * (b - a);
    std::printf("%8.3f %12.6f %12.6f\n", double(p.x), double(values[size_t(k)]), double(cellray::analytic_field(p)));
  }

  // Scattered probes: xyz triples in, one value each out.
  std::vector<float> const probes = {0.f, 0.f, 0.f, 0.5f, -0.5f, 0.25f, 2.f, 0.f, 0.f};
  std::vector<float> const at = cellray::sample_points(tree, mesh, probes);
  for (size_t i = 0; i < at.size(); ++i)
    std::printf("probe (%g, %g, %g): %g\n", double(probes[3 * i]), double(probes[3 * i + 1]),
                double(probes[3 * i + 2]), double(at[i]));
  return 0;
} catch (std::exception const& e) {
  std::fprintf(stderr, "03_samples: %s\n", e.what());
  return 1;
}
