#pragma once
// Runtime dispatch to per-ISA entry points.
//
// An entry point is a class template on the arch with static member
// functions whose signatures use plain types only (no batches):
//
//   template <class Arch> struct RenderTile { static void run(Scene const&, Tile, Rgba*); };
//   CELLRAY_EXTERN_ENTRY(RenderTile)          // in the header every unit sees
//
// Its bodies sit in an `_impl.hpp` header that only ISA units include
// (dispatch/isa_unit.cpp, compiled once per ISA with that ISA's flags), which
// instantiate it with `CELLRAY_INSTANTIATE_ENTRY(RenderTile)`. Callers built
// with baseline flags then call `dispatch<RenderTile>(isa, args...)`.

#include <utility>

#include "../simd/arch.hpp"

/// Declares that `Entry<Arch>` is instantiated in the ISA units, for each ISA.
#define CELLRAY_EXTERN_ENTRY(Entry)                  \
  extern template struct Entry<::cellray::sse4_2>;   \
  extern template struct Entry<::cellray::avx2>;     \
  extern template struct Entry<::cellray::avx512>;

#if defined(CELLRAY_ISA_UNIT)
// 0 = SSE4.2, 1 = AVX2+FMA, 2 = AVX-512 (set by cellray_add_isa_units()).
#if CELLRAY_ISA_UNIT == 2
#define CELLRAY_UNIT_ARCH ::cellray::avx512
#elif CELLRAY_ISA_UNIT == 1
#define CELLRAY_UNIT_ARCH ::cellray::avx2
#else
#define CELLRAY_UNIT_ARCH ::cellray::sse4_2
#endif
/// Instantiates `Entry` for the arch of the ISA unit being compiled.
#define CELLRAY_INSTANTIATE_ENTRY(Entry) template struct Entry<CELLRAY_UNIT_ARCH>;
#endif

namespace cellray {

/// Calls `Entry<arch of isa>::run(args...)`.
/// @throws InvalidArgument when `isa` is not compiled into this program.
template <template <class> class Entry, class... Args>
decltype(auto) dispatch(Isa isa, Args&&... args) {
  switch (isa) {
    case Isa::avx512:
      if constexpr (isa_compiled(Isa::avx512)) return Entry<avx512>::run(std::forward<Args>(args)...);
      break;
    case Isa::avx2:
      if constexpr (isa_compiled(Isa::avx2)) return Entry<avx2>::run(std::forward<Args>(args)...);
      break;
    case Isa::sse4_2:
      if constexpr (isa_compiled(Isa::sse4_2)) return Entry<sse4_2>::run(std::forward<Args>(args)...);
      break;
  }
  throw InvalidArgument(isa_unavailable_reason(isa));
}

}  // namespace cellray
