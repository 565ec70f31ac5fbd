#pragma once
// Test-only entry points: simd::gather_pairs, gather_xyz and gather_quads
// (simd/batch.hpp) per ISA (tests/isa_simd_gather_pairs.cpp instantiates
// them).

#include <cstdint>

#include <cellray/dispatch/dispatch.hpp>

namespace cellray::test {

/// first[k], second[k] = the pair gather_pairs reads for idx[k], a batch
/// of the ISA's width at a time; n a multiple of 16 (every width).
template <class Arch> struct GatherPairsProbe {
  static void run(float const* pairs, int32_t const* idx, int n, float* first, float* second);
};
CELLRAY_EXTERN_ENTRY(GatherPairsProbe)

/// x[k], y[k], z[k] = the point gather_xyz reads for vertex idx[k] of the
/// `vertex_count` points at `xyz`, a batch of the ISA's width at a time; n
/// a multiple of 16.
template <class Arch> struct GatherXyzProbe {
  static void run(float const* xyz, int32_t vertex_count, int32_t const* idx, int n, float* x, float* y, float* z);
};
CELLRAY_EXTERN_ENTRY(GatherXyzProbe)

/// out[4 k + j] = word j of the four gather_quads reads at rows + 4 idx[k]
/// (32-bit integers), a batch of the ISA's width at a time; n a multiple of 16.
template <class Arch> struct GatherQuadsProbe {
  static void run(int32_t const* rows, int32_t const* idx, int n, int32_t* out);
};
CELLRAY_EXTERN_ENTRY(GatherQuadsProbe)

}  // namespace cellray::test
