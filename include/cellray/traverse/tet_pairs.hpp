#pragma once
// (tet, lane) pairs of one ray packet, collected from packet leaves and
// clipped W at a time, one pair per lane. A tet's box is usually met by a
// few of a packet's lanes (2.4 of 16 on component8's DVR segment windows,
// AVX-512), so clipping a broadcast cell for the whole packet wastes most
// lanes. Each lane of a pair clip holds what a packet clip holds for that
// lane (the same ordered corners, ray and window), so the clip's results are
// bit for bit those of the packet clip. Copy-adapted from TetPairs in
// occlusion.hpp (whose pairs span K packets and carry their rays); the two
// could share one buffer. ISA units only.

#include <cstdint>

#include "../cells/corners.hpp"
#include "packet.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {

/// Up to W pairs (ordered tet corners, packet lane, cell id) awaiting a clip.
/// Plain storage: the owner decides when to flush (when full, and once the
/// traversal ends) and what a clip result means.
template <class A> struct PacketTetPairs {
  static constexpr int W = width<A>;
  alignas(64) float x[4][W] = {}, y[4][W] = {}, z[4][W] = {}, s[4][W] = {};
  alignas(64) int32_t id[4][W] = {};
  alignas(64) int32_t lane[W] = {};  ///< packet lane of each pair
  uint64_t cell[W] = {};
  int n = 0;

  bool full() const { return n == W; }

  /// Adds the pair (ordered corners `k` at positions `xyz`, lane `l`).
  CELLRAY_FORCE_INLINE void push(float const* xyz, ScalarCorners<4> const& k, int l, uint64_t cell_id) {
    int const at = n++;
    for (int j = 0; j < 4; ++j) {
      float const* q = xyz + 3 * k.v[j];
      x[j][at] = q[0], y[j][at] = q[1], z[j][at] = q[2];
      s[j][at] = k.s[j], id[j][at] = k.key[j];
    }
    lane[at] = int32_t(l);
    cell[at] = cell_id;
  }

  /// The pairs' corners, one pair per lane (lanes >= n hold stale or zero
  /// corners: mask them off with live()).
  CellCorners<A, 4> corners() const {
    CellCorners<A, 4> c;
    for (int j = 0; j < 4; ++j) {
      c.x[j] = simd::load<A>(x[j]), c.y[j] = simd::load<A>(y[j]), c.z[j] = simd::load<A>(z[j]);
      c.s[j] = simd::load<A>(s[j]), c.id[j] = simd::load<A>(id[j]);
    }
    return c;
  }
  /// Lanes holding a pair.
  vmask<A> live() const { return simd::mask_from_bits<A>(n >= 32 ? ~0u : (1u << n) - 1u); }
  /// Per pair, the value of a per-lane packet array (ray components, windows).
  vfloat<A> of_lane(float const* per_lane) const {
    return simd::gather(per_lane, simd::load<A>(lane));
  }
};

}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
