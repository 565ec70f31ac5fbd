// GatherPairsProbe, GatherXyzProbe and GatherQuadsProbe
// (tests/support/gather_probe.hpp) for one ISA: compiled once per ISA with that ISA's flags.

#include <cellray/simd/batch.hpp>

#include "support/gather_probe.hpp"

namespace cellray::test {

template <class Arch>
void GatherPairsProbe<Arch>::run(float const* pairs, int32_t const* idx, int n, float* first, float* second) {
  constexpr int W = width<Arch>;
  for (int k = 0; k < n; k += W) {
    vfloat<Arch> a, b;
    simd::gather_pairs(pairs, vint<Arch>::load_unaligned(idx + k), a, b);
    a.store_unaligned(first + k), b.store_unaligned(second + k);
  }
}

CELLRAY_INSTANTIATE_ENTRY(GatherPairsProbe)

template <class Arch>
void GatherXyzProbe<Arch>::run(float const* xyz, int32_t vertex_count, int32_t const* idx, int n, float* x, float* y,
                               float* z) {
  constexpr int W = width<Arch>;
  for (int k = 0; k < n; k += W) {
    vfloat<Arch> a, b, c;
    simd::gather_xyz(xyz, vint<Arch>::load_unaligned(idx + k) * vint<Arch>(3), 3 * (vertex_count - 1), a, b, c);
    a.store_unaligned(x + k), b.store_unaligned(y + k), c.store_unaligned(z + k);
  }
}

CELLRAY_INSTANTIATE_ENTRY(GatherXyzProbe)

template <class Arch> void GatherQuadsProbe<Arch>::run(int32_t const* rows, int32_t const* idx, int n, int32_t* out) {
  constexpr int W = width<Arch>;
  for (int k = 0; k < n; k += W) {
    vint<Arch> q[4];
    simd::gather_quads(rows, vint<Arch>::load_unaligned(idx + k) * vint<Arch>(4), q);
    alignas(64) int32_t w[4][W];
    for (int j = 0; j < 4; ++j) q[j].store_aligned(w[j]);
    for (int l = 0; l < W; ++l)
      for (int j = 0; j < 4; ++j) out[4 * (k + l) + j] = w[j][l];
  }
}

CELLRAY_INSTANTIATE_ENTRY(GatherQuadsProbe)

}  // namespace cellray::test
