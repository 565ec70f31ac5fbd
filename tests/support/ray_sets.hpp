#pragma once
// Ray sets shared by the traversal tests over the generated [-1, 1]^3 meshes.

#include <random>
#include <vector>

#include <glm/vec3.hpp>

#include <cellray/traverse/ray.hpp>

namespace cellray::test {

/// `n` rays from outside the cube towards points inside it, some from
/// around one point (coherent, as a packet's), every third from anywhere
/// within 2.5 (some start inside the mesh). `windows`: each ray's
/// [tmin, tmax] ends inside the mesh (in units of dir: the target is t = 1).
inline std::vector<Ray> random_rays(int n, uint32_t seed, bool windows) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f), u01(0.f, 1.f);
  std::vector<Ray> rays;
  for (int i = 0; i < n; ++i) {
    glm::vec3 const target(u(rng), u(rng), u(rng));
    glm::vec3 org = glm::vec3(u(rng), u(rng), u(rng)) * 0.3f + glm::vec3(0.f, 0.f, -2.5f);
    if (i % 3 == 2) org = glm::vec3(u(rng), u(rng), u(rng)) * 2.5f;
    Ray r{org, 0.f, target - org, 1e30f};
    if (windows) r.tmin = 0.6f + 0.4f * u01(rng), r.tmax = r.tmin + 0.05f + 0.3f * u01(rng);
    rays.push_back(r);
  }
  return rays;
}

}  // namespace cellray::test
