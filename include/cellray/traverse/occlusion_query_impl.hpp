#pragma once
// Body of OcclusionEntry (ISA units only).

#include <algorithm>
#include <cstdint>

#include "occlusion.hpp"
#include "occlusion_query.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

template <class A, int N>
void occluded_rays(TreeView const& tree, CellMesh<N> const& mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                   bool grouped, uint8_t* out) {
  constexpr int W = width<A>, K = 4;
  int const threshold = q.hybrid_threshold > 0 ? q.hybrid_threshold : std::max(1, W / 4);
  uint64_t const step = grouped ? uint64_t(K * W) : uint64_t(W);
  for (uint64_t base = 0; base < n; base += step) {
    RayPacket<A> r[K];
    uint32_t entry[K] = {}, pending[K] = {};
    int const packets = grouped ? K : 1;
    for (int k = 0; k < packets; ++k) {
      uint64_t const from = base + uint64_t(k * W);
      int const cnt = from < n ? int(std::min<uint64_t>(W, n - from)) : 0;
      if (cnt == 0) {
        r[k] = r[0];
        continue;
      }
      r[k] = load_rays<A>(rays + from, cnt);
      entry[k] = simd::movemask(simd::mask_from_bits<A>(cnt >= 32 ? ~0u : (1u << cnt) - 1u) && r[k].tmin <= r[k].tmax);
      pending[k] = entry[k];
    }
    if (grouped) {
      occluded_packets<A, K>(tree, mesh, r, pending, q.isos, q.method);
    } else {
      vmask<A> const occ = occluded_in<A>(tree, mesh, r[0], simd::mask_from_bits<A>(entry[0]), q.isos, q.method,
                                          q.traversal, threshold);
      pending[0] = entry[0] & ~simd::movemask(occ);
    }
    for (int k = 0; k < packets; ++k)
      for (int l = 0; l < W; ++l) {
        uint64_t const i = base + uint64_t(k * W + l);
        if (i < n) out[i] = uint8_t((entry[k] & ~pending[k]) >> l & 1u);
      }
  }
}

}  // namespace impl
}  // namespace CELLRAY_ISA_NS

template <class Arch>
void OcclusionEntry<Arch>::run(TreeView const& tree, AnyCellMesh mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                               bool grouped, uint8_t* occluded) {
  mesh.visit([&](auto const& m) { impl::occluded_rays<Arch>(tree, m, rays, n, q, grouped, occluded); });
}

}  // namespace cellray
