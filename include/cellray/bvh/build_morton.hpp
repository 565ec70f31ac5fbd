#pragma once
// Fast builder for rebuild-every-frame use: a linear BVH (Lauterbach 2009,
// Karras 2012). Item centroids get 30-bit Morton codes on a 1024^3 grid over
// the centroid bounds (one scale for all axes, so cells stay cubic); a
// stable parallel LSD radix sort orders them; each range splits where its
// highest differing code bit flips (in the middle when all codes agree),
// and ranges of at most max_leaf_size items become leaves.

#include "build_common.hpp"

namespace cellray {
namespace detail {

/// Spreads the low 10 bits of `v` to every third bit.
inline uint32_t spread_bits10(uint32_t v) noexcept {
  v &= 0x3FFu;
  v = (v | (v << 16)) & 0x030000FFu;
  v = (v | (v << 8)) & 0x0300F00Fu;
  v = (v | (v << 4)) & 0x030C30C3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

/// Bits per radix-sort digit: 10 bits, 3 passes over 30-bit codes.
inline constexpr int radix_bits = 10;

/// Stable LSD radix sort of a[0, n) on the 30-bit `key(a[i])`, parallel over
/// fixed blocks (deterministic). `tmp` is scratch of n entries; returns the
/// buffer (a or tmp) that holds the result.
template <class T, class Key> T* radix_sort30(T* a, T* tmp, uint64_t n, Key const& key) {
  constexpr uint32_t radix = uint32_t(1) << radix_bits;
  constexpr uint64_t block = uint64_t(1) << 16;
  uint64_t const blocks = (n + block - 1) / block;
  std::vector<uint64_t> offset(blocks * radix);
  for (int shift = 0; shift < 30; shift += radix_bits) {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t k = r.begin(); k < r.end(); ++k) {
        uint64_t* h = offset.data() + k * radix;
        std::fill(h, h + radix, 0);
        for (uint64_t i = k * block, end = std::min(n, i + block); i < end; ++i) ++h[(key(a[i]) >> shift) & (radix - 1)];
      }
    });
    uint64_t sum = 0;
    for (uint32_t d = 0; d < radix; ++d)
      for (uint64_t k = 0; k < blocks; ++k) {
        uint64_t const c = offset[k * radix + d];
        offset[k * radix + d] = sum;
        sum += c;
      }
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t k = r.begin(); k < r.end(); ++k) {
        uint64_t* o = offset.data() + k * radix;
        for (uint64_t i = k * block, end = std::min(n, i + block); i < end; ++i)
          tmp[o[(key(a[i]) >> shift) & (radix - 1)]++] = a[i];
      }
    });
    std::swap(a, tmp);
  }
  return a;
}

/// Fills items (sorted by Morton code of the item centroid) and codes (the
/// sorted codes) for items 0..n-1.
template <class Index>
void morton_order(ItemBox const* boxes, uint64_t n, Box3 const& cb, Index* items, uint32_t* codes) {
  // Double: a float extent can overflow (coordinates near FLT_MAX), and
  // inf * 0 would give NaN, which must not reach the integer conversion.
  double const extent = std::max({double(cb.hi[0]) - cb.lo[0], double(cb.hi[1]) - cb.lo[1], double(cb.hi[2]) - cb.lo[2]});
  double const scale = extent > 0.0 ? 1024.0 / extent : 0.0;
  auto code_of = [&](uint64_t i) {
    float c[3];
    centroid2(boxes[i], c);
    uint32_t q[3];
    for (int k = 0; k < 3; ++k) {
      double const t = (double(c[k]) - cb.lo[k]) * scale;
      q[k] = t >= 0.0 ? uint32_t(std::min(t, 1023.0)) : 0u;  // NaN -> 0
    }
    return spread_bits10(q[0]) | spread_bits10(q[1]) << 1 | spread_bits10(q[2]) << 2;
  };
  if constexpr (sizeof(Index) == 4) {
    std::unique_ptr<uint64_t[]> a(new uint64_t[n]), tmp(new uint64_t[n]);  // code << 32 | id
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, scan_block), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t i = r.begin(); i < r.end(); ++i) a[i] = uint64_t(code_of(i)) << 32 | i;
    });
    uint64_t const* sorted = radix_sort30(a.get(), tmp.get(), n, [](uint64_t x) { return uint32_t(x >> 32); });
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
    Pair const* sorted = radix_sort30(a.get(), tmp.get(), n, [](Pair const& x) { return x.code; });
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
