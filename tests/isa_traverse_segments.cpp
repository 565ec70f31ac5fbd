// SegmentProbe (tests/support/segment_probe.hpp) for one ISA: compiled once
// per ISA with that ISA's flags.

#include <memory>

#include <cellray/traverse/segments.hpp>

#include "support/segment_probe.hpp"

namespace cellray::test {

static_assert(probe_max_segments == max_segments && max_segments <= probe_capacity);

template <class Arch>
void SegmentProbe<Arch>::run(TetMesh const& mesh, MinMaxBvh const& bvh, ValueWindows const& windows, Ray const* rays,
                             int n, int how, bool gradients, SegmentProbeOut* out) {
  constexpr int W = width<Arch>;
  TreeView const tree(bvh);
  std::unique_ptr<SegmentQuery<Arch, 4>> q;
  for (int first = 0; first < n; first += W) {
    int const m = n - first < W ? n - first : W;
    RayPacket<Arch> const r = load_rays<Arch>(rays + first, m);
    // Large (max_segments per lane): on the heap, reused packet to packet
    // through reset() as the renderer does.
    if (!q) q = std::make_unique<SegmentQuery<Arch, 4>>(tree, mesh, r, windows, r.tmin, r.tmax, gradients);
    else q->reset(tree, mesh, r, r.tmin, r.tmax);
    uint32_t const bits = m >= 32 ? ~0u : (1u << m) - 1u;
    collect_segments(*q, simd::mask_from_bits<Arch>(bits), Traversal(how), how == 2 ? W / 2 : 0);
    for (int l = 0; l < m; ++l) {
      SegmentProbeOut& o = out[first + l];
      o.count = q->count[l], o.cut = q->cut[l];
      for (int i = 0; i < q->count[l]; ++i) {
        FieldSegment const& fs = q->seg[l][q->order[l][i]];
        o.seg[i] = fs.s;
        o.value[i][0] = fs.value[0], o.value[i][1] = fs.value[1];
        for (int a = 0; a < 3; ++a) o.gradient[i][a] = gradients ? fs.gradient[a][0] : 0.f;
      }
    }
  }
}

CELLRAY_INSTANTIATE_ENTRY(SegmentProbe)

}  // namespace cellray::test
