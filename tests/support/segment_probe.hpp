#pragma once
// Test-only entry point: the cell-segment query (traverse/segments.hpp) run
// on host rays, one packet of W rays at a time, per ISA
// (tests/isa_traverse_segments.cpp instantiates it).

#include <cellray/bvh/bvh.hpp>
#include <cellray/dispatch/dispatch.hpp>
#include <cellray/mesh/cell_mesh.hpp>
#include <cellray/traverse/ray.hpp>
#include <cellray/traverse/tree_view.hpp>

namespace cellray::test {

/// Capacity of a ray's list in SegmentProbeOut (at least max_segments).
inline constexpr int probe_capacity = 64;
/// cellray::max_segments (segments.hpp is for ISA units only; the probe's
/// unit checks the two agree).
inline constexpr int probe_max_segments = 48;

/// One ray's answer: its segments front to back and the list's cut.
struct SegmentProbeOut {
  int count = 0;
  float cut = 0.f;
  CellSegment seg[probe_capacity];
  float value[probe_capacity][2];     ///< FieldSegment::value[0], value[1]
  float gradient[probe_capacity][3];  ///< FieldSegment::gradient[a][0]
};

/// The segments of `rays[i]` in the window [tmin, tmax] of that ray, with
/// `windows` as visibility filter, by traversal `how` (0 packet, 1 SPMD,
/// 2 hybrid); gradients when `gradients`. `out` has `n` entries.
template <class Arch> struct SegmentProbe {
  static void run(TetMesh const& mesh, MinMaxBvh const& bvh, ValueWindows const& windows, Ray const* rays, int n,
                  int how, bool gradients, SegmentProbeOut* out);
};
CELLRAY_EXTERN_ENTRY(SegmentProbe)

}  // namespace cellray::test
