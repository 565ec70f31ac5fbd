#pragma once
// The ISA a test run is for: `--isa=sse4|avx2|avx512` on the command line
// (ctest registers every [isa] test once per ISA), else the best one here.

#include <cellray/simd/arch.hpp>

namespace cellray::test {

/// The ISA under test. Only meaningful inside tests tagged [isa].
Isa isa();

}  // namespace cellray::test
