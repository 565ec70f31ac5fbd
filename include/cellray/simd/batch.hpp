#pragma once
// Width-templated batch aliases and the helpers xsimd 8.1 lacks.
//
// Code written against these compiles for every arch tag in arch.hpp,
// including `scalar` (plain float/int/bool). Kernels use only `+ - * /`,
// comparisons, `! && ||` on masks and the functions below, so one body serves
// all widths. Intrinsics live here only, behind `if constexpr`.

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include <immintrin.h>
#include <xsimd/xsimd.hpp>

#include "arch.hpp"

/// For the small kernels the traversal loops call per node or per cell:
/// GCC otherwise leaves some of them out of line in large loops, passing
/// every batch through memory.
#ifndef CELLRAY_FORCE_INLINE
#if defined(__GNUC__)
#define CELLRAY_FORCE_INLINE inline __attribute__((always_inline))
#else
#define CELLRAY_FORCE_INLINE inline
#endif
#endif

/// For rare paths inside hot kernels (a hex's triangular faces): kept out
/// of line so that the common path's unrolled loop stays small.
#ifndef CELLRAY_NOINLINE
#if defined(__GNUC__)
#define CELLRAY_NOINLINE __attribute__((noinline))
#else
#define CELLRAY_NOINLINE
#endif
#endif

/// Branch hints: the rare side is laid out off the hot path.
#if defined(__GNUC__)
#define CELLRAY_UNLIKELY(x) __builtin_expect(!!(x), 0)
#define CELLRAY_LIKELY(x) __builtin_expect(!!(x), 1)
#else
#define CELLRAY_UNLIKELY(x) (x)
#define CELLRAY_LIKELY(x) (x)
#endif

