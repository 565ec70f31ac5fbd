#pragma once
// Query points in Morton (Z-curve) order, on TBB, and the pipeline that
// locates them in that order and hands the values back in the caller's
// order. Baseline code (no SIMD): sample_points calls it around the per-ISA
// point-location entry (probe.hpp).
//
// Why: random points (a probe filter over a box, particles) make every
// packet of W consecutive points a scatter over the whole mesh, so each
// visits W paths of the tree. Sorted, a packet lies in a few neighbouring
// cells and its points share one path. The order is a counting sort on the
// Morton code of a grid over the scene's bounds (2^k cells per axis, about 8
// points per grid cell, k <= 8), stable within a grid cell: two passes over
// the points, both parallel (per-block histograms), no comparison sort.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/vec3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "../memory.hpp"

namespace cellray {

namespace detail {

/// Spreads the low 10 bits of x to every third bit.
inline uint32_t spread_bits3(uint32_t x) {
  x &= 0x3FFu;
  x = (x | (x << 16)) & 0x030000FFu;
  x = (x | (x << 8)) & 0x0300F00Fu;
  x = (x | (x << 4)) & 0x030C30C3u;
  x = (x | (x << 2)) & 0x09249249u;
  return x;
}

/// Grid bits per axis for n points: about 8 points per grid cell, 1..8.
inline int morton_bits(uint64_t n) {
  double const b = std::log2(std::max(1.0, double(n) / 8.0)) / 3.0;
  return std::clamp(int(std::lround(b)), 1, 8);
}

/// The input positions of n points sorted by the Morton code of their grid
/// cell over [lo, hi] (points outside go to the nearest grid cell, points
/// with a NaN coordinate to cell 0); ties keep the input order. On TBB (the
/// caller's arena). Scratch: a histogram of 8^bits counts per block.
template <class Index>
void morton_order(float const* xyz, uint64_t n, glm::vec3 lo, glm::vec3 hi, LargeVector<Index>& index) {
  int const bits = morton_bits(n);
  uint32_t const cells = 1u << bits;
  uint32_t const buckets = 1u << (3 * bits);
  float scale[3];
  for (int a = 0; a < 3; ++a) {
    double const ext = double(hi[a]) - double(lo[a]);
    scale[a] = ext > 0 && std::isfinite(ext) ? float(double(cells) / ext) : 0.f;
    if (!std::isfinite(lo[a])) lo[a] = 0.f;
  }
  auto code_of = [&](uint64_t i) {
    uint32_t c = 0;
    for (int a = 0; a < 3; ++a) {
      float const q = (xyz[3 * i + uint64_t(a)] - lo[a]) * scale[a];
      // NaN fails both tests: grid cell 0.
      uint32_t const g = q >= float(cells - 1) ? cells - 1 : q > 0.f ? uint32_t(q) : 0u;
      c |= spread_bits3(g) << a;
    }
    return c;
  };
  // Blocks of at least 64k points, at most one per thread, each with its own
  // histogram; the codes are computed again in the second pass (cheaper
  // than writing and reading them back).
  uint64_t const threads = uint64_t(std::max(1, tbb::this_task_arena::max_concurrency()));
  uint64_t const blocks = std::max<uint64_t>(1, std::min(threads, n / 65536));
  uint64_t const per = (n + blocks - 1) / blocks;
  std::vector<std::vector<Index>> count(blocks);
  tbb::parallel_for(uint64_t(0), blocks, [&](uint64_t b) {
    std::vector<Index>& h = count[b];
    h.assign(buckets, Index(0));
    for (uint64_t i = b * per, e = std::min(n, (b + 1) * per); i < e; ++i) ++h[code_of(i)];
  });
  Index sum = 0;
  for (uint32_t c = 0; c < buckets; ++c)
    for (uint64_t b = 0; b < blocks; ++b) {
      Index const k = count[b][c];
      count[b][c] = sum;
      sum += k;
    }
  index.resize(n);
  tbb::parallel_for(uint64_t(0), blocks, [&](uint64_t b) {
    std::vector<Index>& pos = count[b];
    for (uint64_t i = b * per, e = std::min(n, (b + 1) * per); i < e; ++i) index[pos[code_of(i)]++] = Index(i);
  });
}

/// Points per TBB task of the locate pass: a multiple of every packet width.
inline constexpr uint64_t probe_chunk = 2048;

/// out[i] = the value at point i (NaN unless `locate` sets it), with
/// `locate(xyz, m, values)` filling the NaN entries of values[0, m) for the
/// points xyz[0, 3m) (several parts: one after the other, first part wins),
/// called on TBB over chunks of the points, in Morton order when `sort`
/// (bounds [lo, hi]; each chunk's points gathered into a buffer of the task
/// and their values scattered back), else in input order.
template <class Locate>
void probe_in_order(float const* xyz, uint64_t n, float* out, glm::vec3 lo, glm::vec3 hi, bool sort,
                    Locate const& locate) {
  constexpr float qnan = std::numeric_limits<float>::quiet_NaN();
  uint64_t const chunks = (n + probe_chunk - 1) / probe_chunk;
  if (!sort) {
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, chunks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
      for (uint64_t c = r.begin(); c < r.end(); ++c) {
        uint64_t const b = c * probe_chunk, m = std::min(probe_chunk, n - b);
        std::fill(out + b, out + b + m, qnan);
        locate(xyz + 3 * b, m, out + b);
      }
    });
    return;
  }
  auto run = [&](auto& index) {
    morton_order(xyz, n, lo, hi, index);
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, chunks, 1), [&](tbb::blocked_range<uint64_t> const& r) {
      float p[3 * probe_chunk], v[probe_chunk];
      for (uint64_t c = r.begin(); c < r.end(); ++c) {
        uint64_t const b = c * probe_chunk, m = std::min(probe_chunk, n - b);
        for (uint64_t j = 0; j < m; ++j) {
          uint64_t const i = uint64_t(index[b + j]);
          p[3 * j] = xyz[3 * i], p[3 * j + 1] = xyz[3 * i + 1], p[3 * j + 2] = xyz[3 * i + 2];
          v[j] = qnan;
        }
        locate(static_cast<float const*>(p), m, static_cast<float*>(v));
        for (uint64_t j = 0; j < m; ++j) out[index[b + j]] = v[j];
      }
    });
  };
  if (n <= uint64_t(std::numeric_limits<uint32_t>::max())) {
    LargeVector<uint32_t> index;
    run(index);
  } else {
    LargeVector<uint64_t> index;
    run(index);
  }
}

}  // namespace detail
}  // namespace cellray
