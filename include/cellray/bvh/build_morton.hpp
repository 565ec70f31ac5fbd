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

/// Sort of a[0, n) on the 30-bit `key(a[i])`, stable; `tmp` is scratch of
/// n entries; the result is in `a`. One parallel MSD pass on the top 8 bits
/// over fixed blocks (256 streams: the scatter stays cache friendly, unlike
/// 1024), then every bucket, now small enough for the cache, gets three
/// LSD passes (8, 8, 6 bits) as an independent task. Stable, so the result
/// is the one sorted order whatever the thread count.
template <class T, class Key> void radix_sort30(T* a, T* tmp, uint64_t n, Key const& key) {
  constexpr uint32_t top_shift = 22, buckets = 256;
  constexpr uint64_t block = uint64_t(1) << 16;
  uint64_t const blocks = (n + block - 1) / block;
  std::vector<uint64_t> offset(blocks * buckets);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t k = r.begin(); k < r.end(); ++k) {
      uint64_t* h = offset.data() + k * buckets;
      for (uint64_t i = k * block, end = std::min(n, i + block); i < end; ++i) ++h[key(a[i]) >> top_shift];
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
      T* from = tmp;
      T* to = a;
      for (uint32_t shift : {0u, 8u, 16u}) {  // tmp -> a -> tmp -> a
        uint64_t h[256] = {};
        for (uint64_t i = b; i < e; ++i) ++h[(key(from[i]) >> shift) & 0xFFu];
        uint64_t at = b;
        for (auto& c : h) {
          uint64_t const cnt = c;
          c = at;
          at += cnt;
        }
        for (uint64_t i = b; i < e; ++i) to[h[(key(from[i]) >> shift) & 0xFFu]++] = from[i];
        std::swap(from, to);
      }
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
    std::unique_ptr<uint64_t[]> a(new uint64_t[n]), tmp(new uint64_t[n]);  // code << 32 | id
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) a[i] = uint64_t(code_of(i)) << 32 | i;
    });
    radix_sort30(a.get(), tmp.get(), n, [](uint64_t x) { return uint32_t(x >> 32); });
    uint64_t const* sorted = a.get();
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) items[i] = Index(sorted[i]), codes[i] = uint32_t(sorted[i] >> 32);
    });
  } else {
    struct Pair {
      uint32_t code;
      uint64_t id;
    };
    std::unique_ptr<Pair[]> a(new Pair[n]), tmp(new Pair[n]);
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) a[i] = {code_of(i), i};
    });
    radix_sort30(a.get(), tmp.get(), n, [](Pair const& x) { return x.code; });
    Pair const* sorted = a.get();
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) items[i] = Index(sorted[i].id), codes[i] = sorted[i].code;
    });
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