namespace cellray {
inline namespace CELLRAY_ISA_NS {

namespace isa_detail {
template <class Arch> struct batch_types {
  using f = xsimd::batch<float, Arch>;
  using i = xsimd::batch<int32_t, Arch>;
  using m = xsimd::batch_bool<float, Arch>;
  using mi = xsimd::batch_bool<int32_t, Arch>;
  static constexpr int width = int(f::size);
};
template <> struct batch_types<scalar> {
  using f = float;
  using i = int32_t;
  using m = bool;
  using mi = bool;
  static constexpr int width = 1;
};
}  // namespace isa_detail

template <class Arch> using vfloat = typename isa_detail::batch_types<Arch>::f;
template <class Arch> using vint = typename isa_detail::batch_types<Arch>::i;
template <class Arch> using vmask = typename isa_detail::batch_types<Arch>::m;
template <class Arch> using vmaski = typename isa_detail::batch_types<Arch>::mi;
/// Lanes per batch: 1, 4, 8 or 16.
template <class Arch> inline constexpr int width = isa_detail::batch_types<Arch>::width;

namespace simd {

template <class Arch> constexpr bool is_avx512 = std::is_base_of_v<xsimd::avx512f, Arch>;
template <class Arch> constexpr bool is_avx2 = std::is_base_of_v<xsimd::avx2, Arch>;

template <class Arch> inline vfloat<Arch> splat(float x) noexcept { return vfloat<Arch>(x); }
template <class Arch> inline vint<Arch> splat_int(int32_t x) noexcept { return vint<Arch>(x); }

/// Unaligned load of `width<Arch>` floats.
template <class Arch> inline vfloat<Arch> load(float const* p) noexcept {
  if constexpr (std::is_same_v<Arch, scalar>) return *p;
  else return vfloat<Arch>::load_unaligned(p);
}
template <class Arch> inline vint<Arch> load(int32_t const* p) noexcept {
  if constexpr (std::is_same_v<Arch, scalar>) return *p;
  else return vint<Arch>::load_unaligned(p);
}
inline void store(float* p, float v) noexcept { *p = v; }
inline void store(int32_t* p, int32_t v) noexcept { *p = v; }
template <class T, class A> inline void store(T* p, xsimd::batch<T, A> const& v) noexcept {
  v.store_unaligned(p);
}

/// Lane values as a std::array, for the scalar tails of SIMD code and tests.
template <class Arch, class V> inline auto to_array(V const& v) noexcept {
  using T = std::conditional_t<std::is_same_v<V, vint<Arch>>, int32_t, float>;
  std::array<T, width<Arch>> out{};
  simd::store(out.data(), v);
  return out;
}

/// 0, 1, ..., W-1.
template <class Arch> inline vint<Arch> lane_index() noexcept {
  std::array<int32_t, width<Arch>> idx{};
  for (int i = 0; i < width<Arch>; ++i) idx[size_t(i)] = i;
  return load<Arch>(idx.data());
}

inline float select(bool m, float a, float b) noexcept { return m ? a : b; }
inline int32_t select(bool m, int32_t a, int32_t b) noexcept { return m ? a : b; }
template <class T, class A>
inline xsimd::batch<T, A> select(xsimd::batch_bool<T, A> const& m, xsimd::batch<T, A> const& a,
                                 xsimd::batch<T, A> const& b) noexcept {
  // xsimd 8.1's AVX-512BW integer select does not compile with GCC at -O0
  // (its 8/16-bit blend branches are instantiated for int32 too).
  if constexpr (is_avx512<A> && std::is_same_v<T, int32_t>) return _mm512_mask_blend_epi32(m, b, a);
  else return xsimd::select(m, a, b);
}

/// dst[0..4) = v in one 128-bit store (every ISA unit has SSE): for W-wide
/// code that needs only a few lanes of a broadcast in memory.
inline void store_broadcast4(float* dst, float v) noexcept { _mm_storeu_ps(dst, _mm_set1_ps(v)); }
inline void store_broadcast4(int32_t* dst, int32_t v) noexcept {
  _mm_storeu_si128(reinterpret_cast<__m128i*>(dst), _mm_set1_epi32(v));
}

inline float min(float a, float b) noexcept { return a < b ? a : b; }
inline float max(float a, float b) noexcept { return a > b ? a : b; }
inline float abs(float a) noexcept { return std::fabs(a); }
inline float sqrt(float a) noexcept { return std::sqrt(a); }
inline float floor(float a) noexcept { return std::floor(a); }
inline float ceil(float a) noexcept { return std::ceil(a); }
/// a < b ? a : b (max: a > b ? a : b) lane by lane, as the scalar path: b
/// when unordered (NaN) and for equal values (+0 vs -0). That is exactly the
/// definition of x86's MINPS/MAXPS (DEST = SRC1 < SRC2 ? SRC1 : SRC2), which
/// xsimd 8.1 calls with (a, b) on SSE, AVX and AVX-512: one instruction
/// instead of a compare and a blend (2-3% of an iso or DVR frame).
template <class A> inline xsimd::batch<float, A> min(xsimd::batch<float, A> const& a, xsimd::batch<float, A> const& b) noexcept {
  return xsimd::min(a, b);
}
template <class A> inline xsimd::batch<float, A> max(xsimd::batch<float, A> const& a, xsimd::batch<float, A> const& b) noexcept {
  return xsimd::max(a, b);
}
template <class A> inline xsimd::batch<float, A> abs(xsimd::batch<float, A> const& a) noexcept { return xsimd::abs(a); }
template <class A> inline xsimd::batch<float, A> sqrt(xsimd::batch<float, A> const& a) noexcept { return xsimd::sqrt(a); }
template <class A> inline xsimd::batch<float, A> floor(xsimd::batch<float, A> const& a) noexcept { return xsimd::floor(a); }
template <class A> inline xsimd::batch<float, A> ceil(xsimd::batch<float, A> const& a) noexcept { return xsimd::ceil(a); }

/// a*b + c, fused on AVX2 and AVX-512 (xsimd 8.1 only fuses AVX-512 when the
/// compiler contracts `x*y+z`, which clang and -ffp-contract=off do not).
/// SSE4.2 has no FMA instruction, so it and the scalar path round twice.
inline float fmadd(float a, float b, float c) noexcept { return a * b + c; }
template <class A>
inline xsimd::batch<float, A> fmadd(xsimd::batch<float, A> const& a, xsimd::batch<float, A> const& b,
                                    xsimd::batch<float, A> const& c) noexcept {
  if constexpr (is_avx512<A>) return _mm512_fmadd_ps(a, b, c);
  else if constexpr (is_avx2<A>) return _mm256_fmadd_ps(a, b, c);
  else return a * b + c;
}

inline bool any(bool m) noexcept { return m; }
inline bool all(bool m) noexcept { return m; }
inline bool none(bool m) noexcept { return !m; }
template <class T, class A> inline bool any(xsimd::batch_bool<T, A> const& m) noexcept { return xsimd::any(m); }
template <class T, class A> inline bool all(xsimd::batch_bool<T, A> const& m) noexcept { return xsimd::all(m); }
template <class T, class A> inline bool none(xsimd::batch_bool<T, A> const& m) noexcept { return xsimd::none(m); }

/// Bit i set when lane i is true.
inline uint32_t movemask(bool m) noexcept { return m ? 1u : 0u; }
template <class A> inline uint32_t movemask(xsimd::batch_bool<float, A> const& m) noexcept {
  if constexpr (is_avx512<A>) return uint32_t(m.data);
  else if constexpr (std::is_base_of_v<xsimd::avx, A>) return uint32_t(_mm256_movemask_ps(m));
  else return uint32_t(_mm_movemask_ps(m));
}

/// Float mask <-> int mask, for selecting indices with a float comparison.
inline bool to_int_mask(bool m) noexcept { return m; }
inline bool to_float_mask(bool m) noexcept { return m; }
template <class A> inline xsimd::batch_bool<int32_t, A> to_int_mask(xsimd::batch_bool<float, A> const& m) noexcept {
  if constexpr (is_avx512<A>) return xsimd::batch_bool<int32_t, A>(m.data);
  else if constexpr (std::is_base_of_v<xsimd::avx, A>) return xsimd::batch_bool<int32_t, A>(_mm256_castps_si256(m));
  else return xsimd::batch_bool<int32_t, A>(_mm_castps_si128(m));
}
template <class A> inline xsimd::batch_bool<float, A> to_float_mask(xsimd::batch_bool<int32_t, A> const& m) noexcept {
  if constexpr (is_avx512<A>) return xsimd::batch_bool<float, A>(m.data);
  else if constexpr (std::is_base_of_v<xsimd::avx, A>) return xsimd::batch_bool<float, A>(_mm256_castsi256_ps(m));
  else return xsimd::batch_bool<float, A>(_mm_castsi128_ps(m));
}

/// Every lane false / every lane true. Hot code uses these, not
/// `vmask<A>(false)`: xsimd 8.1 builds that from one bool per lane through a
/// recursive template that g++ 12 leaves as a call on AVX-512 (a 16-argument
/// function in traversal and kernel loops, ~1% of an isosurface frame).
template <class Arch> inline vmask<Arch> no_lanes() noexcept {
  if constexpr (std::is_same_v<Arch, scalar>) return false;
  else if constexpr (is_avx512<Arch>) return vmask<Arch>(__mmask16(0));
  else return vfloat<Arch>(0.f) != vfloat<Arch>(0.f);
}
template <class Arch> inline vmask<Arch> all_lanes() noexcept {
  if constexpr (std::is_same_v<Arch, scalar>) return true;
  else if constexpr (is_avx512<Arch>) return vmask<Arch>(__mmask16(0xFFFF));
  else return vfloat<Arch>(0.f) == vfloat<Arch>(0.f);
}

/// Lane i true when bit i of `bits` is set.
template <class Arch> inline vmask<Arch> mask_from_bits(uint32_t bits) noexcept {
  if constexpr (std::is_same_v<Arch, scalar>) return (bits & 1u) != 0;
  else if constexpr (is_avx512<Arch>) return vmask<Arch>(__mmask16(bits));
  else {
    vint<Arch> bit = vint<Arch>(1) << lane_index<Arch>();
    return to_float_mask((vint<Arch>(int32_t(bits)) & bit) != vint<Arch>(0));
  }
}

/// base[idx[i]] per lane. Native gathers on AVX2 and AVX-512 (xsimd 8.1's
/// `gather` is a scalar loop). Every lane's index must be valid: clamp the
/// indices of inactive lanes to 0 first.
inline float gather(float const* base, int32_t idx) noexcept { return base[idx]; }
template <class A> inline xsimd::batch<float, A> gather(float const* base, xsimd::batch<int32_t, A> const& idx) noexcept {
  if constexpr (is_avx512<A>) return _mm512_i32gather_ps(idx, base, 4);
  else if constexpr (is_avx2<A>) return _mm256_i32gather_ps(base, idx, 4);
  else {
    alignas(16) int32_t i[4];
    idx.store_aligned(i);
    return _mm_setr_ps(base[i[0]], base[i[1]], base[i[2]], base[i[3]]);
  }
}
inline int32_t gather(int32_t const* base, int32_t idx) noexcept { return base[idx]; }
template <class A> inline xsimd::batch<int32_t, A> gather(int32_t const* base, xsimd::batch<int32_t, A> const& idx) noexcept {
  if constexpr (is_avx512<A>) return _mm512_i32gather_epi32(idx, base, 4);
  else if constexpr (is_avx2<A>) return _mm256_i32gather_epi32(base, idx, 4);
  else {
    alignas(16) int32_t i[4];
    idx.store_aligned(i);
    return _mm_setr_epi32(base[i[0]], base[i[1]], base[i[2]], base[i[3]]);
  }
}

/// pairs[2 idx[i]] into `first` and pairs[2 idx[i] + 1] into `second`, per
/// lane: one 64-bit gather a lane where the ISA has them (a linear table
/// lookup reads entries i and i + 1 stored side by side; two 32-bit gathers
/// cost about twice as much, docs/performance.md). Every index must be
/// valid, as for gather; `pairs` 8-byte aligned.
inline void gather_pairs(float const* pairs, int32_t idx, float& first, float& second) noexcept {
  first = pairs[2 * idx], second = pairs[2 * idx + 1];
}
template <class A>
inline void gather_pairs(float const* pairs, xsimd::batch<int32_t, A> const& idx, xsimd::batch<float, A>& first,
                         xsimd::batch<float, A>& second) noexcept {
  auto const* base = reinterpret_cast<double const*>(pairs);
  if constexpr (is_avx512<A>) {
    __m512i const i = idx;
    __m512 const lo = _mm512_castpd_ps(_mm512_i32gather_pd(_mm512_castsi512_si256(i), base, 8));
    __m512 const hi = _mm512_castpd_ps(_mm512_i32gather_pd(_mm512_extracti64x4_epi64(i, 1), base, 8));
    __m512i const even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
    first = _mm512_permutex2var_ps(lo, even, hi);
    second = _mm512_permutex2var_ps(lo, _mm512_add_epi32(even, _mm512_set1_epi32(1)), hi);
  } else if constexpr (is_avx2<A>) {
    __m256i const i = idx;
    // The masked form: GCC 12's unmasked one starts from _mm256_undefined_pd,
    // which -Wmaybe-uninitialized flags wherever it inlines.
    __m256d const zero = _mm256_setzero_pd(), all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    // lo = a0 b0 a1 b1 | a2 b2 a3 b3, hi = a4 b4 a5 b5 | a6 b6 a7 b7
    __m256 const lo = _mm256_castpd_ps(_mm256_mask_i32gather_pd(zero, base, _mm256_castsi256_si128(i), all, 8));
    __m256 const hi = _mm256_castpd_ps(_mm256_mask_i32gather_pd(zero, base, _mm256_extracti128_si256(i, 1), all, 8));
    // a0 a1 a4 a5 | a2 a3 a6 a7, then the middle 64-bit halves swapped
    __m256 const a = _mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0));
    __m256 const b = _mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1));
    first = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(a), _MM_SHUFFLE(3, 1, 2, 0)));
    second = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(b), _MM_SHUFFLE(3, 1, 2, 0)));
  } else {
    alignas(16) int32_t i[4];
    idx.store_aligned(i);
    first = _mm_setr_ps(pairs[2 * i[0]], pairs[2 * i[1]], pairs[2 * i[2]], pairs[2 * i[3]]);
    second = _mm_setr_ps(pairs[2 * i[0] + 1], pairs[2 * i[1] + 1], pairs[2 * i[2] + 1], pairs[2 * i[3] + 1]);
  }
}

