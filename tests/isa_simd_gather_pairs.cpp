// GatherPairsProbe (tests/support/gather_probe.hpp) for one ISA: compiled
// once per ISA with that ISA's flags.

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

}  // namespace cellray::test
