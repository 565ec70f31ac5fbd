#pragma once
// Brute-force double-precision oracles over every cell of a mesh: what a
// traversal must find, computed without a tree and without float kernels.

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/glm.hpp>

#include <cellray/mesh/cell_mesh.hpp>
#include <cellray/traverse/ray.hpp>

namespace cellray::test {

struct RefHit {
  double t = std::numeric_limits<double>::infinity();
  uint64_t cell = ~uint64_t(0);
  int iso = -1;
};

/// Nearest crossing of any isovalue along the ray over all tets, in double.
/// In a tet the field is linear, so along the ray it is a + b t.
inline RefHit brute_force_first_hit(TetMesh const& mesh, Ray const& ray, std::vector<float> const& isos) {
  RefHit best;
  glm::dvec3 const o(ray.org), d(ray.dir);
  for (uint64_t c = 0; c < mesh.cell_count(); ++c) {
    glm::dvec3 p[4];
    double s[4];
    bool nan = false;
    for (int k = 0; k < 4; ++k) {
      p[k] = glm::dvec3(mesh.position(mesh.vertex(c, k)));
      s[k] = mesh.value(mesh.vertex(c, k));
      nan = nan || std::isnan(s[k]);
    }
    if (nan) continue;
    double tin = -1e300, tout = 1e300, a = 0, b = 0;
    bool ok = true;
    static constexpr int face[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
    for (int i = 0; i < 4 && ok; ++i) {
      glm::dvec3 const n = glm::cross(p[face[i][1]] - p[face[i][0]], p[face[i][2]] - p[face[i][0]]);
      double const h = glm::dot(n, p[i] - p[face[i][0]]);
      if (h == 0) {
        ok = false;
        break;
      }
      double const no = glm::dot(n, o - p[face[i][0]]) / h, nd = glm::dot(n, d) / h;  // lambda_i = no + t nd
      a += s[i] * no;
      b += s[i] * nd;
      if (nd > 0) tin = std::max(tin, -no / nd);
      else if (nd < 0) tout = std::min(tout, -no / nd);
      else if (no < 0) ok = false;
    }
    tin = std::max(tin, double(ray.tmin));
    tout = std::min(tout, double(ray.tmax));
    if (!ok || tin > tout || b == 0) continue;
    for (size_t k = 0; k < isos.size(); ++k) {
      double const t = (isos[k] - a) / b;
      if (t >= tin && t <= tout && t < best.t) best = {t, c, int(k)};
    }
  }
  return best;
}

}  // namespace cellray::test