/// gather_quads from offsets already stored to memory (`o`: one int a lane).
template <class A>
CELLRAY_FORCE_INLINE void quads_at_offsets(float const* base, int32_t const* o, xsimd::batch<float, A> (&out)[4]) noexcept {
  if constexpr (is_avx512<A>) {
    auto row = [&](int a, int b, int c, int d) {  // lanes a, b, c, d in the four 128-bit blocks
      __m512 r = _mm512_castps128_ps512(_mm_loadu_ps(base + o[a]));
      r = _mm512_insertf32x4(r, _mm_loadu_ps(base + o[b]), 1);
      r = _mm512_insertf32x4(r, _mm_loadu_ps(base + o[c]), 2);
      return _mm512_insertf32x4(r, _mm_loadu_ps(base + o[d]), 3);
    };
    __m512 const r0 = row(0, 4, 8, 12), r1 = row(1, 5, 9, 13), r2 = row(2, 6, 10, 14), r3 = row(3, 7, 11, 15);
    // Per 128-bit block: a0 a1 b0 b1, c0 c1 d0 d1, a2 a3 b2 b3, c2 c3 d2 d3.
    __m512d const t0 = _mm512_castps_pd(_mm512_unpacklo_ps(r0, r1)), t1 = _mm512_castps_pd(_mm512_unpackhi_ps(r0, r1));
    __m512d const t2 = _mm512_castps_pd(_mm512_unpacklo_ps(r2, r3)), t3 = _mm512_castps_pd(_mm512_unpackhi_ps(r2, r3));
    out[0] = _mm512_castpd_ps(_mm512_unpacklo_pd(t0, t2)), out[1] = _mm512_castpd_ps(_mm512_unpackhi_pd(t0, t2));
    out[2] = _mm512_castpd_ps(_mm512_unpacklo_pd(t1, t3)), out[3] = _mm512_castpd_ps(_mm512_unpackhi_pd(t1, t3));
  } else if constexpr (is_avx2<A>) {
    auto row = [&](int a, int b) {
      return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(base + o[a])), _mm_loadu_ps(base + o[b]), 1);
    };
    __m256 const r0 = row(0, 4), r1 = row(1, 5), r2 = row(2, 6), r3 = row(3, 7);
    __m256d const t0 = _mm256_castps_pd(_mm256_unpacklo_ps(r0, r1)), t1 = _mm256_castps_pd(_mm256_unpackhi_ps(r0, r1));
    __m256d const t2 = _mm256_castps_pd(_mm256_unpacklo_ps(r2, r3)), t3 = _mm256_castps_pd(_mm256_unpackhi_ps(r2, r3));
    out[0] = _mm256_castpd_ps(_mm256_unpacklo_pd(t0, t2)), out[1] = _mm256_castpd_ps(_mm256_unpackhi_pd(t0, t2));
    out[2] = _mm256_castpd_ps(_mm256_unpacklo_pd(t1, t3)), out[3] = _mm256_castpd_ps(_mm256_unpackhi_pd(t1, t3));
  } else {
    __m128 r0 = _mm_loadu_ps(base + o[0]), r1 = _mm_loadu_ps(base + o[1]), r2 = _mm_loadu_ps(base + o[2]),
           r3 = _mm_loadu_ps(base + o[3]);
    _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
    out[0] = r0, out[1] = r1, out[2] = r2, out[3] = r3;
  }
}

