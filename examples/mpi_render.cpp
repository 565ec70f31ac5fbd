// cellray-mpi-render: cellray-render's isosurfaces and DVR on several MPI
// ranks, composited by IceT (issue #22). Run under mpirun:
//
//   mpirun -np 4 cellray-mpi-render mesh.vtk --mode dvr -o out.png
//
// Every rank reads the mesh (or generates the default scene), computes the
// same k-d partition of it by cell centroids (k = ranks,
// cellray/mesh/partition.hpp) and keeps the cells of its region (a cell
// straddling a region border goes to every region it touches); it builds a
// BVH over those, renders them with its rays clipped exactly to its region's
// box and a clear background (premultiplied RGBA), and IceT blends the ranks'
// images in the regions' front-to-back order for the eye
// (ICET_COMPOSITE_MODE_BLEND, ICET_ORDERED_COMPOSITE). Rank 0 puts the
// background behind and writes the image. Ordered blending is exact for
// opaque isosurfaces too: the regions are disjoint boxes met in order along
// every ray, so the first opaque hit along a ray (opacity 1) hides what the
// later regions add, as a z-buffer would, with no depth buffer to send.
//
// What a rank cannot do alone: shadow and ambient-occlusion rays need the
// whole mesh (a ray leaving the region may be blocked elsewhere), so
// --shadows and --ao are refused. Smooth normals are exact: the per-vertex
// gradients come from the whole mesh each rank has read.
//
// Flags: a subset of cellray-render's, with the same meaning and defaults
// (so an image compares to cellray-render's with the same flags): mesh,
// --generate, --cells, --array, --mode, --iso, --iso-opacity, --normals,
// --tf (presets), --opacity, --unit-distance, --step, --dvr-mode,
// --background, --eye, --at, --up, --fov, --zoom, --azimuth, --elevation,
// --size, -o, --threads, --skip-unsupported, --stats (per-rank timings as
// JSON lines on rank 0's stdout). Meshes of one cell type only (tets or
// hexes) whose coordinates and values need no rescaling (cellray-render's
// Frame / ValueFrame); others are refused with a message.
//
// Errors: every rank checks its own work; an MPI_Allreduce of an error code
// after each collective phase makes all ranks stop together (exit code as
// cellray-render's: 2 usage, 3 I/O, 4 invalid mesh, 1 other), rank 0
// printing the first failing rank's message: no rank waits for one that
// failed.

#include <mpi.h>

#include <IceT.h>
#include <IceTMPI.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/vertex_gradients.hpp>
#include <cellray/error.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/neighbours.hpp>
#include <cellray/mesh/partition.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/render/render.hpp>
#include <cellray/render/transfer_function.hpp>

#include "cli_common.hpp"
#include "framing.hpp"

