#pragma once
// The renderer: isosurfaces (Rathke 2015 §6, Fig. 1, 6) and direct volume
// rendering (§7) of one or more meshes, tiles scheduled on TBB, each tile
// rendered inside the ISA unit chosen at run time.
//
// A Scene is a list of parts; each part is a mesh view, a BVH built over it
// and the value ranges of the array being shown (the BVH's own, or a refit
// for another time step). Nothing here owns meshes or trees: the host keeps
// them alive while a render runs. Everything is read-only during a render,
// so any number of renders may run at once on the same parts.

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "../bvh/node.hpp"
#include "../cells/vertex_gradients.hpp"
#include "../cells/queries.hpp"
#include "../dispatch/dispatch.hpp"
#include "../mesh/cell_mesh.hpp"
#include "../mesh/neighbours.hpp"
#include "../traverse/queries.hpp"
#include "../traverse/ray.hpp"
#include "camera.hpp"
#include "clip.hpp"
#include "image.hpp"
#include "render_common.hpp"
#include "transfer_function.hpp"

namespace cellray {

/// One mesh of a scene with its tree and the value ranges of its active array.
template <int N> struct ScenePart {
  CellMesh<N> mesh;
  MinMaxBvh const* bvh = nullptr;
  ValueRanges const* ranges = nullptr;  ///< nullptr: the BVH's own ranges
  /// Per-vertex gradients of the active array, for GradientMethod::smooth
  /// (build_vertex_gradients, 12 bytes per vertex; again for a time step).
  VertexGradients const* gradients = nullptr;
  /// Face neighbours (build_hex_neighbours, 24 bytes per cell): cell-segment
  /// DVR and AO rays march through them, as a tet part's (see ScenePart<4>:
  /// one part, or a tet and a hexahedral part linked by
  /// link_face_neighbours). Faster where cells are small against a packet's
  /// footprint (1M hexes at 1024x1024, 1 thread: DVR 1.4-1.8x the rays per
  /// second); coarse meshes do as well through the tree (boxturb48's 110k:
  /// DVR 0.9-1.1x; AO rays 1.02x, the flange's 1.03x).
  HexNeighbours const* neighbours = nullptr;
};

/// Tet parts may also carry their face neighbours (build_tet_neighbours,
/// 16 bytes per cell): cell-segment DVR then marches from cell to cell
/// instead of clipping every cell of the BVH leaves a packet reaches, and AO
/// rays march from their hit cells (traverse/march.hpp; component8, 1 thread:
/// DVR 2.8x the rays per second, shadow + AO rays 1.1x). The same image up
/// to rounding (AO: bit for bit); without them (nullptr) both use the tree
/// alone. Used when a scene has one part, or exactly one tet and one
/// hexahedral part whose neighbours link_face_neighbours linked (a mixed
/// mesh's two parts: DVR and AO rays march across both), and for meshes
/// whose gather offsets fit 31 bits (under 2^29 cells and 2^31 / 3
/// vertices).
template <> struct ScenePart<4> {
  CellMesh<4> mesh;
  MinMaxBvh const* bvh = nullptr;
  ValueRanges const* ranges = nullptr;  ///< nullptr: the BVH's own ranges
  TetNeighbours const* neighbours = nullptr;
  VertexGradients const* gradients = nullptr;  ///< see ScenePart<N>::gradients
};

/// What is rendered: tetrahedral and hexahedral parts (e.g. the two halves of
/// a mixed file, or the partitions of a simulation).
struct Scene {
  std::vector<ScenePart<4>> tets;
  std::vector<ScenePart<8>> hexes;

  Scene() = default;
  Scene(TetMesh const& m, MinMaxBvh const& bvh, ValueRanges const* r = nullptr, TetNeighbours const* n = nullptr) {
    tets.push_back({m, &bvh, r, n});
  }
  Scene(HexMesh const& m, MinMaxBvh const& bvh, ValueRanges const* r = nullptr, HexNeighbours const* n = nullptr) {
    hexes.push_back({m, &bvh, r, nullptr, n});
  }

