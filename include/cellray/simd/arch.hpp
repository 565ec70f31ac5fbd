#pragma once
// Instruction sets cellray is compiled for, and which one this CPU runs.
//
// Kernels and traversals are templates on an `Arch` tag. The tags below are
// xsimd's own arch types for the three vector ISAs, plus `scalar` (width 1),
// which compiles the same template code with plain floats (a reference for
// the SIMD paths and a fallback for hosts that build no ISA units).

#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>

#include <xsimd/xsimd.hpp>

#include "../error.hpp"

// Code compiled with different ISA flags must not share out-of-line symbols:
// the linker keeps one copy of each weak (inline or template) function and
// may keep the AVX-512 one for a baseline caller (TOOLCHAIN.md, ODR trap).
// Helpers and kernels therefore live in an inline namespace named after the
// flags of the translation unit that compiles them; only arch-templated entry
// points and plain data types are shared across units.
#if defined(__AVX512BW__)
#define CELLRAY_ISA_NS isa_avx512
#elif defined(__AVX2__)
#define CELLRAY_ISA_NS isa_avx2
#elif defined(__SSE4_2__)
#define CELLRAY_ISA_NS isa_sse4
#else
#define CELLRAY_ISA_NS isa_base
#endif

namespace cellray {

using sse4_2 = xsimd::sse4_2;             ///< 4 float lanes, `-msse4.2`
using avx2 = xsimd::fma3<xsimd::avx2>;    ///< 8 float lanes, `-mavx2 -mfma`
using avx512 = xsimd::avx512bw;           ///< 16 float lanes, `-mavx512{f,cd,dq,bw}`

/// Width-1 arch: `vfloat<scalar>` is `float`, `vmask<scalar>` is `bool`.
struct scalar {
  static constexpr char const* name() noexcept { return "scalar"; }
};

/// The vector ISAs a runtime dispatcher chooses from, best last.
enum class Isa { sse4_2, avx2, avx512 };

inline constexpr Isa all_isas[] = {Isa::sse4_2, Isa::avx2, Isa::avx512};

/// "sse4", "avx2" or "avx512": the spelling of `CELLRAY_ISA` and `--isa`.
constexpr char const* isa_name(Isa isa) noexcept {
  switch (isa) {
    case Isa::sse4_2: return "sse4";
    case Isa::avx2: return "avx2";
    case Isa::avx512: return "avx512";
  }
  return "?";
}

/// Parses "sse4" (or "sse4_2", "sse4.2"), "avx2", "avx512".
/// @throws InvalidArgument naming the text and the accepted values.
inline Isa parse_isa(std::string_view text) {
  if (text == "sse4" || text == "sse4_2" || text == "sse4.2") return Isa::sse4_2;
  if (text == "avx2") return Isa::avx2;
  if (text == "avx512") return Isa::avx512;
  throw InvalidArgument("unknown ISA '" + std::string(text) +
                              "' (expected sse4, avx2 or avx512)");
}

/// True when this CPU (and its OS, which must save the wider registers) can
/// run code compiled for `isa`. GCC's and clang's cpu model checks XGETBV.
inline bool cpu_supports(Isa isa) noexcept {
  switch (isa) {
    case Isa::sse4_2: return __builtin_cpu_supports("sse4.2");
    case Isa::avx2: return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case Isa::avx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
             __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
  }
  return false;
}

#ifndef CELLRAY_ISA_COMPILED_MASK
/// Bit i set: the ISA units of `Isa(i)` are linked into this program.
/// `cellray_add_isa_units(target ISAS ...)` defines it for the target (and its
/// ISA units, so every translation unit agrees); the default is all three.
#define CELLRAY_ISA_COMPILED_MASK 7
#endif

/// True when this program contains the entry points compiled for `isa`.
constexpr bool isa_compiled(Isa isa) noexcept { return ((CELLRAY_ISA_COMPILED_MASK >> int(isa)) & 1) != 0; }

/// True when `isa` is both compiled into this program and supported here.
inline bool isa_available(Isa isa) noexcept { return isa_compiled(isa) && cpu_supports(isa); }

/// Why `isa` cannot run here ("" when it can): for error messages.
inline std::string isa_unavailable_reason(Isa isa) {
  if (!isa_compiled(isa))
    return std::string(isa_name(isa)) + " is not compiled into this program (CMake: CELLRAY_ISAS)";
  if (!cpu_supports(isa)) return std::string("this CPU does not support ") + isa_name(isa);
  return {};
}

/// The widest ISA that is compiled in and that this CPU supports.
/// @throws Error when there is none (e.g. a CPU below SSE4.2).
inline Isa best_isa() {
  for (Isa isa : {Isa::avx512, Isa::avx2, Isa::sse4_2})
    if (isa_available(isa)) return isa;
  throw Error("cellray: none of the ISAs compiled into this program runs on this CPU (SSE4.2 at least is needed)");
}

/// The ISA used when a call does not name one: `CELLRAY_ISA` from the
/// environment if set (it must be available here), else `best_isa()`.
/// @throws InvalidArgument for an unknown or unavailable `CELLRAY_ISA`.
inline Isa default_isa() {
  char const* env = std::getenv("CELLRAY_ISA");
  if (env == nullptr || *env == '\0' || std::string_view(env) == "auto") return best_isa();
  Isa isa = parse_isa(env);
  if (!isa_available(isa)) throw InvalidArgument(std::string("CELLRAY_ISA=") + env + ": " + isa_unavailable_reason(isa));
  return isa;
}

/// Maps an `Isa` value to its arch tag type and back.
template <Isa I> struct arch_of;
template <> struct arch_of<Isa::sse4_2> { using type = sse4_2; };
template <> struct arch_of<Isa::avx2> { using type = avx2; };
template <> struct arch_of<Isa::avx512> { using type = avx512; };

template <class Arch> constexpr Isa isa_of() noexcept {
  if constexpr (std::is_same_v<Arch, avx512>) return Isa::avx512;
  else if constexpr (std::is_same_v<Arch, avx2>) return Isa::avx2;
  else return Isa::sse4_2;
}

}  // namespace cellray
