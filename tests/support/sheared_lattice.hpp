#pragma once
// A hexahedral lattice whose cells are parallelepipeds up to float rounding
// of their corners (the affine fast paths of cells/hex.hpp), optionally with
// one half distorted, for the cell and render tests of those paths.

#include <cmath>
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "adversarial.hpp"

namespace cellray::test {

/// n^3 hexes over lattice points mapped by a shear (double, rounded to
/// float: parallelepipeds up to rounding), vertex ids shuffled so canonical
/// face orders vary. Interior vertices with lattice x index above n/2 move
/// by up to `jitter` lattice spacings: cells there are distorted, the faces
/// they share with the undistorted half stay parallelograms.
inline OwnedMesh<8> sheared_lattice(int n, double jitter, uint64_t seed) {
  Rng rng(seed);
  int const p = n + 1;
  int const nv = p * p * p;
  std::vector<uint32_t> id(static_cast<size_t>(nv));
  std::iota(id.begin(), id.end(), 0u);
  for (int i = nv - 1; i > 0; --i) std::swap(id[size_t(i)], id[size_t(rng.next() % uint64_t(i + 1))]);
  glm::dvec3 const a(0.21, 0.03, -0.02), b(0.05, 0.19, 0.04), c(-0.03, 0.02, 0.23), o(-0.4, 0.1, 0.3);
  OwnedMesh<8> m;
  m.xyz.resize(size_t(nv) * 3);
  m.values.resize(size_t(nv));
  for (int k = 0; k < p; ++k)
    for (int j = 0; j < p; ++j)
      for (int i = 0; i < p; ++i) {
        glm::dvec3 x = o + double(i) * a + double(j) * b + double(k) * c;
        bool const interior = i > 0 && j > 0 && k > 0 && i < n && j < n && k < n;
        if (interior && 2 * i > n) x += jitter * 0.2 * rng.in_box(-1, 1);  // spacing ~0.2
        uint32_t const v = id[size_t((k * p + j) * p + i)];
        m.xyz[3 * v] = float(x.x), m.xyz[3 * v + 1] = float(x.y), m.xyz[3 * v + 2] = float(x.z);
        m.values[v] = float(std::sin(3.0 * x.x) + 0.7 * std::cos(2.0 * x.y + x.z) + 0.5 * x.z * x.z);
      }
  auto vid = [&](int i, int j, int k) { return id[size_t((k * p + j) * p + i)]; };
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        uint32_t const cell[8] = {vid(i, j, k),         vid(i + 1, j, k),         vid(i + 1, j + 1, k),
                                  vid(i, j + 1, k),     vid(i, j, k + 1),         vid(i + 1, j, k + 1),
                                  vid(i + 1, j + 1, k + 1), vid(i, j + 1, k + 1)};
        m.cells.insert(m.cells.end(), cell, cell + 8);
      }
  return m;
}

}  // namespace cellray::test
