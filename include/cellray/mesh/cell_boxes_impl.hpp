#pragma once
// Bodies of CellBoxes / CellRanges; included by the ISA units only.

#include <limits>

#include "../simd/batch.hpp"
#include "cell_boxes.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

/// Vertex ids of corner `c` for the W cells starting at `cell` (all valid).
template <class Arch, int N>
inline vint<Arch> corner_ids(CellMesh<N> const& mesh, uint64_t cell, int c) {
  if (mesh.has_32bit_indices() && mesh.vertex_count() <= uint64_t(std::numeric_limits<int32_t>::max()) &&
      cell * N < uint64_t(std::numeric_limits<int32_t>::max()) - uint64_t(width<Arch>) * N) {
    vint<Arch> off = simd::lane_index<Arch>() * vint<Arch>(N) + vint<Arch>(int32_t(c));
    return simd::gather(reinterpret_cast<int32_t const*>(mesh.indices32() + cell * N), off);
  }
  alignas(64) int32_t ids[width<Arch>];
  for (int l = 0; l < width<Arch>; ++l) ids[l] = int32_t(mesh.vertex(cell + uint64_t(l), c));
  return simd::load<Arch>(ids);
}

template <class Arch, int N>
inline void boxes_and_ranges(CellMesh<N> const& mesh, uint64_t begin, uint64_t end, ItemBox* boxes,
                             float* vmin_out, float* vmax_out) {
  constexpr int W = width<Arch>;
  constexpr float inf = std::numeric_limits<float>::infinity();
  float const* xyz = mesh.positions();
  float const* val = mesh.values();
  // Gathers use 32-bit vertex offsets; meshes beyond that take the scalar loop.
  bool const simd_ok = mesh.vertex_count() * 3 < uint64_t(std::numeric_limits<int32_t>::max());
  uint64_t i = begin;
  if (simd_ok) {
    for (; i + W <= end; i += W) {
      vfloat<Arch> lo[3] = {inf, inf, inf}, hi[3] = {-inf, -inf, -inf};
      vfloat<Arch> vmin(inf), vmax(-inf);
      vmask<Arch> has_nan = simd::no_lanes<Arch>();
      for (int c = 0; c < N; ++c) {
        vint<Arch> v = corner_ids<Arch>(mesh, i, c);
        if (boxes) {
          vint<Arch> v3 = v * vint<Arch>(3);
          for (int k = 0; k < 3; ++k) {
            vfloat<Arch> p = simd::gather(xyz + k, v3);
            lo[k] = simd::min(lo[k], p);
            hi[k] = simd::max(hi[k], p);
          }
        }
        if (val) {
          vfloat<Arch> s = simd::gather(val, v);
          has_nan = has_nan || simd::not_finite(s);
          vmin = simd::min(vmin, s);
          vmax = simd::max(vmax, s);
        } else {
          has_nan = simd::all_lanes<Arch>();
        }
      }
      vmin = simd::select(has_nan, vfloat<Arch>(inf), vmin);
      vmax = simd::select(has_nan, vfloat<Arch>(-inf), vmax);
      if (boxes) {
        alignas(64) float t[8][W];
        for (int k = 0; k < 3; ++k) {
          simd::store(t[k], lo[k]);
          simd::store(t[4 + k], hi[k]);
        }
        simd::store(t[3], vmin);
        simd::store(t[7], vmax);
        for (int l = 0; l < W; ++l) {
          ItemBox& b = boxes[i - begin + uint64_t(l)];
          b.lo = {t[0][l], t[1][l], t[2][l]};
          b.vmin = t[3][l];
          b.hi = {t[4][l], t[5][l], t[6][l]};
          b.vmax = t[7][l];
        }
      } else {
        simd::store(vmin_out + (i - begin), vmin);
        simd::store(vmax_out + (i - begin), vmax);
      }
    }
  }
  for (; i < end; ++i) {  // tail and huge meshes
    ItemBox b{{inf, inf, inf}, inf, {-inf, -inf, -inf}, -inf};
    bool nan = val == nullptr;
    for (int c = 0; c < N; ++c) {
      uint64_t v = mesh.vertex(i, c);
      for (int k = 0; k < 3; ++k) {
        float p = xyz[3 * v + uint64_t(k)];
        b.lo[k] = simd::min(b.lo[k], p);
        b.hi[k] = simd::max(b.hi[k], p);
      }
      if (val) {
        float s = val[v];
        nan = nan || simd::not_finite(s);
        b.vmin = simd::min(b.vmin, s);
        b.vmax = simd::max(b.vmax, s);
      }
    }
    if (nan) b.vmin = inf, b.vmax = -inf;
    if (boxes) boxes[i - begin] = b;
    else vmin_out[i - begin] = b.vmin, vmax_out[i - begin] = b.vmax;
  }
}

}  // namespace impl
}  // namespace CELLRAY_ISA_NS

template <class Arch> void CellBoxes<Arch>::run(AnyCellMesh mesh, uint64_t begin, uint64_t end, ItemBox* out) {
  mesh.visit([&](auto const& m) { impl::boxes_and_ranges<Arch>(m, begin, end, out, nullptr, nullptr); });
}
template <class Arch>
void CellRanges<Arch>::run(AnyCellMesh mesh, uint64_t begin, uint64_t end, float* vmin, float* vmax) {
  mesh.visit([&](auto const& m) { impl::boxes_and_ranges<Arch>(m, begin, end, nullptr, vmin, vmax); });
}

}  // namespace cellray
