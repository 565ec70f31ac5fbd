#pragma once
// Holes cut into the generated [-1, 1]^3 meshes, for the tests of what
// marches and occlusion queries do where a ray leaves the mesh and
// comes back.

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include <cellray/mesh/generate.hpp>

namespace cellray::test {

/// The index rows of `g`'s cells whose vertex mean `drop` rejects, removed.
template <int N, class Drop> std::vector<uint32_t> cells_without(GeneratedMesh<N> const& g, Drop drop) {
  std::vector<uint32_t> out;
  for (size_t c = 0; c + N <= g.cells.size(); c += N) {
    glm::vec3 m(0.f);
    for (int i = 0; i < N; ++i) {
      float const* q = &g.xyz[3 * g.cells[c + size_t(i)]];
      m += glm::vec3(q[0], q[1], q[2]);
    }
    if (!drop(m / float(N))) out.insert(out.end(), g.cells.begin() + long(c), g.cells.begin() + long(c) + N);
  }
  return out;
}

}  // namespace cellray::test
