#pragma once
// Fast builder for rebuild-every-frame use: a linear BVH (Lauterbach 2009,
// Karras 2012). Item centroids get 30-bit Morton codes on a 1024^3 grid over
// the centroid bounds (one scale for all axes, so cells stay cubic); a
// stable parallel radix sort (one MSD pass, then LSD per bucket) orders them; each range splits where its
// highest differing code bit flips (in the middle when all codes agree),
// and ranges of at most max_leaf_size items become leaves.

#include <array>

#include "build_common.hpp"

namespace cellray {
namespace detail {

/// Spreads the low 10 bits of `v` to every third bit.
constexpr uint32_t spread_bits10(uint32_t v) noexcept {
  v &= 0x3FFu;
  v = (v | (v << 16)) & 0x030000FFu;
  v = (v | (v << 8)) & 0x0300F00Fu;
  v = (v | (v << 4)) & 0x030C30C3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

/// spread_bits10 of every 10-bit value: three table loads per code.
struct SpreadTable {
  uint32_t v[1024];
  constexpr SpreadTable() : v() {
    for (uint32_t i = 0; i < 1024; ++i) v[i] = spread_bits10(i);
  }
};
inline constexpr SpreadTable spread_table{};

/// Stable parallel radix sort of n elements on a 30-bit key, built around
/// the Morton builder: `make(i)` produces element i, `emit(slot, x)`
/// receives the sorted elements (slot = rank). `a` and `tmp` are scratch of
/// n elements each. Passes:
///  1. make every element into `a` and count its top 8 key bits per fixed
///     block (one read of the boxes, no separate counting pass);
///  2. scatter `a` into `tmp` by those 8 bits (256 streams: the scatter
///     stays cache friendly, unlike 1024 or 2048);
///  3. per bucket, now small enough for the cache, as an independent task:
///     count both 11-bit digits of the other 22 bits in one read, scatter
///     tmp -> a by the low digit, then emit by the high digit (tiny buckets:
///     an insertion sort instead).
/// Stable, so the result is the one sorted order whatever the thread count.
template <class T, class Key, class Make, class Emit>
void radix_sort30(uint64_t n, T* a, T* tmp, Key const& key, Make const& make, Emit const& emit) {
  constexpr uint32_t top_shift = 22, buckets = 256, low_bits = 11, digit = 1u << low_bits;
  constexpr uint64_t block = uint64_t(1) << 16, tiny = 48;
  uint64_t const blocks = (n + block - 1) / block;
  std::vector<uint64_t> offset(blocks * buckets);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t k = r.begin(); k < r.end(); ++k) {
      uint64_t* h = offset.data() + k * buckets;
      for (uint64_t i = k * block, end = std::min(n, i + block); i < end; ++i) {
        T const x = make(i);
        a[i] = x;
        ++h[key(x) >> top_shift];
      }
    }
  });
  std::vector<uint64_t> bucket_begin(buckets + 1);
  uint64_t sum = 0;
  for (uint32_t d = 0; d < buckets; ++d) {
    bucket_begin[d] = sum;
    for (uint64_t k = 0; k < blocks; ++k) {
      uint64_t const c = offset[k * buckets + d];
      offset[k * buckets + d] = sum;
      sum += c;
    }
  }
  bucket_begin[buckets] = sum;
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t k = r.begin(); k < r.end(); ++k) {
      uint64_t* o = offset.data() + k * buckets;
      for (uint64_t i = k * block, end = std::min(n, i + block); i < end; ++i) tmp[o[key(a[i]) >> top_shift]++] = a[i];
    }
  });
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, buckets, 1), [&](tbb::blocked_range<uint32_t> const& r) {
    for (uint32_t d = r.begin(); d < r.end(); ++d) {
      uint64_t const b = bucket_begin[d], e = bucket_begin[d + 1];
      if (e - b <= tiny) {  // insertion sort (stable) in place
        for (uint64_t i = b + 1; i < e; ++i) {
          T const x = tmp[i];
          uint64_t j = i;
          for (; j > b && key(tmp[j - 1]) > key(x); --j) tmp[j] = tmp[j - 1];
          tmp[j] = x;
        }
        for (uint64_t i = b; i < e; ++i) emit(i, tmp[i]);
        continue;
      }
      uint32_t h0[digit] = {}, h1[digit] = {};  // bucket sizes fit 32 bits: < 2^32 items per BVH
      for (uint64_t i = b; i < e; ++i) {
        uint32_t const c = key(tmp[i]);
        ++h0[c & (digit - 1)];
        ++h1[(c >> low_bits) & (digit - 1)];
      }
      uint32_t at0 = 0, at1 = 0;
      for (uint32_t j = 0; j < digit; ++j) {
        uint32_t const c0 = h0[j], c1 = h1[j];
        h0[j] = at0, h1[j] = at1;
        at0 += c0, at1 += c1;
      }
      for (uint64_t i = b; i < e; ++i) a[b + h0[key(tmp[i]) & (digit - 1)]++] = tmp[i];
      for (uint64_t i = b; i < e; ++i) emit(b + h1[(key(a[i]) >> low_bits) & (digit - 1)]++, a[i]);
    }
  });
}