/// Four consecutive 32-bit words per lane, lane i's at `base + at[i]`, into
/// out[0..3] (word k of every lane in out[k]): one 16-byte load a lane and
/// a transpose, where 16-lane gathers of the four cost about twice as much
/// on the Zen 5 (docs/performance.md). Every lane's four words must be
/// readable.
template <class A>
inline void gather_quads(float const* base, xsimd::batch<int32_t, A> const& at, xsimd::batch<float, A> (&out)[4]) noexcept {
  alignas(64) int32_t o[xsimd::batch<int32_t, A>::size];
  at.store_aligned(o);
  quads_at_offsets<A>(base, o, out);
}

/// Three gather_quads from `base + at`, `base + at + 4` and `base + at + 8`
/// (12 consecutive words a lane), the offsets stored once; inlined.
template <class A>
CELLRAY_FORCE_INLINE void gather_quads3(float const* base, xsimd::batch<int32_t, A> const& at,
                                        xsimd::batch<float, A> (&q0)[4], xsimd::batch<float, A> (&q1)[4],
                                        xsimd::batch<float, A> (&q2)[4]) noexcept {
  alignas(64) int32_t o[xsimd::batch<int32_t, A>::size];
  at.store_aligned(o);
  quads_at_offsets<A>(base, o, q0), quads_at_offsets<A>(base + 4, o, q1), quads_at_offsets<A>(base + 8, o, q2);
}
inline void gather_quads3(float const* base, int32_t at, float (&q0)[4], float (&q1)[4], float (&q2)[4]) noexcept {
  for (int k = 0; k < 4; ++k) q0[k] = base[at + k], q1[k] = base[at + 4 + k], q2[k] = base[at + 8 + k];
}
inline void gather_quads(int32_t const* base, int32_t at, int32_t (&out)[4]) noexcept {
  for (int k = 0; k < 4; ++k) out[k] = base[at + k];
}
/// gather_quads of 32-bit integers (a cell's vertex ids).
template <class A>
inline void gather_quads(int32_t const* base, xsimd::batch<int32_t, A> const& at,
                         xsimd::batch<int32_t, A> (&out)[4]) noexcept {
  xsimd::batch<float, A> f[4];
  gather_quads<A>(reinterpret_cast<float const*>(base), at, f);
  for (int k = 0; k < 4; ++k) out[k] = xsimd::bitwise_cast<xsimd::batch<int32_t, A>>(f[k]);
}

