#pragma once
// Test-only entry point: CellMarch (traverse/march.hpp) driven over host
// rays, one packet of W rays at a time, per ISA (tests/isa_traverse_march.cpp
// instantiates it), recording every visible segment a lane steps through;
// and the marched occlusion query of ambient-occlusion rays.

#include <cellray/bvh/bvh.hpp>
#include <cellray/dispatch/dispatch.hpp>
#include <cellray/mesh/cell_mesh.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/traverse/ray.hpp>
#include <cellray/traverse/tree_view.hpp>

namespace cellray::test {

inline constexpr int march_capacity = 256;

/// One ray's march: its visible segments in the order stepped (t_in, t_out
/// and end values of the cell's clip; `cell`), how many steps and locates.
struct MarchProbeOut {
  int count = 0;
  int steps = 0, locates = 0;
  CellSegment seg[march_capacity];
};

/// Marches `rays[i]` over [tmin, tmax] with `windows` as visibility filter,
/// `max_faint` invisible cells before a locate, traversal `how` (0 packet,
/// 1 SPMD, 2 hybrid) for the locates. `out` has `n` entries.
template <class Arch> struct MarchProbe {
  static void run(TetMesh const& mesh, MinMaxBvh const& bvh, TetNeighbours const& nb, ValueWindows const& windows,
                  Ray const* rays, int n, int how, int max_faint, MarchProbeOut* out);
  static void run(HexMesh const& mesh, MinMaxBvh const& bvh, HexNeighbours const& nb, ValueWindows const& windows,
                  Ray const* rays, int n, int how, int max_faint, MarchProbeOut* out);
};
CELLRAY_EXTERN_ENTRY(MarchProbe)

/// MixedMarch (traverse/march.hpp) over a mixed mesh's two parts with
/// linked face neighbours, as MarchProbe: segments carry `piece` 0 (a tet)
/// or 1 (a hexahedron); `crossings` counts steps that went on in the other
/// part without a locate in between.
struct MixedMarchProbeOut : MarchProbeOut {
  int crossings = 0;
};
template <class Arch> struct MixedMarchProbe {
  static void run(TetMesh const& tets, MinMaxBvh const& tet_bvh, TetNeighbours const& tet_nb, HexMesh const& hexes,
                  MinMaxBvh const& hex_bvh, HexNeighbours const& hex_nb, Ray const* rays, int n, int how,
                  MixedMarchProbeOut* out);
};
CELLRAY_EXTERN_ENTRY(MixedMarchProbe)

/// march_occluded (traverse/march.hpp) on `rays[i]` starting in cell
/// `start[i]`, packets of W: per ray occluded (1/0), undecided (1/0: the
/// march could not finish) and how far it got without a crossing. Tets or
/// hexahedra.
template <class Arch> struct MarchOcclusionProbe {
  static void run(TetMesh const& mesh, MinMaxBvh const& bvh, TetNeighbours const& nb, Ray const* rays,
                  int32_t const* start, int n, IsoSet const& isos, uint8_t* occluded, uint8_t* undecided,
                  float* t_done);
  static void run(HexMesh const& mesh, MinMaxBvh const& bvh, HexNeighbours const& nb, Ray const* rays,
                  int32_t const* start, int n, IsoSet const& isos, uint8_t* occluded, uint8_t* undecided,
                  float* t_done);
};
CELLRAY_EXTERN_ENTRY(MarchOcclusionProbe)

/// The first visible cell of each ray past its tmin (FirstCellQuery), for
/// consecutive groups of four packets of W rays: `grouped` from one
/// traversal of each group (FirstCellGroup, as the DVR renderer's first
/// locates), `alone` from one traversal per packet. Per ray: the cell (-1
/// none) and its t_in (+inf none). `n` is a multiple of 4 W.
struct FirstCellsOut {
  int32_t cell = -1;
  float t_in = 0.f;
};
template <class Arch> struct FirstCellsProbe {
  static void run(TetMesh const& mesh, MinMaxBvh const& bvh, ValueWindows const& windows, Ray const* rays, int n,
                  FirstCellsOut* grouped, FirstCellsOut* alone);
  static void run(HexMesh const& mesh, MinMaxBvh const& bvh, ValueWindows const& windows, Ray const* rays, int n,
                  FirstCellsOut* grouped, FirstCellsOut* alone);
};
CELLRAY_EXTERN_ENTRY(FirstCellsProbe)

}  // namespace cellray::test