namespace {

using namespace cellray;
using namespace cellray_cli;

struct Options {
  std::string mesh_path;
  std::string generate = "tets";
  uint64_t cells = 300000;
  std::string array;
  std::string mode = "iso";
  std::string iso, iso_opacity;
  std::string normals = "smooth";
  std::string tf = "cool-warm";
  float opacity = -1.f;
  float unit_distance = 0.f;
  float step = 0.f;
  std::string dvr_mode = "segments";
  std::string background;
  std::string eye, at, up;
  float fov = 30.f;
  float zoom = 1.f, azimuth = 0.f, elevation = 0.f;
  std::string size = "1024x768";
  std::string out = "cellray.png";
  int threads = 0;
  bool skip_unsupported = false;
  bool stats = false;
  bool shadows = false;
  int ao = 0;
};

/// The error of one rank, carried to the collective check.
struct Failure {
  int code = exit_ok;
  std::string message;
};

template <class F> Failure attempt(F&& f) {
  try {
    f();
    return {};
  } catch (UsageError const& e) {
    return {exit_usage, e.what()};
  } catch (InvalidArgument const& e) {
    return {exit_usage, e.what()};
  } catch (IoError const& e) {
    return {exit_io, e.what()};
  } catch (InvalidMesh const& e) {
    return {exit_invalid_mesh, e.what()};
  } catch (std::bad_alloc const&) {
    return {exit_other, "out of memory"};
  } catch (std::exception const& e) {
    return {exit_other, e.what()};
  }
}

/// Collective: every rank learns whether any rank failed. Returns the exit
/// code (0: none failed); rank 0 prints the lowest failing rank's message.
int agree(Failure const& f, int rank, int ranks) {
  int const mine = f.code != exit_ok ? rank : ranks;
  int first = ranks;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (first == ranks) return exit_ok;
  int code = f.code;
  MPI_Bcast(&code, 1, MPI_INT, first, MPI_COMM_WORLD);
  int len = int(f.message.size());
  MPI_Bcast(&len, 1, MPI_INT, first, MPI_COMM_WORLD);
  std::string msg = f.message;
  msg.resize(size_t(len));
  MPI_Bcast(msg.data(), len, MPI_CHAR, first, MPI_COMM_WORLD);
  if (rank == 0) {
    std::replace(msg.begin(), msg.end(), '\n', ' ');
    std::cerr << "cellray-mpi-render: error";
    if (ranks > 1) std::cerr << " (rank " << first << ")";
    std::cerr << ": " << msg << "\n";
  }
  return code;
}

/// What every rank holds: the whole mesh, its region's cells and the render set-up.
struct Setup {
  std::optional<UnstructuredGrid> grid;
  std::optional<GeneratedMesh<4>> gen_tets;
  std::optional<GeneratedMesh<8>> gen_hexes;
  TetMesh tets;
  HexMesh hexes;
  KdPartition part;
  CellSubset<4> tet_sub;
  CellSubset<8> hex_sub;
  TetMesh tet_region;
  HexMesh hex_region;
  MinMaxBvh bvh;
  TetNeighbours neighbours;
  VertexGradients gradients;
  Scene scene;  // empty when the region has no cells
  Camera cam;
  IsoParams ip;
  DvrParams dp;
  glm::vec4 background{1.f};
  double read_ms = 0, partition_ms = 0, build_ms = 0;
};

/// Reads, partitions and builds; the same on every rank but for the region.
void set_up(Options const& o, int rank, int ranks, Setup& s) {
  if (o.shadows || o.ao > 0)
    throw UsageError(std::string(o.shadows ? "--shadows" : "--ao") +
                     ": shadow and ambient-occlusion rays need the whole mesh, which no rank holds alone "
                     "(render them with cellray-render)");
  int width = 0, height = 0;
  parse_size(o.size, width, height);
  if (image_format(o.out).empty()) throw UsageError("-o: '" + o.out + "' must end in .png or .ppm");
  if (o.mode != "iso" && o.mode != "dvr") throw UsageError("--mode: iso or dvr, got '" + o.mode + "'");

  auto t0 = Clock::now();
  // Test hook: CELLRAY_MPI_FAIL_RANK=r makes rank r fail to read, as a
  // rank whose file is unreadable would (tests/mpi: the others must not hang).
  if (char const* fail = std::getenv("CELLRAY_MPI_FAIL_RANK"); fail && std::atoi(fail) == rank)
    throw IoError("rank " + std::to_string(rank) + ": cannot read the mesh (CELLRAY_MPI_FAIL_RANK)");
  std::string name = "default scene";
  if (o.mesh_path.empty()) {
    if (o.generate == "hexes") s.gen_hexes = generate_hexes(o.cells), s.hexes = s.gen_hexes->mesh();
    else s.gen_tets = generate_tets(o.cells), s.tets = s.gen_tets->mesh();
  } else {
    name = o.mesh_path;
    ReadOptions ro;
    ro.skip_unsupported_cells = o.skip_unsupported;
    s.grid = read_mesh(o.mesh_path, ro);
    if (s.grid->empty()) throw InvalidMesh(name + " holds no tetrahedra or hexahedra");
    s.tets = s.grid->tet_mesh();
    s.hexes = s.grid->hex_mesh();
    if (!s.tets.empty() && !s.hexes.empty())
      throw UsageError(name + ": mixed tet and hex meshes are not supported by cellray-mpi-render (use cellray-render)");
  }
  bool const tet = !s.tets.empty();
  auto const& arrays = tet ? s.tets.arrays() : s.hexes.arrays();
  if (arrays.empty()) throw InvalidMesh(name + " has no point arrays to render");
  std::string array = arrays.front().name;
  if (!o.array.empty()) {
    bool found = false;
    for (auto const& a : arrays) found = found || a.name == o.array;
    if (!found) throw UsageError("--array: " + name + " has no point array '" + o.array + "'");
    array = o.array;
  }
  if (tet) s.tets = s.tets.with_array(array);
  else s.hexes = s.hexes.with_array(array);
  ValidationReport const rep = tet ? validate(s.tets) : validate(s.hexes);
  if (!rep.ok()) throw InvalidMesh(name + " failed validation: " + rep.message());
  float const vlo = rep.value_min, vhi = rep.value_max;
  if (!(vlo <= vhi)) throw InvalidMesh(name + ": point array '" + array + "' has no finite value");
  if (std::max(std::fabs(vlo), std::fabs(vhi)) > 0x1p+40f)
    throw UsageError(name + ": values need rescaling for float ray tracing (cellray-render does it; this program does not)");
  s.read_ms = ms_since(t0);

  t0 = Clock::now();
  s.part = tet ? partition_kd(s.tets, ranks) : partition_kd(s.hexes, ranks);
  glm::vec3 const lo = s.part.lo, hi = s.part.hi;
  {
    float const extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    float const reach = std::max({std::fabs(lo.x), std::fabs(lo.y), std::fabs(lo.z), std::fabs(hi.x), std::fabs(hi.y),
                                  std::fabs(hi.z)});
    if (!(extent >= 0x1p-20f && extent <= 0x1p+20f && reach <= 0x1p+8f * extent))
      throw UsageError(name + ": coordinates need rescaling for float ray tracing (cellray-render does it; this program does not)");
  }
  KdRegion const& region = s.part.regions[size_t(rank)];
  s.partition_ms = ms_since(t0);

  // Camera: cellray-render's default view of the whole mesh's bounds.
  t0 = Clock::now();
  float const framing = o.mesh_path.empty() ? 0.75f : 1.f;
  glm::vec3 const centre = 0.5f * (lo + hi);
  glm::dvec3 const fit_lo(centre + framing * (lo - centre)), fit_hi(centre + framing * (hi - centre));
  glm::dvec3 const dir = cellray_render::view_direction(o.azimuth, o.elevation);
  double const fit = cellray_render::fit_distance(fit_lo, fit_hi, dir, 0.9 * o.zoom, o.fov, width, height);
  s.cam = cellray_render::box_camera(fit_lo, fit_hi, dir, fit, o.fov, width, height);
  if (!o.eye.empty() || !o.at.empty() || !o.up.empty())
    s.cam = Camera::look_at(o.eye.empty() ? s.cam.eye : parse_vec3(o.eye, "--eye"),
                            o.at.empty() ? centre : parse_vec3(o.at, "--at"),
                            o.up.empty() ? glm::vec3(0.f, 1.f, 0.f) : parse_vec3(o.up, "--up"), o.fov, width, height);
  float const diagonal = glm::length(hi - lo);
  std::optional<glm::vec4> background;
  if (!o.background.empty()) background = parse_background(o.background);

  bool const smooth = o.mode == "iso" && o.normals == "smooth";
  if (o.mode == "iso") {
    std::vector<float> values, opacity;
    if (!o.iso.empty()) values = parse_floats(o.iso, "--iso");
    else if (o.mesh_path.empty()) values = {0.3f, 0.45f, 0.6f};
    else
      for (double t : {0.25, 0.5, 0.75}) values.push_back(float(vlo + t * (double(vhi) - vlo)));
    if (values.size() > 8) throw UsageError("--iso: at most 8 isovalues");
    if (!o.iso_opacity.empty()) opacity = parse_floats(o.iso_opacity, "--iso-opacity");
    if (!opacity.empty() && opacity.size() != 1 && opacity.size() != values.size())
      throw UsageError("--iso-opacity: give one opacity or one per isovalue");
    for (float a : opacity)
      if (a < 0.f || a > 1.f) throw UsageError("--iso-opacity: opacities must lie in [0, 1]");
    for (size_t i = 0; i < values.size(); ++i)
      s.ip.surfaces.push_back({values[i], iso_color(i),
                               opacity.empty()       ? (i + 1 == values.size() ? 1.f : 0.4f)
                               : opacity.size() == 1 ? opacity[0]
                                                     : opacity[i]});
    if (o.normals != "smooth" && o.normals != "flat" && o.normals != "central")
      throw UsageError("--normals: smooth, flat or central, got '" + o.normals + "'");
    s.ip.normals = o.normals == "central" ? GradientMethod::central
                   : o.normals == "flat"  ? GradientMethod::analytic
                                          : GradientMethod::smooth;
    s.background = background.value_or(s.ip.background);
    s.ip.background = {0.f, 0.f, 0.f, 0.f};
    s.ip.clip.planes = clip_box(region.lo, region.hi);
  } else {
    if (o.tf != "cool-warm" && o.tf != "viridis" && o.tf != "inferno" && o.tf != "grayscale")
      throw UsageError("--tf: presets only (cool-warm, viridis, inferno, grayscale), got '" + o.tf + "'");
    if (o.dvr_mode != "segments" && o.dvr_mode != "samples")
      throw UsageError("--dvr-mode: segments or samples, got '" + o.dvr_mode + "'");
    float const max_alpha = o.opacity >= 0.f ? o.opacity : 0.8f;
    s.dp.tf = transfer_function_preset(o.tf, vlo, vhi, max_alpha);
    double const span = vhi > vlo ? double(vhi) - vlo : 1.0;  // cellray-render's linear opacity ramp
    for (size_t i = 0; i < s.dp.tf.values.size(); ++i)
      s.dp.tf.rgba[i].a = max_alpha * float(std::clamp((s.dp.tf.values[i] - double(vlo)) / span, 0.0, 1.0));
    s.dp.tf.unit_distance = o.unit_distance > 0.f ? o.unit_distance : std::max(diagonal / 10.f, 1e-30f);
    s.dp.mode = o.dvr_mode == "samples" ? DvrMode::samples : DvrMode::segments;
    // The whole mesh's default step, not the region's.
    s.dp.step = o.step > 0.f ? o.step : default_dvr_step(s.dp.mode, diagonal);
    s.background = background.value_or(glm::vec4(0.08f, 0.08f, 0.1f, 1.f));
    s.dp.background = {0.f, 0.f, 0.f, 0.f};
    s.dp.clip.planes = clip_box(region.lo, region.hi);
  }
  // Smooth normals from the whole mesh: exact at the region's borders.
  if (smooth) s.gradients = tet ? build_vertex_gradients(s.tets) : build_vertex_gradients(s.hexes);

  if (!region.cells.empty()) {
    if (tet) {
      s.tet_sub = subset_cells(s.tets, region.cells);
      s.tet_region = s.tet_sub.mesh();
      s.bvh = build_minmax_bvh(s.tet_region);
      bool const march = o.mode == "dvr" && s.dp.mode == DvrMode::segments;
      if (march) s.neighbours = build_tet_neighbours(s.tet_region);
      s.scene.tets.push_back({s.tet_region, &s.bvh, nullptr, march ? &s.neighbours : nullptr,
                              smooth ? &s.gradients : nullptr});
    } else {
      s.hex_sub = subset_cells(s.hexes, region.cells);
      s.hex_region = s.hex_sub.mesh();
      s.bvh = build_minmax_bvh(s.hex_region);
      s.scene.hexes.push_back({s.hex_region, &s.bvh, nullptr, smooth ? &s.gradients : nullptr});
    }
  }
  s.build_ms = ms_since(t0);
}

int run(Options const& o, int rank, int ranks) {
  std::optional<tbb::global_control> limit;
  if (o.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(o.threads));
  auto const t_start = Clock::now();
  Setup s;
  if (int const code = agree(attempt([&] { set_up(o, rank, ranks, s); }), rank, ranks)) return code;

  // Render this rank's region: premultiplied RGBA over a clear background.
  Image image;
  double render_ms = 0;
  Failure f = attempt([&] {
    auto const t0 = Clock::now();
    if (s.scene.cell_count() == 0) image = Image(s.cam.width, s.cam.height);  // an empty region adds nothing
    else image = o.mode == "iso" ? render_iso(s.scene, s.cam, s.ip) : render_dvr(s.scene, s.cam, s.dp);
    render_ms = ms_since(t0);
  });
  if (int const code = agree(f, rank, ranks)) return code;

  // IceT: ordered blending of the ranks' images, front to back for the eye.
  MPI_Barrier(MPI_COMM_WORLD);  // the composite time then excludes waiting for slower renders
  auto const t_comp = Clock::now();
  IceTCommunicator comm = icetCreateMPICommunicator(MPI_COMM_WORLD);
  IceTContext context = icetCreateContext(comm);
  icetDiagnostics(ICET_DIAG_ERRORS);
  icetSetColorFormat(ICET_IMAGE_COLOR_RGBA_FLOAT);
  icetSetDepthFormat(ICET_IMAGE_DEPTH_NONE);
  icetCompositeMode(ICET_COMPOSITE_MODE_BLEND);
  icetStrategy(ICET_STRATEGY_REDUCE);
  icetSingleImageStrategy(ICET_SINGLE_IMAGE_STRATEGY_AUTOMATIC);
  icetResetTiles();
  icetAddTile(0, 0, s.cam.width, s.cam.height, 0);
  icetEnable(ICET_ORDERED_COMPOSITE);
  std::vector<IceTInt> order;
  for (int r : s.part.front_to_back(s.cam.eye)) order.push_back(IceTInt(r));
  icetCompositeOrder(order.data());
  IceTDouble const identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  IceTFloat const clear[4] = {0.f, 0.f, 0.f, 0.f};
  IceTImage composite = icetCompositeImage(image.rgba.data(), nullptr, nullptr, identity, identity, clear);
  if (rank == 0) {
    IceTFloat const* c = icetImageGetColorcf(composite);
    std::copy(c, c + image.rgba.size(), image.rgba.begin());
  }
  double const composite_ms = ms_since(t_comp);
  icetDestroyContext(context);
  icetDestroyMPICommunicator(comm);

  // Rank 0: the background behind the composite, as cellray-render's
  // renderer puts it (C + (1 - A) background, premultiplied), then the file.
  f = attempt([&] {
    if (rank != 0) return;
    for (size_t i = 0; i < image.rgba.size(); i += 4) {
      float const t = 1.f - image.rgba[i + 3];
      for (size_t k = 0; k < 4; ++k) image.rgba[i + k] += t * s.background[int(k)];
    }
    write_image(o.out, image);
  });
  if (int const code = agree(f, rank, ranks)) return code;

  if (o.stats) {
    double const total_ms = ms_since(t_start);
    double const mine[7] = {s.read_ms, s.partition_ms, s.build_ms, render_ms, composite_ms, total_ms,
                            double(s.scene.cell_count())};
    std::vector<double> all(size_t(7 * ranks));
    MPI_Gather(mine, 7, MPI_DOUBLE, all.data(), 7, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    if (rank == 0)
      for (int r = 0; r < ranks; ++r) {
        double const* m = &all[size_t(7 * r)];
        std::printf("{\"rank\": %d, \"ranks\": %d, \"cells\": %.0f, \"read_ms\": %.1f, \"partition_ms\": %.1f, "
                    "\"build_ms\": %.1f, \"render_ms\": %.1f, \"composite_ms\": %.1f, \"total_ms\": %.1f}\n",
                    r, ranks, m[6], m[0], m[1], m[2], m[3], m[4], m[5]);
      }
  }
  return exit_ok;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);

  CLI::App app{"cellray-mpi-render: cellray-render's isosurfaces and DVR over MPI ranks, composited by IceT.\n"
               "Run as: mpirun -np N cellray-mpi-render [mesh] [flags]"};
  app.footer("Exit codes: 0 success; 1 other error; 2 usage; 3 I/O; 4 invalid mesh (all ranks exit with it).");
  Options o;
  app.add_option("mesh", o.mesh_path, "Legacy .vtk or .vtu mesh; none: the generated default scene");
  app.add_option("--generate", o.generate, "Default scene cell type")->check(CLI::IsMember({"tets", "hexes"}));
  app.add_option("--cells", o.cells, "Default scene size in cells (approximate)")->check(CLI::Range(uint64_t(1), uint64_t(1) << 31));
  app.add_option("--array", o.array, "Point array to render (default: the first)");
  app.add_option("--mode", o.mode, "iso or dvr")->check(CLI::IsMember({"iso", "dvr"}));
  app.add_option("--iso", o.iso, "Isovalues V1,V2,... (default: 3 spread over the value range)");
  app.add_option("--iso-opacity", o.iso_opacity, "One opacity, or one per isovalue (default: 0.4, the last 1)");
  app.add_option("--normals", o.normals, "smooth, flat or central")->check(CLI::IsMember({"smooth", "flat", "central"}));
  app.add_option("--tf", o.tf, "Transfer function preset: cool-warm, viridis, inferno, grayscale");
  app.add_option("--opacity", o.opacity, "Largest DVR opacity per unit distance (default 0.8)")->check(CLI::Range(0.f, 1.f));
  app.add_option("--unit-distance", o.unit_distance, "DVR opacity unit distance (default: diagonal / 10)");
  app.add_option("--step", o.step, "DVR step, world units (default: the whole mesh's diagonal / 250 or / 500)");
  app.add_option("--dvr-mode", o.dvr_mode, "segments or samples")->check(CLI::IsMember({"segments", "samples"}));
  app.add_option("--background", o.background, "R,G,B[,A] in [0,1], or white, black, transparent");
  app.add_option("--eye", o.eye, "Camera position X,Y,Z");
  app.add_option("--at", o.at, "Look-at point X,Y,Z");
  app.add_option("--up", o.up, "Up vector X,Y,Z");
  app.add_option("--fov", o.fov, "Vertical field of view, degrees")->check(CLI::Range(0.01f, 179.f));
  app.add_option("--zoom", o.zoom, "Default view: scale of the fitted mesh")->check(CLI::Range(1e-3f, 1e3f));
  app.add_option("--azimuth", o.azimuth, "Default view: degrees about +y");
  app.add_option("--elevation", o.elevation, "Default view: degrees up")->check(CLI::Range(-89.f, 89.f));
  app.add_option("--size", o.size, "Image size WxH");
  app.add_option("-o,--output", o.out, "Output image, .png or .ppm (written by rank 0)");
  app.add_option("--threads", o.threads, "Worker threads per rank (default: all cores)")->check(CLI::Range(1, 4096));
  app.add_flag("--skip-unsupported", o.skip_unsupported, "Skip cells other than tets and hexes");
  app.add_flag("--stats", o.stats, "Per-rank timings as JSON lines on rank 0's stdout");
  app.add_flag("--shadows", o.shadows, "Refused: shadow rays need the whole mesh");
  app.add_option("--ao", o.ao, "Refused: ambient-occlusion rays need the whole mesh");

  int code = exit_ok;
  try {
    app.parse(argc, argv);
    code = run(o, rank, ranks);
  } catch (CLI::CallForHelp const& e) {
    code = rank == 0 ? app.exit(e) : 0;
  } catch (CLI::ParseError const& e) {
    if (rank == 0) std::cerr << "cellray-mpi-render: error: " << e.what() << " (see --help)\n";
    code = exit_usage;  // every rank parses the same flags: all fail alike
  }
  MPI_Finalize();
  return code;
}
