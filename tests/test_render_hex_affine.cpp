// Isosurfaces through the hex fast paths (parallelogram faces as planes,
// the exact cubic of parallelepipeds, shading from the gradient the iso
// query computes at the hit): the fast renderer against the double
// reference on a sheared lattice of parallelepipeds, on a lattice mixing
// them with distorted hexes, and on the DNS box (a structured grid stored as
// hexes: the case the fast paths exist for).

#include <catch2/catch.hpp>

#include <string>

#include <cellray/io/read_mesh.hpp>

#include "support/render_fixtures.hpp"
#include "support/sanitized.hpp"
#include "support/sheared_lattice.hpp"
#include "support/test_data.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_render_hex_affine {

using namespace cellray;
using namespace cellray::test;

namespace {

/// Frame side: 96 in the Release build (every ISA), 48 under the sanitizers.
constexpr int frame = full_or_sanitized(96, 48);

/// Fast vs reference iso images: one opaque surface with analytic normals,
/// then two surfaces (the first transparent) with shadows and central
/// differences. Bound: pixels off by more than 2/255, as
/// test_render_reference.cpp's (measured 0 to 0.011% there).
void iso_vs_reference(std::string const& name, Scene const& scene, float iso1, float iso2) {
  Camera const cam = camera_for(scene, frame, frame);
  RenderOptions const ro = isa_options();
  IsoParams ip;
  ip.surfaces.push_back({iso1, {0.9f, 0.7f, 0.4f}, 1.f});
  ImageDiff const d1 = compare_images(render_iso(scene, cam, ip, ro), render_iso_reference(scene, cam, ip), 2.0);
  report(name + " iso (exact, analytic)", d1);
  CHECK(d1.nonfinite == 0);
  CHECK(d1.frac_over <= 0.005);
  ip.surfaces.front().opacity = 0.5f;
  ip.surfaces.push_back({iso2, {0.3f, 0.5f, 0.9f}, 1.f});
  ip.shadows = true;
  ip.light_dir = {0.3f, 1.f, 0.5f};
  ip.normals = GradientMethod::central;
  ImageDiff const d2 = compare_images(render_iso(scene, cam, ip, ro), render_iso_reference(scene, cam, ip), 2.0);
  report(name + " iso, 2 surfaces, transparent, shadows, central", d2);
  CHECK(d2.nonfinite == 0);
  CHECK(d2.frac_over <= 0.005);
}

}  // namespace

TEST_CASE("fast vs reference: parallelepiped and mixed hex lattices", "[render][reference][isa]") {
  OwnedMesh<8> const affine = sheared_lattice(12, 0.0, 3);
  auto const la = load(affine.mesh());
  iso_vs_reference("sheared lattice (parallelepipeds)", la->scene(), 0.3f, 1.0f);
  OwnedMesh<8> const mixed = sheared_lattice(12, 0.25, 4);
  auto const lm = load(mixed.mesh());
  iso_vs_reference("sheared lattice, half distorted", lm->scene(), 0.3f, 1.0f);
}

TEST_CASE("fast vs reference: boxturb48_dns (structured hexes)", "[render][reference][isa][data]") {
  auto const path = shared_data_file("openfoam/boxturb48_dns.vtk");
  if (!path) return;
  auto const g = read_mesh(*path);
  auto const l = load(g.hex_mesh().with_array("enstrophy"));
  iso_vs_reference("boxturb48_dns enstrophy", l->scene(), 0.1f, 0.3f);
}

}  // namespace test_render_hex_affine
