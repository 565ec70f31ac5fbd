// Tet isosurface normals in the fast renderer (the analytic gradient the iso
// query keeps per hit cell, shaded W lanes at once) against the double
// reference renderer, on every ISA. Lighting is diffuse only from a fixed
// light, so each pixel is the surface colour times n.l: the image is a
// direct picture of the shading normals. The field has a large offset, as
// real data has (component8's temperatures near 400).

#include <catch2/catch.hpp>

#include <vector>

#include <cellray/mesh/generate.hpp>

#include "support/render_fixtures.hpp"
#include "support/sanitized.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_tet_normals {

using namespace cellray;
using namespace cellray::test;

TEST_CASE("fast vs reference: tet normals from the iso query on an offset field (diffuse light only)", "[render][reference][isa]") {
  auto const g = generate_tets(20000, 5);
  std::vector<float> offset(g.field.size());
  for (size_t v = 0; v < offset.size(); ++v) offset[v] = 400.f + 4.f * g.field[v];
  auto const l = load(g.mesh().with_values(view(offset)));
  int const size = full_or_sanitized(96, 48);
  Camera const cam = camera_for(l->scene(), size, size);
  IsoParams ip;
  ip.surfaces.push_back({401.8f, {1.f, 1.f, 1.f}, 1.f});
  ip.ambient = 0.f, ip.diffuse = 1.f, ip.specular = 0.f;
  ip.light_dir = {0.3f, 1.f, 0.5f};
  ImageDiff const d = compare_images(render_iso(l->scene(), cam, ip, isa_options()),
                                     render_iso_reference(l->scene(), cam, ip), 0.5);
  report("generated tets 20k, offset field, n.l", d);
  CHECK(d.nonfinite == 0);
  // A pixel whose hit lies within rounding of a face shared by two cells may
  // take either cell's (constant) gradient, in either renderer: those are
  // the only pixels allowed past half an 8-bit step. Bound 0.5% (measured:
  // see the test log).
  CHECK(d.frac_over <= 0.005);
  CHECK(d.max < 64.0);
}

}  // namespace test_render_tet_normals