/// Fills items (sorted by Morton code of the item centroid) and codes (the
/// sorted codes) for items 0..n-1.
template <class Index>
void morton_order(ItemBox const* boxes, uint64_t n, Box3 const& cb, Index* items, uint32_t* codes) {
  // Scale in double: a float extent can overflow (coordinates near
  // FLT_MAX); the quantisation then runs in float lanes, where an overflow
  // gives inf (clamped to 1023) and inf - inf gives NaN (max(NaN, 0) = 0),
  // so no NaN or out-of-range value reaches the integer conversion.
  double const extent = std::max({double(cb.hi[0]) - cb.lo[0], double(cb.hi[1]) - cb.lo[1], double(cb.hi[2]) - cb.lo[2]});
  float const scale = extent > 0.0 ? float(1024.0 / extent) : 0.f;
  F4 const lo = F4::load(std::array<float, 4>{cb.lo[0], cb.lo[1], cb.lo[2], 0.f}.data());
  F4 const sc = F4::load(std::array<float, 4>{scale, scale, scale, 0.f}.data());
  F4 const zero = F4::splat(0.f), top = F4::splat(1023.f);
  auto code_of = [&](uint64_t i) {
    alignas(16) int32_t q[4];
    min(max((centroid4(boxes[i]) - lo) * sc, zero), top).to_int(q);
    return spread_table.v[q[0]] | spread_table.v[q[1]] << 1 | spread_table.v[q[2]] << 2;
  };
  if constexpr (sizeof(Index) == 4) {
    // Unset, and huge pages from 4 MB: with plain new[] their first writes
    // were 58% of the page faults of component8's first image.
    LargeVector<uint64_t> a(n), tmp(n);  // code << 32 | id
    radix_sort30(
        n, a.data(), tmp.data(), [](uint64_t x) { return uint32_t(x >> 32); },
        [&](uint64_t i) { return uint64_t(code_of(i)) << 32 | i; },
        [items, codes](uint64_t slot, uint64_t x) { items[slot] = Index(x), codes[slot] = uint32_t(x >> 32); });
  } else {
    struct Pair {
      uint32_t code;
      uint64_t id;
    };
    LargeVector<Pair> a(n), tmp(n);
    radix_sort30(
        n, a.data(), tmp.data(), [](Pair const& x) { return x.code; }, [&](uint64_t i) { return Pair{code_of(i), i}; },
        [items, codes](uint64_t slot, Pair const& x) { items[slot] = Index(x.id), codes[slot] = x.code; });
  }
}

template <class Index> struct MortonSplitter {
  uint32_t const* codes;
  ItemBox const* boxes;  ///< by item id (not reordered)
  Index const* items;
  uint32_t max_leaf;

  Bounds4 leaf_fit(uint64_t b, uint64_t e) const noexcept {
    Bounds4 f = Bounds4::empty();
    for (uint64_t i = b; i < e; ++i) f.grow(boxes[items[i]]);
    return f;
  }

  /// Before a private subtree is built: its leaves will read the boxes of
  /// items[b, e) in slot order, i.e. at random (boxes are by item id).
  /// Touching them in one branch-free loop first lets those cache misses
  /// overlap; inside the recursion they stall between its branches.
  void prepare(uint64_t b, uint64_t e) const noexcept {
    for (uint64_t i = b; i < e; ++i) __builtin_prefetch(boxes + items[i]);
  }

  /// Centroid bounds are not tracked (the codes carry the geometry).
  Split split(uint64_t b, uint64_t e, uint32_t /*depth*/, Box3 const& /*cb*/) const {
    uint64_t const n = e - b;
    if (n <= max_leaf) return {e, {}, {}};
    uint32_t const diff = codes[b] ^ codes[e - 1];
    if (diff == 0) return {b + n / 2, {}, {}};
    uint32_t const bit = uint32_t(1) << (31 - __builtin_clz(diff));
    // Codes in [b, e) agree above `bit` and are sorted: bit clear comes first.
    auto const m = std::partition_point(codes + b, codes + e, [bit](uint32_t c) { return (c & bit) == 0; });
    return {uint64_t(m - codes), {}, {}};
  }
};

}  // namespace detail
}  // namespace cellray