/// Points stored as x y z triples: lane i's point at `xyz + at[i]` into x, y
/// and z. Where every lane's point has another float after it (at[i] <
/// `last`, the offset of the array's last point), gather_quads' loads and
/// transpose; else gathers. Every offset must be valid, as for gather.
inline void gather_xyz(float const* xyz, int32_t at, int32_t, float& x, float& y, float& z) noexcept {
  x = xyz[at], y = xyz[at + 1], z = xyz[at + 2];
}
template <class A>
inline void gather_xyz(float const* xyz, xsimd::batch<int32_t, A> const& at, int32_t last, xsimd::batch<float, A>& x,
                       xsimd::batch<float, A>& y, xsimd::batch<float, A>& z) noexcept {
  if (xsimd::none(at >= xsimd::batch<int32_t, A>(last))) {
    xsimd::batch<float, A> q[4];
    gather_quads<A>(xyz, at, q);
    x = q[0], y = q[1], z = q[2];
    return;
  }
  x = gather(xyz, at), y = gather(xyz + 1, at), z = gather(xyz + 2, at);
}

inline bool isnan(float x) noexcept { return x != x; }
// Not `x != x`: xsimd compiles != to an ordered compare on AVX (false for NaN).
template <class A> inline xsimd::batch_bool<float, A> isnan(xsimd::batch<float, A> const& x) noexcept { return !(x == x); }

/// NaN and +-inf: the scalar values that make a cell invisible (a field
/// value of inf has no place in a transfer function or an isosurface).
inline bool not_finite(float x) noexcept { return !(std::fabs(x) <= std::numeric_limits<float>::max()); }
template <class A> inline xsimd::batch_bool<float, A> not_finite(xsimd::batch<float, A> const& x) noexcept {
  return !(xsimd::abs(x) <= xsimd::batch<float, A>(std::numeric_limits<float>::max()));
}
/// `x`, or NaN where it is +-inf: corner values enter the kernels this way,
/// so every NaN rule downstream covers inf too.
inline float finite_or_nan(float x) noexcept { return not_finite(x) ? std::numeric_limits<float>::quiet_NaN() : x; }
template <class A> inline xsimd::batch<float, A> finite_or_nan(xsimd::batch<float, A> const& x) noexcept {
  return xsimd::select(not_finite(x), xsimd::batch<float, A>(std::numeric_limits<float>::quiet_NaN()), x);
}

}  // namespace simd
}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
