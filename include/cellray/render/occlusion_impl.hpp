#pragma once
// Shadow and ambient-occlusion rays over a whole scene (ISA units only):
// any-hit queries over every part, and a pixel block's AO rays regrouped by
// direction into dense packets (RenderOptions::secondary_query).

#include <cstdint>

#include "../traverse/occlusion.hpp"
#include "render.hpp"
#include "render_common.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

/// The lanes of `active` whose segment [tmin, tmax] crosses an isosurface
/// of any part of the scene; a lane occluded by one part is not searched in
/// the next.
template <class A>
inline vmask<A> scene_occluded(PreparedScene const& s, RayPacket<A> const& r, vmask<A> active, IsoSet const& isos,
                               CellIsoOptions const& roots, Traversal how, int threshold) {
  vmask<A> occ = simd::no_lanes<A>();
  for (PreparedPart const& part : s.parts) {
    vmask<A> const open = active && !occ;
    if (simd::none(open)) break;
    occ = occ || part.visit([&](auto const& mesh, auto const*) {
      return occluded_in<A>(part.tree, mesh, r, open, isos, roots, how, threshold);
    });
  }
  return occ;
}

/// Occlusion of `n` rays (n <= max_sorted_rays) traced in packets of W after
/// sorting them by direction_bin: rays of one pixel block leave from nearby
/// points, so rays of similar direction sweep the same nodes and cells.
/// Sets bit i of `occluded` (n bits, 64 per word) for occluded rays. Each
/// ray's answer is the one an unsorted packet gives: packet lanes never
/// change each other's answers.
/// `grouped`: the sorted rays go K packets at a time through one traversal
/// per part (occluded_packets); `how` and `threshold` are then unused.
inline constexpr int max_sorted_rays = 256;
inline constexpr int grouped_packets = 4;
template <class A>
inline void scene_occluded_sorted(PreparedScene const& s, Ray const* rays, int n, IsoSet const& isos,
                                  CellIsoOptions const& roots, Traversal how, int threshold, bool grouped,
                                  uint64_t* occluded) {
  constexpr int W = width<A>, K = grouped_packets;
  uint32_t key[max_sorted_rays];
  uint16_t order[max_sorted_rays];
  for (int i = 0; i < n; ++i) key[i] = direction_bin(rays[i].dir.x, rays[i].dir.y, rays[i].dir.z);
  sort_by_direction_bin(order, n, key);
  for (int i = 0; i < (n + 63) / 64; ++i) occluded[i] = 0;
  if (grouped) {
    for (int base = 0; base < n; base += K * W) {
      RayPacket<A> r[K];
      uint32_t entry[K], pending[K];
      for (int k = 0; k < K; ++k) {
        int const from = base + k * W, cnt = n - from < W ? n - from : W;
        entry[k] = pending[k] = cnt <= 0 ? 0u : cnt >= 32 ? ~0u : (1u << cnt) - 1u;
        if (cnt <= 0) {
          r[k] = r[0];
          continue;
        }
        Ray packet[W];
        for (int l = 0; l < cnt; ++l) packet[l] = rays[order[from + l]];
        r[k] = load_rays<A>(packet, cnt);
      }
      for (PreparedPart const& part : s.parts) {
        part.visit([&](auto const& mesh, auto const*) {
          occluded_packets<A, K>(part.tree, mesh, r, pending, isos, roots);
        });
      }
      for (int k = 0; k < K; ++k)
        for (uint32_t b = entry[k] & ~pending[k]; b; b &= b - 1) {
          int const i = order[base + k * W + __builtin_ctz(b)];
          occluded[i / 64] |= uint64_t(1) << (i % 64);
        }
    }
    return;
  }
  for (int base = 0; base < n; base += W) {
    int const cnt = n - base < W ? n - base : W;
    Ray packet[W];
    for (int l = 0; l < cnt; ++l) packet[l] = rays[order[base + l]];
    RayPacket<A> const r = load_rays<A>(packet, cnt);
    uint32_t const lanes = cnt >= 32 ? ~0u : (1u << cnt) - 1u;
    uint32_t const occ =
        simd::movemask(scene_occluded<A>(s, r, simd::mask_from_bits<A>(lanes), isos, roots, how, threshold)) & lanes;
    for (uint32_t b = occ; b; b &= b - 1) {
      int const i = order[base + __builtin_ctz(b)];
      occluded[i / 64] |= uint64_t(1) << (i % 64);
    }
  }
}

}  // namespace impl
}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
