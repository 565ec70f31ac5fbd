#pragma once
// Ray sets shared by the traversal tests over the generated [-1, 1]^3 meshes,
// and the interval measure their coverage checks use.

#include <algorithm>
#include <random>
#include <utility>
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

/// Rays in the planes, along the lines and through the vertices of the
/// regular lattice of `n` cells per side over [-1, 1]^3, for every other
/// lattice line in one direction and every `every`-th in the other.
inline std::vector<Ray> lattice_rays(int n, int every) {
  std::vector<Ray> rays;
  float const h = 2.f / float(n);
  for (int i = 1; i < n; i += 2)
    for (int j = 1; j < n; j += every) {
      float const a = -1.f + h * float(i), b = -1.f + h * float(j);
      rays.push_back({{a, b, -1.5f}, 0.f, {0.f, 0.f, 1.f}, 3.f});                    // along an edge
      rays.push_back({{-1.5f, a, b + 0.5f * h}, 0.f, {1.f, 0.f, 0.f}, 3.f});         // in a face plane
      rays.push_back({{-1.5f, -1.5f, b}, 0.f, {1.f, 1.f, 0.f}, 3.f});                // face diagonals
      rays.push_back({{a, -1.5f, -1.5f}, 0.f, {0.f, 1.f, 1.f}, 3.f});                // face diagonals, through vertices
      rays.push_back({{-1.5f, -1.5f, -1.5f}, 0.f, {1.f, 1.f + 0.1f * a, 1.f}, 4.f});  // near the body diagonal
    }
  return rays;
}

/// Length of the union of [a, b] intervals clipped to [lo, hi].
inline double union_length(std::vector<std::pair<double, double>> v, double lo, double hi) {
  std::sort(v.begin(), v.end());
  double total = 0, end = lo;
  for (auto [a, b] : v) {
    a = std::max(a, end), b = std::min(b, hi);
    if (b > a) total += b - a, end = b;
  }
  return total;
}

}  // namespace cellray::test
