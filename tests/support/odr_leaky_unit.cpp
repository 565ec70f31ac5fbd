// Deliberately wrong ISA unit: an inline helper outside CELLRAY_ISA_NS that
// is not inlined away. The ODR check must reject this object (WILL_FAIL).
#include <cellray/simd/arch.hpp>

[[gnu::noinline]] inline float leaked_helper(float x) { return x * 2.f + 1.f; }

template <class Arch> struct LeakyEntry {
  static float run(float x) { return leaked_helper(x); }
};
template struct LeakyEntry<cellray::avx512>;