  /// The parts of type N: `tets` or `hexes` (what prepare() iterates over
  /// the list of cell types).
  template <int N> std::vector<ScenePart<N>> const& parts() const {
    static_assert(N == 4 || N == 8, "Scene holds tetrahedral and hexahedral parts");
    if constexpr (N == 4) return tets;
    else return hexes;
  }

  /// Bounds of every part's root box (empty parts ignored).
  void bounds(glm::vec3& lo, glm::vec3& hi) const;
  uint64_t cell_count() const;
};

/// One isosurface: isovalue, colour, opacity (1 = opaque; below 1 the ray
/// continues behind the surface and composites front to back, Fig. 1).
struct IsoSurface {
  float value = 0.f;
  glm::vec3 color{0.85f, 0.85f, 0.85f};
  float opacity = 1.f;
};

/// Isosurfaces coloured by another point array (ParaView's "Coloring"): the
/// array of that name (every part's mesh must have it) interpolated at the
/// hit in the hit cell, through `colors` (RGB; alpha ignored). Empty `array`:
/// each surface's own colour. Where the array is NaN, the surface's colour.
struct IsoColorBy {
  std::string array;
  TransferFunction colors;
};

/// Isosurface rendering. Changing any of this never rebuilds or refits.
struct IsoParams {
  std::vector<IsoSurface> surfaces;  ///< 1 to 8 isovalues
  CellIsoOptions roots;              ///< exact roots (default) or Neubauer with N steps
  /// Analytic (the hit cell's gradient: facets on tets), central differences
  /// (the paper's) or smooth (needs ScenePart::gradients in every part).
  GradientMethod normals = GradientMethod::analytic;
  IsoColorBy color_by;  ///< colour by another array (off by default)
  /// Lambert + Blinn-Phong with a headlight; `light_dir` (towards the light,
  /// world space) is used for shadows; zero = the headlight.
  glm::vec3 light_dir{0.f};
  bool shadows = false;   ///< hard shadows from `light_dir` (or the headlight), through the same BVH
  int ao_samples = 0;     ///< ambient-occlusion rays per hit (0: off)
  float ao_radius = 0.f;  ///< world units; 0: 5% of the scene diagonal
  float ambient = 0.2f, diffuse = 0.7f, specular = 0.25f, shininess = 40.f;
  glm::vec4 background{1.f, 1.f, 1.f, 1.f};
  /// Clip planes or box: rays start where they enter the kept region, and
  /// shadow and AO rays end where they leave it; optional caps (clip.hpp).
  Clip clip;
};

/// How DVR finds values along a ray.
enum class DvrMode {
  samples,   ///< point samples at t0 + k * step, located through the BVH in groups (paper §7.2)
  segments,  ///< the cells the ray crosses, integrated piece by piece (exact cell boundaries)
};

/// Optional gradient shading of DVR (issue #6), the same in both DVR modes
/// and in the reference renderer. At a sample with transfer-function colour
/// c and field gradient g (analytic, world units: constant in a tet, the
/// trilinear derivative J^-T grad_uvw in a hex), with the headlight
/// l = -(unit ray direction) and the two-sided normal n = g / |g|:
///   lit = min(1, c (ambient + diffuse |n.l|) + specular |n.l|^shininess)
///   c'  = c + m (lit - c),  m = min(1, |g| / gradient_full)
/// per RGB channel; opacity is not changed. The blend m is the rule for
/// "where the gradient means something": a flat region (|g| -> 0, e.g. a
/// constant field or an extremum) has no direction, so it keeps its
/// unshaded colour, and shading fades in linearly up to |g| = gradient_full
/// (no hard threshold, so no speckle where |g| hovers around one). A zero
/// or non-finite gradient gives m = 0.
struct DvrShading {
  bool enabled = false;
  float ambient = 0.3f, diffuse = 0.7f, specular = 0.2f, shininess = 20.f;
  /// Gradient magnitude (value units per world unit) from which shading
  /// applies in full. 0: the transfer function's value span / scene
  /// diagonal (a field that would cross the whole colour map over the
  /// scene's extent is shaded in full).
  float gradient_full = 0.f;
};

/// The DVR step when DvrParams::step is 0: scene diagonal / 125 for cell
/// segments (each piece integrates the transfer function exactly between
/// its end values; what the step bounds is the light's order within a piece
/// and, in hexahedra, the field's bend: worst measured RMSE 0.014/255, max
/// 0.36/255, where the midpoint rule at / 250 gave 0.020 and 0.66), / 500 for
/// point samples (whose error is first found by the step; docs/accuracy.md).
inline float default_dvr_step(DvrMode mode, float scene_diagonal) {
  return scene_diagonal / (mode == DvrMode::segments ? 125.f : 500.f);
}

/// Direct volume rendering: emission-absorption, front to back (DESIGN.md).
/// Defaults: cell segments at default_dvr_step, the point on the measured
/// speed/error Pareto front below 1/255 RMSE (docs/accuracy.md).
struct DvrParams {
  TransferFunction tf;
  /// World units. Samples: the spacing of the samples. Segments: the longest
  /// piece a cell segment is integrated in (over the transfer function
  /// between the piece's end values). 0: default_dvr_step.
  float step = 0.f;
  /// Samples per ray in a ray's first traversal (segments: the first
  /// window's length in steps), 1..32; each further traversal of the ray
  /// takes twice as many, up to 32. A ray still going after a group is
  /// likely crossing faint material, and every group costs a traversal from
  /// the root. (The paper: a fixed 16.) Point samples against a fixed 16:
  /// component8 0.93x frame time, a generated 5M-tet mesh 1.00x, boxturb
  /// 1.01x; starting at 8 instead: 0.94x, 0.92x, 1.02x (segments' windows
  /// 0.99x, 1.00x, 1.03x), so 16 stays the first group.
  int group_size = 16;
  DvrMode mode = DvrMode::segments;
  bool empty_space_skipping = true;  ///< skip subtrees whose values map to zero opacity
  float termination = 0.99f;         ///< stop a ray at this accumulated opacity
  glm::vec4 background{1.f, 1.f, 1.f, 1.f};
  DvrShading shading;  ///< off by default
  /// Clip planes or box: each ray integrates only the part inside the kept
  /// region (clip.hpp; caps do not apply: the volume starts at the cut).
  Clip clip;
};

/// What a shadow or ambient-occlusion ray asks of the tree.
enum class SecondaryQuery {
  nearest,    ///< the nearest isosurface hit, one packet per pixel block and AO sample
  occlusion,  ///< any hit (early exit per lane and packet), one packet per pixel block and AO sample
  /// Any hit; a pixel block's AO rays (up to 4 samples at a time) regrouped
  /// by direction into dense packets (shadow rays as `occlusion`).
  sorted,
  /// As `sorted`, and the regrouped AO packets go 4 at a time through one
  /// traversal (nodes and cell corners read once for all of them).
  grouped,
  /// As `grouped`, except AO rays of a scene of one tet part with face
  /// neighbours (ScenePart<4>::neighbours): each marches from its hit cell
  /// through the neighbours (traverse/march.hpp), the tree only for what a
  /// march cannot finish (a ray leaving the mesh).
  march,
};

inline constexpr char const* secondary_query_name(SecondaryQuery q) {
  return q == SecondaryQuery::nearest     ? "nearest"
         : q == SecondaryQuery::occlusion ? "occlusion"
         : q == SecondaryQuery::sorted    ? "sorted"
         : q == SecondaryQuery::grouped   ? "grouped"
                                          : "march";
}

/// Where and how to run.
struct RenderOptions {
  Isa isa = default_isa();
  Traversal traversal = Traversal::packet;  ///< primary rays
  /// Shadow and AO rays (not used by `grouped` AO rays, which traverse as
  /// packets). Packets of them start at neighbouring hit points and still
  /// share most nodes: packet traversal measured 6x faster than SPMD and 3x
  /// faster than hybrid there (bench/bench_targets, README Performance).
  Traversal secondary_traversal = Traversal::packet;
  /// Shadow and AO rays: which query. Every choice gives the same image:
  /// any-hit queries answer "is there a crossing in [eps, radius]" (AO) and
  /// "is the light blocked" as the nearest hit does (same cells, same
  /// kernel, same window); shadows with surfaces of different opacities
  /// keep the nearest hit's opacity (the reference renderer's meaning), so
  /// they always use the nearest-hit query. Default `march` (which is
  /// `grouped` unless the scene is one tet part with face neighbours),
  /// measured on component8 (iso 423, shadows from a light above the left
  /// shoulder + 4 AO rays per hit, 512x512, 1 thread, AVX-512, AMD EPYC,
  /// `bench_targets --secondary`, secondary CPU time): `march` 1.61x less
  /// than `nearest`, `grouped` 1.48x. `grouped` against `nearest`: the
  /// secondary rays' instructions 1.37x fewer (callgrind, AVX2, 256x256; AO
  /// rays 1.44x, shadow rays 1.05x), but they wait on memory (a loaded Xeon:
  /// 1.09x-1.25x less time).
  SecondaryQuery secondary_query = SecondaryQuery::march;
  int hybrid_threshold = 0;  ///< 0: a quarter of the packet width
  int tile_size = 32;        ///< pixels per tile side, scheduled on TBB
};

/// Pixel rectangle [x0, x0 + w) x [y0, y0 + h) of the camera's image.
struct Tile {
  int x0 = 0, y0 = 0, w = 0, h = 0;
};

/// Counters a render reports (summed over tiles).
struct RenderStats {
  uint64_t rays = 0;  ///< primary rays
  uint64_t secondary_rays = 0;
};

/// Entry points per ISA (dispatch.hpp). `out` covers the whole image; only
/// the tile's pixels are written. The scene is prepared once per frame.
template <class Arch> struct RenderTileEntry {
  static void run(PreparedScene const& scene, Camera const& cam, IsoParams const& p, RenderOptions const& o, Tile tile,
                  FrameBuffer const& out);
  static void run(PreparedScene const& scene, Camera const& cam, DvrParams const& p, RenderOptions const& o, Tile tile,
                  FrameBuffer const& out);
};
CELLRAY_EXTERN_ENTRY(RenderTileEntry)

/// Volume integration of host rays [tmin, tmax] (ISA units): premultiplied
/// RGBA (4 floats per ray, no background) and, if `depth`, the ray distance
/// where the opacity first reaches `depth_at` (+inf where it never does).
template <class Arch> struct RayVolumeEntry {
  static void run(PreparedScene const& scene, DvrParams const& p, RenderOptions const& o, Ray const* rays, uint64_t n,
                  float* rgba, float* depth, float depth_at);
};
CELLRAY_EXTERN_ENTRY(RayVolumeEntry)

namespace render_detail {
struct DvrSetup {
  PreparedScene scene;
  PreparedTf table;
};
}  // namespace render_detail

/// An isosurface frame prepared once (scene checks, clip, vertex gradients
/// and colouring looked up), for hosts that render it tile by tile on their
/// own threads: every render_tile call reads it, none changes it. The scene's
/// meshes, trees and `p` must outlive it.
class IsoFrame {
 public:
  IsoFrame(Scene const& scene, IsoParams const& p);
  PreparedScene const& prepared() const { return scene_; }
  IsoParams const& params() const { return *p_; }

