#pragma once
// Array-in, array-out entry points over the cell kernels: run one kernel for
// n (ray or point, cell) pairs on the ISA chosen at run time. Used by tests
// (SIMD vs the double reference), benchmarks, and hosts that query cells
// they located themselves. Render paths call the kernels from tet.hpp /
// hex.hpp directly inside their traversal instead.

#include <cstdint>

#include "../dispatch/dispatch.hpp"
#include "../mesh/cell_mesh.hpp"

namespace cellray {

/// A ray as plain floats: origin and direction (not necessarily unit).
struct RayQuery {
  float ox, oy, oz, dx, dy, dz;
};

/// Which cell each query uses. SPMD (`ids` set): query i uses cell ids[i],
/// corners gathered per lane. Packet (`ids` null): every query uses cell
/// `uniform`, corners broadcast, W queries per kernel call.
struct CellSelect {
  uint32_t const* ids = nullptr;
  uint64_t uniform = 0;
};

/// clip_tet / clip_hex output per query (u_in/u_out: hexes only).
struct ClipOut {
  float t_in, t_out, s_in, s_out;
  float u_in[3], u_out[3];
  int32_t hit;
};

/// locate_tet / locate_hex output per query.
struct LocateOut {
  float value;
  float param[3];
  int32_t inside, converged;
};

/// Iso root output per query: t = +inf and index = -1 without a hit.
struct IsoOut {
  float t;
  int32_t index, hit;
};

enum class CellIsoMethod { exact, neubauer };
/// Normals of isosurfaces: the cell's analytic gradient (constant in a tet:
/// facets), central differences (the paper's), or smooth: per-vertex
/// gradients (cells/vertex_gradients.hpp) interpolated in the hit cell. The
/// cell-level queries know no vertex gradients and answer `smooth` analytically.
enum class GradientMethod { analytic, central, smooth };

/// Options of CellQueries::iso: Neubauer rounds (paper: 2) and the hex exact
/// method's world-space refinement steps.
struct CellIsoOptions {
  CellIsoMethod method = CellIsoMethod::exact;
  int neubauer_steps = 2;
  int refine_steps = 2;
};

/// Entry points: `dispatch<CellQueries>(isa, mesh, cells, inputs..., out)`;
/// the overload is chosen by the output type (ClipOut, LocateOut, float
/// gradients, IsoOut). Single-threaded; outputs are caller-allocated with n
/// entries; cell ids must be valid.
template <class Arch> struct CellQueries {
  /// Ray clip: out[i] for rays[i] against its cell.
  static void run(TetMesh const& mesh, CellSelect cells, RayQuery const* rays, uint64_t n, ClipOut* out);
  static void run(HexMesh const& mesh, CellSelect cells, RayQuery const* rays, uint64_t n, ClipOut* out);
  /// Point location + interpolation: points are xyz triples.
  static void run(TetMesh const& mesh, CellSelect cells, float const* points, uint64_t n, LocateOut* out);
  static void run(HexMesh const& mesh, CellSelect cells, float const* points, uint64_t n, LocateOut* out);
  /// Field gradient at points (xyz triples) in world space, 3 floats each.
  /// Analytic: tets ignore the point; hexes evaluate at its inverted
  /// coordinates. Central: step h (world units).
  static void run(TetMesh const& mesh, CellSelect cells, float const* points, uint64_t n, GradientMethod method,
                       float h, float* out);
  static void run(HexMesh const& mesh, CellSelect cells, float const* points, uint64_t n, GradientMethod method,
                       float h, float* out);
  /// Clip, then the first crossing of any of `count` isovalues.
  static void run(TetMesh const& mesh, CellSelect cells, RayQuery const* rays, uint64_t n, float const* isovalues,
                  int count, CellIsoOptions options, IsoOut* out);
  static void run(HexMesh const& mesh, CellSelect cells, RayQuery const* rays, uint64_t n, float const* isovalues,
                  int count, CellIsoOptions options, IsoOut* out);
};
CELLRAY_EXTERN_ENTRY(CellQueries)

}  // namespace cellray
