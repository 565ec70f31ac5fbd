#pragma once
// Test-only entry point: simd::gather_pairs (simd/batch.hpp) per ISA
// (tests/isa_simd_gather_pairs.cpp instantiates it).

#include <cstdint>

#include <cellray/dispatch/dispatch.hpp>

namespace cellray::test {

/// first[k], second[k] = the pair gather_pairs reads for idx[k], a batch
/// of the ISA's width at a time; n a multiple of 16 (every width).
template <class Arch> struct GatherPairsProbe {
  static void run(float const* pairs, int32_t const* idx, int n, float* first, float* second);
};
CELLRAY_EXTERN_ENTRY(GatherPairsProbe)

}  // namespace cellray::test