 private:
  PreparedScene scene_;
  IsoParams const* p_;
};

/// A DVR frame prepared once: scene checks, clip, value windows and the
/// transfer-function table (4096 entries; built per tile before, 8 % of a
/// 256-pixel tile's time on component8). Same rules as IsoFrame.
class DvrFrame {
 public:
  DvrFrame(Scene const& scene, DvrParams const& p);
  PreparedScene const& prepared() const { return setup_->scene; }
  DvrParams const& params() const { return *p_; }

 private:
  std::unique_ptr<render_detail::DvrSetup> setup_;  // the scene points into its table: kept in place
  DvrParams const* p_;
};

/// Renders the whole image with TBB (the calling thread's arena).
/// @throws InvalidArgument for bad parameters (no or more than 8 isovalues,
///         step <= 0 after defaults, group size outside 1..32, ...),
///         InvalidMesh when a part has no values or no BVH.
Image render_iso(Scene const& scene, Camera const& cam, IsoParams const& p, RenderOptions const& o = {});
Image render_dvr(Scene const& scene, Camera const& cam, DvrParams const& p, RenderOptions const& o = {});

/// One tile of a prepared frame on the calling thread, into the host's
/// buffer (premultiplied RGBA, optional depth in and out: FrameBuffer), for
/// hosts with their own scheduler. Thread-safe: tiles of one frame may run
/// at once. @throws InvalidArgument when the buffer's size is not the
/// camera's, the tile lies outside it or the buffer is missing.
void render_tile(IsoFrame const& frame, Camera const& cam, Tile tile, FrameBuffer const& out,
                 RenderOptions const& o = {});
void render_tile(DvrFrame const& frame, Camera const& cam, Tile tile, FrameBuffer const& out,
                 RenderOptions const& o = {});

/// The same without a prepared frame (prepared per call: slower per tile).
void render_tile(Scene const& scene, Camera const& cam, IsoParams const& p, Tile tile, Image& out,
                 RenderOptions const& o = {});
void render_tile(Scene const& scene, Camera const& cam, DvrParams const& p, Tile tile, Image& out,
                 RenderOptions const& o = {});

/// The whole image into the host's buffer, on TBB (the calling thread's arena).
void render(Scene const& scene, Camera const& cam, IsoParams const& p, FrameBuffer const& out,
            RenderOptions const& o = {});
void render(Scene const& scene, Camera const& cam, DvrParams const& p, FrameBuffer const& out,
            RenderOptions const& o = {});

/// First isosurface hit of each host ray in [tmin, tmax] over every part of
/// the scene (the nearest of the parts'; `piece` is the part: tets first,
/// then hexes, as listed), the isovalues, roots and normals of `p` (smooth
/// normals are answered analytically here), on TBB. NaN cells are never hit.
std::vector<SurfaceHit> first_hits(Scene const& scene, std::vector<Ray> const& rays, IsoParams const& p,
                                   RenderOptions const& o = {});

/// The scene's field at each point (xyz triples): from the first part
/// (tets first, then hexes) whose mesh holds it, NaN outside every part or
/// in NaN cells; the active array of each part's mesh. A point on a face,
/// edge or vertex shared by cells gets one of their values (no cracks: see
/// probe_tet_tolerance). On TBB (the calling thread's arena): the points are
/// sorted along a Morton curve of the scene's bounds, located W at a time
/// through each part's BVH by point-in-box tests (traverse/probe.hpp), and
/// returned in input order. Scratch: 4 bytes per point (8 beyond 2^32).
std::vector<float> sample_points(Scene const& scene, std::vector<float> const& xyz, RenderOptions const& o = {});

/// The same into the host's buffer: `out[i]` (n floats) receives the value
/// at (xyz[3i], xyz[3i + 1], xyz[3i + 2]) (3n floats). Nothing is kept.
/// @throws InvalidArgument when n > 0 and either pointer is null, as the
/// other overload for a part without a BVH or values.
void sample_points(Scene const& scene, float const* xyz, uint64_t n, float* out, RenderOptions const& o = {});

/// Direct volume rendering of the host's own rays, each over its [tmin,
/// tmax] (unit directions: distances and opacity per unit length assume
/// them; a zero-length or NaN direction gives nothing): `rgba` receives 4
/// floats per ray, premultiplied, no background (composite it over what the
/// ray hits at tmax); `depth` (optional, one float per ray) the distance
/// where the accumulated opacity first reaches `depth_at` (+inf: never).
/// Both DVR modes, march or tree as render_dvr. Runs on TBB over chunks of
/// rays. @throws as render_dvr.
void integrate_rays(DvrFrame const& frame, Ray const* rays, uint64_t n, float* rgba, float* depth = nullptr,
                    float depth_at = 0.5f, RenderOptions const& o = {});

}  // namespace cellray

#include "render_api.inl"
