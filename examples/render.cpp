// cellray-render: renders isosurfaces or a volume (DVR) of a legacy .vtk or
// .vtu mesh, or of a generated default scene, to PNG or PPM. See docs/cli.md
// or `cellray-render --help`. Every message goes to stderr; stdout carries
// only the --stats JSON, so scripts can parse it.

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <unistd.h>

#include <csignal>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <glm/common.hpp>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <cellray/bvh/bvh.hpp>
#include <cellray/error.hpp>
#include <cellray/io/image_write.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/mesh/validate.hpp>
#include <cellray/render/camera.hpp>
#include <cellray/render/reference.hpp>
#include <cellray/render/render.hpp>
#include <cellray/render/transfer_function.hpp>

#include "cli_common.hpp"
#include "exodus.hpp"
#include "framing.hpp"
#include "legend.hpp"

namespace {

using namespace cellray;
using namespace cellray_cli;

/// --stats' total_ms counts from here (static initialisation, before main).
Clock::time_point const process_start = Clock::now();

std::string gib(double bytes) {
  char s[32];
  std::snprintf(s, sizeof s, "%.1f GiB", bytes / double(uint64_t(1) << 30));
  return s;
}

/// Joins a multi-line message (a validation report) into one line: "a; b".
std::string one_line(std::string msg) {
  while (!msg.empty() && (msg.back() == '\n' || msg.back() == ' ')) msg.pop_back();
  std::string out;
  for (size_t i = 0; i < msg.size(); ++i) {
    if (msg[i] != '\n') {
      out += msg[i];
      continue;
    }
    out += "; ";
    while (i + 1 < msg.size() && msg[i + 1] == ' ') ++i;
  }
  return out;
}

// ------------------------------------------------------ transfer functions

/// Piecewise-linear lookup over increasing knots `x` (ends extend flat).
template <class T> T lerp_at(std::vector<float> const& x, std::vector<T> const& y, float v) {
  if (v <= x.front()) return y.front();
  if (v >= x.back()) return y.back();
  size_t const i = size_t(std::upper_bound(x.begin(), x.end(), v) - x.begin());
  float const den = x[i] - x[i - 1];
  float const t = den > 0.f ? (v - x[i - 1]) / den : 1.f;
  return y[i - 1] + t * (y[i] - y[i - 1]);
}

/// Maps knots from their own range onto [lo, hi] (ParaView's default when a
/// preset is applied: "use preset range" off).
void rescale(std::vector<float>& x, float lo, float hi) {
  double const a = x.front(), b = x.back();  // double: hi - lo overflows float near +-3e38
  for (float& v : x) v = b > a ? float(lo + (v - a) / (b - a) * (double(hi) - lo)) : lo;
}

/// Reads a colour map saved by ParaView ("Save preset": a JSON list of
/// objects; the first is used) or one such object. "RGBPoints" is
/// [x, r, g, b, ...]; the optional "Points" is [x, alpha, midpoint,
/// sharpness, ...] (midpoint and sharpness are ignored: linear ramps). Without
/// "Points" the opacity rises linearly from 0 to `max_alpha` over the range;
/// with them, `alpha_scale` multiplies their opacities.
TransferFunction read_paraview_tf(std::string const& path, float vmin, float vmax, float max_alpha, float alpha_scale,
                                  bool keep_file_range) {
  std::ifstream in(path);
  if (!in) throw IoError(path + ": cannot open the transfer function file");
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(in);
  } catch (nlohmann::json::exception const& e) {
    throw IoError(path + ": not valid JSON (" + e.what() + ")");
  }
  nlohmann::json const* preset = &doc;
  if (doc.is_array()) {
    if (doc.empty()) throw IoError(path + ": the preset list is empty");
    preset = &doc[0];
  }
  if (!preset->is_object()) throw IoError(path + ": expected a ParaView colour map preset (a JSON object or a list of them)");
  auto numbers = [&](char const* key, std::vector<double>& out) {
    auto it = preset->find(key);
    if (it == preset->end()) return false;
    if (!it->is_array()) throw IoError(path + ": \"" + key + "\" must be a list of numbers");
    for (auto const& v : *it) {
      if (!v.is_number()) throw IoError(path + ": \"" + key + "\" must be a list of numbers");
      out.push_back(v.get<double>());
      // Positions and opacities are floats from here on: 1e300 would become inf.
      if (!std::isfinite(float(out.back())))
        throw IoError(path + ": \"" + key + "\" entry " + std::to_string(out.size() - 1) + " (" + shown(v.dump()) +
                      ") is beyond the range of a float");
    }
    if (out.empty() || out.size() % 4 != 0)
      throw IoError(path + ": \"" + key + "\" must hold groups of 4 numbers, it has " + std::to_string(out.size()));
    return true;
  };
  std::vector<double> rgb_points, alpha_points;
  if (!numbers("RGBPoints", rgb_points))
    throw IoError(path + ": no \"RGBPoints\" (indexed / categorical colour maps are not supported)");
  bool const has_alpha = numbers("Points", alpha_points);

  std::vector<float> cx, ax;
  std::vector<glm::vec3> cv;
  std::vector<float> av;
  for (size_t i = 0; i < rgb_points.size(); i += 4) {
    if (!cx.empty() && float(rgb_points[i]) < cx.back())
      throw IoError(path + ": \"RGBPoints\" values must not decrease (at entry " + std::to_string(i) + ")");
    cx.push_back(float(rgb_points[i]));
    cv.emplace_back(rgb_points[i + 1], rgb_points[i + 2], rgb_points[i + 3]);
  }
  if (has_alpha) {
    for (size_t i = 0; i < alpha_points.size(); i += 4) {
      if (!ax.empty() && float(alpha_points[i]) < ax.back())
        throw IoError(path + ": \"Points\" values must not decrease (at entry " + std::to_string(i) + ")");
      ax.push_back(float(alpha_points[i]));
      av.push_back(float(alpha_points[i + 1]) * alpha_scale);
    }
  } else {
    ax = {0.f, 1.f};  // ParaView's default opacity: a linear ramp
    av = {0.f, max_alpha};
  }
  if (!keep_file_range || !has_alpha) {
    if (!keep_file_range) rescale(cx, vmin, vmax);
    rescale(ax, keep_file_range ? cx.front() : vmin, keep_file_range ? cx.back() : vmax);
  }
  std::vector<float> knots(cx);
  knots.insert(knots.end(), ax.begin(), ax.end());
  std::sort(knots.begin(), knots.end());
  knots.erase(std::unique(knots.begin(), knots.end()), knots.end());
  TransferFunction tf;
  for (float k : knots) {
    glm::vec3 const c = glm::clamp(lerp_at(cx, cv, k), glm::vec3(0.f), glm::vec3(1.f));
    float const a = std::clamp(lerp_at(ax, av, k), 0.f, 1.f);
    tf.values.push_back(k);
    tf.rgba.emplace_back(c, a);
  }
  try {
    tf.check();
  } catch (InvalidArgument const& e) {
    throw IoError(path + ": " + e.what());
  }
  return tf;
}

// ---------------------------------------------------------------- progress

/// Prints "cellray-render: <what>..." on stderr when a phase is still
/// running after one second, and the time it took when it ends. Does nothing
/// when disabled (stderr not a terminal and no --progress).
/// The phase running last, for an out-of-memory message that says where.
std::string current_phase;

class Phase {
 public:
  Phase(bool enabled, std::string what) : what_(std::move(what)), t0_(Clock::now()) {
    current_phase = what_;
    if (enabled) watcher_ = std::thread([this] { watch(); });
  }
  Phase(Phase const&) = delete;
  Phase& operator=(Phase const&) = delete;
  ~Phase() { finish(); }

  /// Ends the phase; returns its duration in milliseconds.
  double finish() {
    if (!finished_) {
      ms_ = ms_since(t0_);
      {
        std::lock_guard<std::mutex> lock(m_);
        finished_ = true;
      }
      cv_.notify_all();
      if (watcher_.joinable()) watcher_.join();
      if (printed_) std::fprintf(stderr, " %.1f s\n", ms_ / 1e3);
    }
    return ms_;
  }

 private:
  void watch() {
    std::unique_lock<std::mutex> lock(m_);
    if (cv_.wait_for(lock, std::chrono::seconds(1), [this] { return finished_; })) return;
    std::fprintf(stderr, "cellray-render: %s...", what_.c_str());
    std::fflush(stderr);
    printed_ = true;
  }

  std::string what_;
  Clock::time_point t0_;
  std::thread watcher_;
  std::mutex m_;
  std::condition_variable cv_;
  bool finished_ = false;
  bool printed_ = false;  // written by the watcher, read after join
  double ms_ = 0;
};

// ------------------------------------------------------------------ options

struct Options {
  std::string mesh_path;
  std::string generate = "tets";
  uint64_t cells = 300000;
  std::string array;
  std::string mode = "iso";
  std::string iso, iso_opacity;
  std::string tf = "cool-warm";
  bool tf_file_range = false;
  float step = 0.f;
  std::string eye, at, up;
  float fov = 30.f;
  std::string size = "1024x768";
  std::string out = "cellray.png";
  std::string isa = "auto";
  std::string traversal = "packet";
  std::string secondary = "march";
  int threads = 0;
  int frames = 1;
  bool shadows = false;
  int ao = 0;
  int time_step = -1;
  bool reference = false;
  bool stats = false;
  bool progress = false;
  bool verbose = false;
  bool info = false;
  std::string builder = "auto";
  int leaf_size = 7;
  int group_size = 16;
  std::string dvr_mode = "segments";
  bool no_march = false;
  bool march = false;
  std::string fold_tets = "auto";
  bool dvr_shading = false;
  bool no_skip = false;
  int neubauer = 0;
  bool central_normals = false;
  std::string normals = "smooth";
  std::string color_by, color_map = "cool-warm";
  std::vector<std::string> clip;
  std::string clip_box;
  bool clip_caps = false;
  bool skip_unsupported = false;
  std::string cell_to_point;
  float unit_distance = 0.f;
  float opacity = -1.f;
  std::string background;
  float zoom = 1.f;
  float azimuth = 0.f, elevation = 0.f;
  int orbit = 0;
  bool legend = false;
  std::string title;
  std::string font = cellray_render::default_font_path;
};

constexpr char const* exit_code_help =
    "Exit codes: 0 success; 1 other error; 2 usage (unknown flag, bad value, unknown array);\n"
    "3 I/O (mesh, transfer function or font file missing, not a regular file, unreadable or malformed -- cells\n"
    "naming points the file lacks, unsupported cells; image not writable: the old image is kept);\n"
    "4 invalid mesh (fails validation: a non-finite position of a vertex a cell uses; no cells, no finite value).\n"
    "A file with no point array renders its first cell array whose values vary, averaged to the vertices, else\n"
    "the coordinate along its longest side (a note on stderr says which).\n"
    "Negative numbers as values work directly (--eye -2,1,3) or with '=' (--eye=-2,1,3).";

void add_options(CLI::App& app, Options& o) {
  app.add_option("mesh", o.mesh_path, "Legacy .vtk, .vtu or .pvtu mesh (pieces merged); none: the generated default scene");
  app.add_option("--generate", o.generate, "Default scene cell type (without a mesh)")
      ->check(CLI::IsMember({"tets", "hexes", "wedges", "pyramids", "hex-family"}))
      ->capture_default_str();
  app.add_option("--cells", o.cells, "Default scene size in cells (approximate)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 31))
      ->capture_default_str();
  app.add_option("--array", o.array, "Point array to render (default: the first)");
  app.add_option("--time-step", o.time_step,
                 "Render the K-th point array (0-based) as a time step of the --array one: refits the BVH's "
                 "value ranges, never rebuilds")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--cell-to-point", o.cell_to_point,
                 "Average the cell array NAME to the vertices and render it (unless --array says otherwise)");
  app.add_flag("--skip-unsupported", o.skip_unsupported, "Skip cells cellray cannot read (2D cells, other non-linear 3D types...) instead of failing");
  app.add_option("--mode", o.mode, "isosurfaces or direct volume rendering")
      ->check(CLI::IsMember({"iso", "dvr"}))
      ->capture_default_str();
  app.add_option("--iso", o.iso, "Isovalues V1,V2,... (1 to 8; default: 3 spread over the value range)");
  app.add_option("--iso-opacity", o.iso_opacity,
                 "Opacity per isovalue A1,A2,... or one for all (default: 0.4 for all but the last, which is opaque)");
  app.add_option("--neubauer", o.neubauer, "Isosurface roots by N Neubauer steps instead of exactly")
      ->check(CLI::Range(1, 64));
  app.add_option("--normals", o.normals,
                 "Isosurface normals: smooth (per-vertex gradients interpolated in the cell, 12 bytes a vertex), "
                 "flat (the cell's own gradient: facets on tets) or central (differences, the paper's)")
      ->check(CLI::IsMember({"smooth", "flat", "central"}))
      ->capture_default_str();
  app.add_flag("--central-normals", o.central_normals, "Same as --normals central");
  app.add_option("--color-by", o.color_by, "Colour the isosurfaces by point array NAME (through --color-map)");
  app.add_option("--color-map", o.color_map,
                 "Colour map of --color-by and of --clip-caps, over that array's range: cool-warm, viridis, inferno, "
                 "grayscale")
      ->check(CLI::IsMember({"cool-warm", "viridis", "inferno", "grayscale"}))
      ->capture_default_str();
  app.add_option("--clip", o.clip,
                 "Clip plane X,Y,Z,NX,NY,NZ (a point and a normal, world units): the side the normal points to is "
                 "cut away; repeat for several (at most 16 with --clip-box)");
  app.add_option("--clip-box", o.clip_box, "Keep only the box X0,Y0,Z0,X1,Y1,Z1 (world units)");
  app.add_flag("--clip-caps", o.clip_caps,
               "Iso: draw the cut faces of --clip / --clip-box, coloured by the rendered array through --color-map");
  app.add_flag("--shadows", o.shadows, "Hard shadows from a light above the camera's left shoulder (iso)");
  app.add_option("--ao", o.ao, "Ambient-occlusion rays per hit (iso)")->check(CLI::Range(0, 1024));
  app.add_option("--tf", o.tf,
                 "DVR transfer function: cool-warm, viridis, inferno, grayscale, or a ParaView colour map JSON file")
      ->capture_default_str();
  app.add_flag("--tf-file-range", o.tf_file_range,
               "Keep a JSON colour map's own value range instead of rescaling it to the data range");
  app.add_option("--opacity", o.opacity,
                 "DVR peak opacity of a preset ramp (default 0.8); scales a JSON file's opacity points")
      ->check(finite_in(0.f, 1.f));
  app.add_option("--unit-distance", o.unit_distance,
                 "DVR opacity unit distance, world units (default: scene diagonal / 10)")
      ->check(positive_finite);
  app.add_option("--step", o.step,
                 "DVR step, world units: sample spacing, or the longest integration piece of a cell segment "
                 "(default: scene diagonal / 125 for segments, / 500 for samples)")
      ->check(positive_finite);
  app.add_option("--dvr-mode", o.dvr_mode,
                 "DVR by exact cell segments (default: faster and more accurate, docs/accuracy.md) or point samples")
      ->check(CLI::IsMember({"samples", "segments"}))
      ->capture_default_str();
  app.add_flag("--no-march", o.no_march,
               "DVR segments: clip the cells of the BVH leaves each packet reaches instead of marching from cell to "
               "cell through face neighbours (16 bytes per tet, 24 per hexahedron; the same image up to rounding; "
               "for comparisons)");
  app.add_flag("--march", o.march,
               "DVR segments march through face neighbours: the default for tets and hexahedra (wedges and pyramids "
               "included) and mixed meshes, folded or across their two parts; kept for scripts")
      ->excludes("--no-march");
  app.add_option("--fold-tets", o.fold_tets,
                 "A mesh of tets and hexahedra (wedges, pyramids): store its tets as collapsed hexahedra, one part "
                 "under one BVH (always), keep two parts (never), or fold when the tets are at most a fifth of the cells "
                 "(auto: folded tets run the hexahedron kernels)")
      ->check(CLI::IsMember({"auto", "always", "never"}))
      ->capture_default_str();
  app.add_flag("--dvr-shading", o.dvr_shading,
               "DVR gradient shading: headlight Lambert + Blinn-Phong from the scalar gradient, fading out where the "
               "field is flat");
  app.add_option("--group-size", o.group_size, "DVR samples per ray in its first traversal; each further one doubles, up to 32")
      ->check(CLI::Range(1, 32))
      ->capture_default_str();
  app.add_flag("--no-skip", o.no_skip, "Disable DVR empty-space skipping");
  app.add_option("--background", o.background, "R,G,B[,A] in [0,1], or white, black, transparent (default white)");
  app.add_option("--eye", o.eye, "Camera position X,Y,Z (default: framing the mesh bounds)");
  app.add_option("--zoom", o.zoom,
                 "Default view: the bounds' projection spans Z x 90% of the image's shorter side (default 1)")
      ->check(positive_finite);
  app.add_option("--azimuth", o.azimuth,
                 "Default view: turn the view direction DEG degrees about the up axis (+y) through the bounds' centre")
      ->check(finite_in(-36000.f, 36000.f));
  app.add_option("--elevation", o.elevation,
                 "Default view: raise the view direction DEG degrees towards +y (the result is kept within +-89)")
      ->check(finite_in(-180.f, 180.f));
  app.add_option("--orbit", o.orbit,
                 "Turntable: N frames around the up axis (+y) through the bounds' centre, 360/N degrees apart, one "
                 "BVH build; -o out/spin.png writes out/spin_0000.png, out/spin_0001.png, ...")
      ->check(CLI::Range(1, 100000));
  app.add_flag("--legend", o.legend,
               "Draw a colour legend: the array's name, its value range with ticks, and the transfer function's "
               "colours (DVR) or each isosurface's colour and value (iso)");
  app.add_option("--title", o.title, "Draw TEXT as a title at the top of the image");
  app.add_option("--font", o.font, "TrueType font for --legend and --title")->capture_default_str();
  app.add_option("--at", o.at, "Look-at point X,Y,Z (default: the bounds' centre)");
  app.add_option("--up", o.up, "Up vector X,Y,Z (default 0,1,0)");
  app.add_option("--fov", o.fov, "Vertical field of view, degrees")->check(finite_in(0.01f, 179.f))->capture_default_str();
  app.add_option("--size", o.size, "Image size WxH")->capture_default_str();
  app.add_option("-o,--output", o.out, "Output image, .png or .ppm")->capture_default_str();
  app.add_option("--isa", o.isa, "SIMD instruction set (auto honours CELLRAY_ISA)")
      ->check(CLI::IsMember({"auto", "sse4", "avx2", "avx512"}))
      ->capture_default_str();
  app.add_option("--traversal", o.traversal, "Primary-ray traversal")
      ->check(CLI::IsMember({"packet", "spmd", "hybrid"}))
      ->capture_default_str();
  app.add_option("--secondary", o.secondary,
                 "Shadow/AO ray query: nearest hit, any hit (occlusion), any hit with AO rays sorted by direction, "
                 "sorted and 4 packets per traversal (grouped), or AO rays marching from their hit cells through face "
                 "neighbours (march: tet meshes and mixed meshes kept as two parts; same image)")
      ->check(CLI::IsMember({"nearest", "occlusion", "sorted", "grouped", "march"}))
      ->capture_default_str();
  app.add_option("--threads", o.threads, "Worker threads (default: all cores)")->check(CLI::Range(1, 4096));
  app.add_option("--frames", o.frames, "Render N times and report the median time")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--builder", o.builder,
                 "BVH builder; auto: morton for one image, binned_sah for --frames N or --orbit N")
      ->check(CLI::IsMember({"auto", "binned_sah", "spatial_median", "morton", "sah", "median"}))
      ->capture_default_str();
  app.add_option("--leaf-size", o.leaf_size, "Largest BVH leaf, cells")->capture_default_str();
  app.add_flag("--reference", o.reference, "Render with the double-precision reference renderer (slow; the oracle for comparisons)");
  app.add_flag("--stats", o.stats, "Print one JSON object with sizes and timings on stdout");
  app.add_flag("--progress", o.progress, "Progress lines on stderr even when it is not a terminal");
  app.add_flag("-v,--verbose", o.verbose, "Print what was read, the validation report and BVH statistics");
  app.add_flag("--info", o.info, "Print what was read and the arrays, then exit without rendering");
}

// ------------------------------------------------------------------- scene

/// The mesh data, owned here; views into it are made once it is final.
struct Loaded {
  std::optional<UnstructuredGrid> grid;
  std::optional<GeneratedMesh<4>> gen_tets;
  std::optional<GeneratedMesh<8>> gen_hexes;
  std::string name;  // for messages
  TetMesh tets;
  HexMesh hexes;

  std::vector<ScalarArray> const& arrays() const { return tets.empty() ? hexes.arrays() : tets.arrays(); }
  uint64_t cells() const { return tets.cell_count() + hexes.cell_count(); }
  uint64_t vertices() const { return tets.empty() ? hexes.vertex_count() : tets.vertex_count(); }
  uint64_t tets_as_hexes = 0;  // tets folded into the hexahedra (load_file)
  /// The file's id of each cell of a part (empty: the cell's index is its id).
  Span<uint32_t> tet_file_cells() const { return grid ? view(grid->tet_file_cells) : Span<uint32_t>{}; }
  Span<uint32_t> hex_file_cells() const { return grid ? view(grid->hex_file_cells) : Span<uint32_t>{}; }
  std::string cell_type() const {
    return tets_as_hexes || (!tets.empty() && !hexes.empty()) ? "mixed" : tets.empty() ? "hex" : "tet";
  }
};

/// What the parts hold, for --info: "N tetrahedra" and the hexahedral
/// part's cells by kind (wedges, pyramids and folded tetrahedra are stored
/// as collapsed hexahedra; mesh/validate.hpp names them).
std::string describe_parts(Loaded const& l) {
  std::ostringstream s;
  KindCounts kinds;
  for (uint64_t c = 0; c < l.hexes.cell_count(); ++c) {
    uint64_t v[8];
    for (int k = 0; k < 8; ++k) v[k] = l.hexes.vertex(c, k);
    kinds.add(collapsed_kind(v));
  }
  s << (!l.tets.empty() && !l.hexes.empty() ? "two parts, " : "one part, ");
  if (!l.tets.empty()) s << l.tets.cell_count() << " tetrahedra" << (l.hexes.empty() ? "" : " and ");
  if (!l.hexes.empty()) {
    if (kinds[CollapsedKind::hexahedron] == l.hexes.cell_count()) s << l.hexes.cell_count() << " hexahedra";
    else s << l.hexes.cell_count() << " cells as hexahedra (" << kinds.list() << ")";
  }
  if (l.tets.empty() && l.hexes.empty()) s << "no cells";
  return s.str();
}

std::string list_names(std::vector<std::string> const& names) {
  std::string s;
  for (auto const& n : names) s += (s.empty() ? "" : ", ") + shown(n);
  return s.empty() ? "none" : s;
}

std::vector<std::string> point_array_names(Loaded const& l) {
  std::vector<std::string> n;
  for (auto const& a : l.arrays()) n.push_back(a.name);
  return n;
}

std::vector<std::string> cell_array_names(Loaded const& l) {
  std::vector<std::string> n;
  if (l.grid)
    for (auto const& a : l.grid->cell_arrays) n.push_back(a.name);
  return n;
}

/// A file with no point array still renders (a user opening a solver's
/// cell-centred output or a bare mesh expects a picture, not a flag to
/// look up): the first cell array whose values vary, averaged to the
/// vertices as --cell-to-point does, else the coordinate along the longest
/// side of the bounds (a geometry-only mesh: iso shows a cut across it,
/// DVR the shape). Says which on stderr.
void add_default_field(UnstructuredGrid& g, std::string const& name) {
  for (CellArray const& c : g.cell_arrays) {
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (auto const* v : {&c.tet_values, &c.hex_values})
      for (float x : *v)
        if (std::isfinite(x)) lo = std::min(lo, x), hi = std::max(hi, x);
    if (!(hi > lo)) continue;
    std::cerr << "cellray-render: note: " << name << " has no point arrays; rendering cell array '" << c.name
              << "' averaged to the vertices (as --cell-to-point '" << c.name << "')\n";
    g.cell_to_point(c.name);
    return;
  }
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  for (uint64_t v = 0; v < g.vertex_count(); ++v) {
    glm::vec3 const p(g.xyz[3 * v], g.xyz[3 * v + 1], g.xyz[3 * v + 2]);
    lo = glm::min(lo, p), hi = glm::max(hi, p);
  }
  glm::vec3 const size = hi - lo;
  int const axis = size.x >= size.y && size.x >= size.z ? 0 : size.y >= size.z ? 1 : 2;
  PointArray a;
  a.name = std::string(1, "xyz"[axis]);
  a.values.resize(g.vertex_count());
  for (uint64_t v = 0; v < g.vertex_count(); ++v) a.values[v] = g.xyz[3 * v + uint64_t(axis)];
  std::cerr << "cellray-render: note: " << name << " has no data array that varies"
            << (g.cell_arrays.empty() ? "" : " (its cell arrays are constant)") << "; rendering the " << a.name
            << " coordinate (the longest side) as point array '" << a.name << "'\n";
  g.report.arrays_read.push_back("point '" + a.name + "' (the vertices' " + a.name + " coordinate: no data array varies)");
  g.point_arrays.push_back(std::move(a));
}

void load(Options const& o, Loaded& l) {
  if (o.mesh_path.empty()) {
    l.name = "default scene";
    if (o.generate != "tets") {
      // Wedges and pyramids as collapsed hexahedra, as the readers store them.
      if (o.generate == "hexes") l.gen_hexes = generate_hexes(o.cells);
      else if (o.generate == "wedges") l.gen_hexes = generate_wedges(o.cells);
      else if (o.generate == "pyramids") l.gen_hexes = generate_pyramids(o.cells);
      else l.gen_hexes = generate_hex_family(o.cells * 2 / 3);  // a third of its lattice cells split in two
      l.hexes = l.gen_hexes->mesh();
    } else {
      l.gen_tets = generate_tets(o.cells);
      l.tets = l.gen_tets->mesh();
    }
    if (!o.cell_to_point.empty()) throw UsageError("--cell-to-point needs a mesh file (the default scene has point arrays only)");
    return;
  }
  l.name = std::filesystem::path(o.mesh_path).filename().string();
  ReadOptions ro;
  ro.skip_unsupported_cells = o.skip_unsupported;
  try {
    if (cli::is_exodus_path(o.mesh_path)) {
      l.grid = cli::read_exodus_through_module(o.mesh_path, ro);
    } else {
      l.grid = read_mesh(o.mesh_path, ro);
    }
  } catch (IoError const& e) {
    // The reader names its option; tell the flag instead.
    if (!o.skip_unsupported && std::string(e.what()).find("unsupported cells") != std::string::npos)
      throw IoError(std::string(e.what()) + "; cellray-render: pass --skip-unsupported to skip them");
    throw;
  }
  UnstructuredGrid& g = *l.grid;
  if (!o.cell_to_point.empty()) {
    if (!g.cell_array(o.cell_to_point)) {
      std::vector<std::string> names;
      for (auto const& a : g.cell_arrays) names.push_back(a.name);
      throw UsageError("--cell-to-point: " + l.name + " has no cell array '" + shown(o.cell_to_point) +
                       "' (cell arrays: " + list_names(names) + ")");
    }
    // A file may hold a point and a cell array of one name (OpenFOAM's T).
    std::string target = o.cell_to_point;
    if (g.point_array(target)) target += "@cells";
    g.cell_to_point(o.cell_to_point, target);
  }
  if (g.point_arrays.empty() && !g.empty()) add_default_field(g, l.name);
  if (g.empty())
    throw InvalidMesh(l.name + " holds no tetrahedra or hexahedra" +
                      (g.report.skipped_count() ? " (all cells were skipped as unsupported)" : ""));
  // A mixed mesh with few tets (a snappyHexMesh mesh: hexes, wedges, and
  // the polyhedra's pyramids and tets) becomes one part: its tets as
  // collapsed hexahedra, one BVH, and DVR marches across all its cells.
  // Folded tets run the hexahedron kernels, so only a few pay. One thread,
  // 1024x768, folded against two parts: the flange (16% tets) iso
  // 0.96-1.1x, DVR through the trees 1.05x, marching 1.36x the speed;
  // sphere_bl.geo's boundary-layer meshes (30-82% tets) iso 0.4-0.5x, and
  // (2 threads) DVR 0.45-0.63x of two parts marching across each other
  // (link_face_neighbours), where the flange folded is 1.17x (docs/cli.md).
  bool const few_tets = 4 * g.tet_count() <= g.hex_count();  // at most a fifth of the cells
  bool const fold = o.fold_tets == "always" || (o.fold_tets == "auto" && few_tets);
  if (!g.tets.empty() && !g.hexes.empty() && fold) l.tets_as_hexes = g.fold_tets_into_hexes();
  l.tets = g.tet_mesh();
  l.hexes = g.hex_mesh();
}

/// The array a name selects, or a usage error listing the choices.
std::string select_array(Loaded const& l, std::string const& wanted, char const* flag) {
  auto const names = point_array_names(l);
  if (std::find(names.begin(), names.end(), wanted) != names.end()) return wanted;
  std::string msg = std::string(flag) + ": " + l.name + " has no point array '" + shown(wanted) + "' (point arrays: " +
                    list_names(names) + ")";
  auto const cells = cell_array_names(l);
  if (std::find(cells.begin(), cells.end(), wanted) != cells.end())
    msg += "; '" + shown(wanted) + "' is a cell array: use --cell-to-point " + shown(wanted);
  throw UsageError(msg);
}

template <int N> void set_active(CellMesh<N>& m, std::string const& name) {
  if (!m.empty()) m = m.with_array(name);
}

/// Validates a non-empty part; returns its finite value range through lo/hi.
/// Findings name the file's cell ids (`file_cells`, where the reader
/// reordered the cells), as ParaView shows them.
template <int N>
void check_part(CellMesh<N> const& m, Span<uint32_t> file_cells, Options const& o, char const* what, float& lo, float& hi) {
  if (m.empty()) return;
  ValidationReport const rep = validate(m, file_cells);
  if (o.verbose) std::cerr << "cellray-render: " << what << ": " << rep.message() << "\n";
  if (!rep.ok()) throw InvalidMesh(std::string(what) + " failed validation: " + one_line(rep.message()));
  if (rep.has_warnings() && !o.verbose) std::cerr << "cellray-render: warning: " << what << ": " << one_line(rep.message()) << "\n";
  lo = std::min(lo, rep.value_min);
  hi = std::max(hi, rep.value_max);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  size_t const n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double peak_rss_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;  // Linux: KiB
}

/// Where -o would fail, found before any work: a missing or read-only
/// folder, a directory or device in the file's place (exit 3).
void check_output_path(std::string const& out) {
  namespace fs = std::filesystem;
  std::error_code ec;
  auto const st = fs::status(out, ec);
  if (st.type() == fs::file_type::directory) throw IoError("-o: " + shown(out) + " is a directory");
  if (!ec && st.type() != fs::file_type::not_found && st.type() != fs::file_type::regular)
    throw IoError("-o: " + shown(out) + " is not a regular file (a device, FIFO or socket)");
  fs::path target(out);
  if (fs::is_symlink(fs::symlink_status(target, ec))) target = fs::weakly_canonical(target, ec);
  fs::path const dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec))
    throw IoError("-o: " + shown(out) + ": the directory " + shown(dir.string()) + " does not exist");
  if (::access(dir.c_str(), W_OK) != 0)
    throw IoError("-o: " + shown(out) + ": cannot write in the directory " + shown(dir.string()) + " (" +
                  std::strerror(errno) + ")");
}

/// The k-th of n turntable frames of `out`: out/spin.png -> out/spin_0007.png
/// (at least 4 digits, more when n needs them).
std::string orbit_path(std::string const& out, int k, int n) {
  std::filesystem::path const p(out);
  int digits = 4;
  for (int m = 10000; m < n && digits < 9; m *= 10) ++digits;
  char num[16];
  std::snprintf(num, sizeof num, "_%0*d", digits, k);
  std::filesystem::path q = p;
  q.replace_filename(p.stem().string() + num + p.extension().string());
  return q.string();
}

bool is_tf_preset(std::string const& name) {
  return name == "cool-warm" || name == "viridis" || name == "inferno" || name == "grayscale";
}

/// --tf names a file when one exists by that name, or when it looks like a
/// path (a folder or a .json ending): a missing file is then an I/O error
/// (exit 3), not an unknown preset (exit 2).
bool tf_names_file(std::string const& tf) {
  std::error_code ec;
  if (std::filesystem::symlink_status(tf, ec).type() != std::filesystem::file_type::not_found && !ec) return true;
  if (is_tf_preset(tf)) return false;
  return tf.find('/') != std::string::npos ||
         (tf.size() >= 5 && io::iequals(std::string_view(tf).substr(tf.size() - 5), ".json"));
}

/// The same for a point array's values, when they are so large that their
/// differences, or gradients squared, overflow float (values near 1e38):
/// v -> (v - centre) * scale, scale a power of two. Isovalues and a colour
/// map's own values (--tf-file-range) are mapped alike; messages show data
/// units. Affine in the value, so the picture does not change.
struct ValueFrame {
  double centre = 0.0, scale = 1.0;
  bool moved = false;

  float to_render(float v) const { return moved ? float((double(v) - centre) * scale) : v; }
  double to_data(float v) const { return moved ? double(v) / scale + centre : double(v); }
};

ValueFrame fit_values(std::vector<float>& values) {
  ValueFrame f;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (float v : values)
    if (std::isfinite(v)) lo = std::min(lo, double(v)), hi = std::max(hi, double(v));
  if (!(lo <= hi) || std::max(std::fabs(lo), std::fabs(hi)) <= 0x1p+40) return f;
  f.moved = true;
  f.centre = 0.5 * (lo + hi);
  double const reach = std::max(hi - f.centre, 1e-300);
  f.scale = std::ldexp(1.0, -std::ilogb(reach));  // max |v - centre| -> [1, 2)
  for (float& v : values)
    if (std::isfinite(v)) v = float((double(v) - f.centre) * f.scale);
  return f;
}

/// A similarity transform of a file mesh's coordinates, applied before
/// anything sees them when float ray tracing could not use them as they are:
/// far from the origin for their size (UTM-like offsets: the kernels'
/// plane equations would cancel) or an extent near float's limits (products
/// of edge lengths overflow or underflow). Centre at the bounds' centre,
/// computed in double; scale a power of two, so scaling itself is exact.
/// Camera flags and world lengths (--eye, --at, --step, --unit-distance) are
/// mapped the same way, so the picture is the one the file describes.
struct Frame {
  glm::dvec3 centre{0.0};
  double scale = 1.0;
  bool moved = false;

  glm::vec3 point(glm::vec3 const& w) const { return glm::vec3((glm::dvec3(w) - centre) * scale); }
  float length(float w) const { return float(double(w) * scale); }
  double world_length(float f) const { return double(f) / scale; }
};

Frame fit_frame(UnstructuredGrid& g) {
  Frame f;
  constexpr double inf = std::numeric_limits<double>::infinity();
  glm::dvec3 lo(inf), hi(-inf);
  // In parallel: a fresh process pays this before the first ray (608k tets
  // read 2.4M random vertices: ~18 ms on one thread).
  using Box = std::pair<glm::dvec3, glm::dvec3>;
  auto grow = [&](std::vector<uint32_t> const& ids) {
    Box const b = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, ids.size(), size_t(1) << 16), Box{lo, hi},
        [&](tbb::blocked_range<size_t> const& r, Box acc) {
          for (size_t i = r.begin(); i < r.end(); ++i)
            for (int k = 0; k < 3; ++k) {
              float const x = g.xyz[3 * size_t(ids[i]) + size_t(k)];
              if (std::isfinite(x)) acc.first[k] = std::min(acc.first[k], double(x)), acc.second[k] = std::max(acc.second[k], double(x));
            }
          return acc;
        },
        [](Box a, Box const& b) { return Box{glm::min(a.first, b.first), glm::max(a.second, b.second)}; });
    lo = b.first, hi = b.second;
  };
  grow(g.tets);
  grow(g.hexes);
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return f;  // validation names the problem
  double const extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
  double const reach = std::max({std::fabs(lo.x), std::fabs(lo.y), std::fabs(lo.z), std::fabs(hi.x), std::fabs(hi.y),
                                 std::fabs(hi.z)});
  if (!(extent > 0.0)) return f;
  bool const fits = extent >= 0x1p-20 && extent <= 0x1p+20 && reach <= 0x1p+8 * extent;
  if (fits) return f;
  f.moved = true;
  f.centre = 0.5 * (lo + hi);
  f.scale = std::ldexp(1.0, -std::ilogb(extent));  // extent -> [1, 2)
  for (size_t v = 0; v < g.xyz.size() / 3; ++v)
    for (int k = 0; k < 3; ++k) {
      float& x = g.xyz[3 * v + size_t(k)];
      if (std::isfinite(x)) x = float((double(x) - f.centre[k]) * f.scale);
    }
  return f;
}

int run(Options const& o) {
  bool const progress = o.progress || isatty(STDERR_FILENO);

  // Everything checkable before any work is checked first.
  int width = 0, height = 0;
  parse_size(o.size, width, height);
  {
    // The float image, its 8-bit copy and the encoded file: about 24 bytes a
    // pixel. Linux overcommits, so a size past RAM would fail mid-render.
    double const pixels = double(width) * double(height);
    if (pixels > 0x1p+28)
      throw UsageError("--size " + o.size + ": " + std::to_string(uint64_t(pixels)) +
                       " pixels, more than 2^28; render larger images in tiles through the library (render_tile)");
    double const need = 24.0 * pixels;
    double const ram = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    if (ram > 0 && need > ram)
      throw UsageError("--size " + o.size + ": the image needs " + gib(need) + " of buffers, more than this machine's " +
                       gib(ram));
  }
  if (image_format(o.out).empty()) throw UsageError("-o: '" + shown(o.out) + "' must end in .png or .ppm");
  if (o.orbit > 0 && o.frames > 1)
    throw UsageError("--orbit with --frames " + std::to_string(o.frames) + ": an orbit renders each view once");
  check_output_path(o.orbit > 0 ? orbit_path(o.out, 0, o.orbit) : o.out);
  // The font is read before the mesh: a missing one is an I/O error (exit 3).
  std::optional<cellray_render::Font> font;
  if (o.legend || !o.title.empty()) font.emplace(o.font);
  bool const tf_file = o.mode == "dvr" && tf_names_file(o.tf);
  if (tf_file) io::require_regular_file(o.tf, "transfer function file");
  if (o.mode == "dvr" && !tf_file && !is_tf_preset(o.tf))
    throw UsageError("--tf: unknown transfer function preset '" + shown(o.tf) +
                     "' (presets: cool-warm, viridis, inferno, grayscale) and no file of that name");
  if (o.leaf_size < 1 || o.leaf_size > int(Node::max_leaf_items))
    throw UsageError("--leaf-size: must be in [1, " + std::to_string(Node::max_leaf_items) + "]");
  Isa isa = default_isa();
  if (o.isa != "auto") {
    isa = parse_isa(o.isa);
    if (!isa_available(isa)) throw UsageError("--isa " + o.isa + ": " + isa_unavailable_reason(isa));
  }
  Traversal const traversal = o.traversal == "spmd"     ? Traversal::spmd
                              : o.traversal == "hybrid" ? Traversal::hybrid
                                                        : Traversal::packet;
  BuildOptions bo;
  // One image: the Morton build is 2-3x faster than binned SAH (component8,
  // fresh processes, 2 threads: 30-50 against 65-130 ms) and its tree
  // renders DVR as fast and an isosurface 5-14% slower, so the first image
  // comes sooner (component8 iso 115-142 against 162-209 ms). Frames
  // rendered again and again repay the SAH build (docs/cli.md).
  bool const one_image = o.frames == 1 && o.orbit <= 1;
  if (o.builder == "auto") bo.builder = one_image ? BvhBuilder::morton : BvhBuilder::binned_sah;
  else if (o.builder == "spatial_median" || o.builder == "median") bo.builder = BvhBuilder::spatial_median;
  else if (o.builder == "morton") bo.builder = BvhBuilder::morton;
  else bo.builder = BvhBuilder::binned_sah;  // binned_sah, sah
  bo.max_leaf_size = uint32_t(o.leaf_size);
  bo.isa = isa;
  std::optional<glm::vec4> background;
  if (!o.background.empty()) background = parse_background(o.background);
  std::vector<float> isovalues, iso_opacity;
  if (!o.iso.empty()) {
    isovalues = parse_floats(o.iso, "--iso");
    if (isovalues.size() > 8) throw UsageError("--iso: at most 8 isovalues, got " + std::to_string(isovalues.size()));
  }
  if (!o.iso_opacity.empty()) {
    iso_opacity = parse_floats(o.iso_opacity, "--iso-opacity");
    for (float a : iso_opacity)
      if (a < 0.f || a > 1.f) throw UsageError("--iso-opacity: opacities must lie in [0, 1]");
  }
  std::optional<glm::vec3> eye, at, up;
  if (!o.eye.empty()) eye = parse_vec3(o.eye, "--eye");
  if (!o.at.empty()) at = parse_vec3(o.at, "--at");
  if (!o.up.empty()) up = parse_vec3(o.up, "--up");
  // Clip planes in world units (mapped with the mesh's Frame once it is read).
  std::vector<ClipPlane> world_clip;
  for (auto const& text : o.clip) {
    auto const v = parse_floats(text, "--clip");
    if (v.size() != 6) throw UsageError("--clip: expected X,Y,Z,NX,NY,NZ, got '" + shown(text) + "'");
    if (v[3] == 0.f && v[4] == 0.f && v[5] == 0.f) throw UsageError("--clip: the normal of '" + shown(text) + "' is zero");
    world_clip.push_back({{v[0], v[1], v[2]}, {v[3], v[4], v[5]}});
  }
  std::optional<std::pair<glm::vec3, glm::vec3>> world_box;
  if (!o.clip_box.empty()) {
    auto const v = parse_floats(o.clip_box, "--clip-box");
    if (v.size() != 6 || v[0] > v[3] || v[1] > v[4] || v[2] > v[5])
      throw UsageError("--clip-box: expected X0,Y0,Z0,X1,Y1,Z1 with X0 <= X1, Y0 <= Y1, Z0 <= Z1, got '" +
                       shown(o.clip_box) + "'");
    world_box = {{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
  }
  if (world_clip.size() + (world_box ? 6 : 0) > size_t(Clip::max_planes))
    throw UsageError("--clip, --clip-box: at most " + std::to_string(Clip::max_planes) +
                     " planes in all (a box is 6)");

  std::optional<tbb::global_control> thread_limit;
  if (o.threads > 0) thread_limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(o.threads));
  int const threads = o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();
  // TBB's first parallel call loads its allocator and starts the worker
  // threads (~2-3 ms on a fresh process here, and the workers join late):
  // done beside the file's reading instead of inside the loader's first
  // parallel loop.
  struct PoolStart {
    std::thread thread;
    ~PoolStart() { thread.join(); }
  } const pool_start{std::thread([] { tbb::parallel_for(0, 2, [](int) {}); })};

  // Load.
  Loaded l;
  double load_ms = 0;
  {
    Phase ph(progress, o.mesh_path.empty() ? "generating the default scene" : "reading " + o.mesh_path);
    load(o, l);
    load_ms = ph.finish();
  }
  auto const prepare_t0 = Clock::now();
  Frame const frame = l.grid ? fit_frame(*l.grid) : Frame{};
  Clip clip;
  for (ClipPlane const& c : world_clip) clip.planes.push_back({frame.point(c.point), c.normal});
  if (world_box)
    for (ClipPlane const& c : clip_box(frame.point(world_box->first), frame.point(world_box->second)))
      clip.planes.push_back(c);
  if (frame.moved && (o.verbose || o.info))
    std::cerr << "cellray-render: coordinates moved by -(" << frame.centre.x << ", " << frame.centre.y << ", "
              << frame.centre.z << ") and scaled by " << frame.scale << " for float ray tracing\n";
  if (l.grid && (o.verbose || o.info)) std::cerr << l.grid->report.summary() << "\n";
  if (l.grid && l.grid->report.skipped_count() && !o.verbose && !o.info)
    std::cerr << "cellray-render: note: skipped " << l.grid->report.skipped_count() << " unsupported cells\n";
  auto const names = point_array_names(l);
  if (o.info) {
    std::cerr << l.name << ": " << describe_parts(l) << "; " << l.vertices() << " vertices\n  point arrays: "
              << list_names(names)
              << "\n  cell arrays: " << list_names(cell_array_names(l)) << "\n";
    return exit_ok;
  }
  if (names.empty()) {
    auto const cells = cell_array_names(l);
    throw InvalidMesh(l.name + " has no point arrays to render" +
                      (cells.empty() ? std::string() : " (cell arrays: " + list_names(cells) + "; use --cell-to-point NAME)"));
  }
  std::string build_array = names.front();
  if (!o.cell_to_point.empty()) build_array = l.grid->point_arrays.back().name;
  if (!o.array.empty()) build_array = select_array(l, o.array, "--array");
  ValueFrame vframe;
  auto fit_array = [&](std::string const& name) {
    if (l.grid)
      for (auto& a : l.grid->point_arrays)
        if (a.name == name) return fit_values(a.values);
    return ValueFrame{};
  };
  vframe = fit_array(build_array);
  set_active(l.tets, build_array);
  set_active(l.hexes, build_array);

  double const prepare_ms = ms_since(prepare_t0);

  // Validate and build once per part (geometry + the build array).
  float vlo = std::numeric_limits<float>::infinity(), vhi = -vlo;
  double validate_ms = 0;
  {
    Phase ph(progress, "validating");
    check_part(l.tets, l.tet_file_cells(), o, "tetrahedral part", vlo, vhi);
    check_part(l.hexes, l.hex_file_cells(), o, "hexahedral part", vlo, vhi);
    validate_ms = ph.finish();
  }
  // Smooth isosurface normals: per-vertex gradients of the rendered array.
  // Without a time step that is the build's array, and they are computed
  // on a task of their own while the BVH builds: a pass (two ranges in
  // parallel on large meshes) beside a build that leaves a core idle in
  // its less parallel stretches (fresh
  // processes, median to the written image: component8 iso 175 -> 167 ms,
  // the flange 185 -> 175 ms).
  // The face neighbours gained nothing there: they are parallel throughout.
  std::string const normals = o.central_normals ? "central" : o.normals;
  bool const smooth = o.mode == "iso" && normals == "smooth";
  VertexGradients tet_gradients, hex_gradients;
  double gradients_ms = 0;
  auto build_gradients = [&] {
    auto const t0 = Clock::now();
    if (!l.tets.empty()) tet_gradients = build_vertex_gradients(l.tets);
    if (!l.hexes.empty()) hex_gradients = build_vertex_gradients(l.hexes);
    gradients_ms = ms_since(t0);
  };
  bool const gradients_beside_build = smooth && o.time_step < 0;
  MinMaxBvh tet_bvh, hex_bvh;
  double build_ms = 0;
  {
    Phase ph(progress, "building the BVH over " + std::to_string(l.cells()) + " cells" +
                           (gradients_beside_build ? " and vertex gradients" : ""));
    tbb::task_group beside;
    if (gradients_beside_build) beside.run(build_gradients);
    if (!l.tets.empty()) tet_bvh = build_minmax_bvh(l.tets, bo);
    if (!l.hexes.empty()) hex_bvh = build_minmax_bvh(l.hexes, bo);
    beside.wait();
    build_ms = ph.finish();
  }
  if (o.verbose) {
    if (!l.tets.empty()) std::cerr << "cellray-render: tet BVH: " << bvh_stats(tet_bvh) << "\n";
    if (!l.hexes.empty()) std::cerr << "cellray-render: hex BVH: " << bvh_stats(hex_bvh) << "\n";
  }

  // A time step: another array over the same geometry, ranges refit.
  std::string array = build_array;
  ValueRanges tet_ranges, hex_ranges;
  bool refit = false;
  double refit_ms = 0;
  if (o.time_step >= 0) {
    if (size_t(o.time_step) >= names.size())
      throw UsageError("--time-step " + std::to_string(o.time_step) + ": " + l.name + " has " +
                       std::to_string(names.size()) + " point arrays (" + list_names(names) + "), steps 0 to " +
                       std::to_string(names.size() - 1));
    array = names[size_t(o.time_step)];
    if (array != build_array) vframe = fit_array(array);
    set_active(l.tets, array);
    set_active(l.hexes, array);
    vlo = std::numeric_limits<float>::infinity();
    vhi = -vlo;
    check_part(l.tets, l.tet_file_cells(), o, "tetrahedral part", vlo, vhi);
    check_part(l.hexes, l.hex_file_cells(), o, "hexahedral part", vlo, vhi);
    auto const t0 = Clock::now();
    if (!l.tets.empty()) refit_ranges(tet_bvh, l.tets, tet_ranges, isa);
    if (!l.hexes.empty()) refit_ranges(hex_bvh, l.hexes, hex_ranges, isa);
    refit_ms = ms_since(t0);
    refit = true;
  }
  if (!(vlo <= vhi))
    throw InvalidMesh(l.name + ": point array '" + array + "' has no finite value: nothing to render");

  // Cell-segment DVR of a tet or a hex mesh (wedges and pyramids included)
  // marches through face neighbours; so does a mixed mesh kept as two
  // parts, across both (link_face_neighbours), and the AO rays of a tet
  // mesh or of a mixed mesh's two parts. A hex mesh's AO rays could march
  // too (the library does it when given neighbours), but gain 2-3% of a
  // frame (boxturb48, the flange, 1 thread) where their neighbours cost
  // more (the flange: 40-90 ms).
  TetNeighbours neighbours;
  HexNeighbours hex_neighbours;
  double neighbours_ms = 0;
  bool const march_dvr = o.mode == "dvr" && o.dvr_mode == "segments" && !o.no_march && !o.reference;
  bool const march_ao = o.mode == "iso" && o.ao > 0 && o.secondary == "march" && !o.reference && !l.tets.empty();
  bool const march = (march_dvr || march_ao) && !l.tets.empty();
  // Hexes march too: their neighbours build at 10-20 M cells/s on 2
  // threads (issue #23), less than one frame gains. Fresh processes,
  // 1024x768, 2 threads, total time through the tree / marching:
  // boxturb48 1.38x, the snappy flange 1.69x, 1M generated hexes 1.50x;
  // can.vtu's 4.8k shell hexes 0.83-0.88x, the only loss seen
  // (docs/cli.md). --march is kept, a no-op.
  bool const hex_march = (march_dvr || march_ao) && !l.hexes.empty();
  if (march && hex_march) {
    Phase ph(progress, "finding face neighbours of " + std::to_string(l.tets.cell_count()) + " tets and " +
                           std::to_string(l.hexes.cell_count()) + " hexahedra");
    neighbours = build_tet_neighbours(l.tets);
    hex_neighbours = build_hex_neighbours(l.hexes);
    link_face_neighbours(l.tets, neighbours, l.hexes, hex_neighbours);
    neighbours_ms = ph.finish();
  } else if (march) {
    Phase ph(progress, "finding face neighbours of " + std::to_string(l.tets.cell_count()) + " tets");
    neighbours = build_tet_neighbours(l.tets);
    neighbours_ms = ph.finish();
  } else if (hex_march) {
    Phase ph(progress, "finding face neighbours of " + std::to_string(l.hexes.cell_count()) + " hexahedra");
    hex_neighbours = build_hex_neighbours(l.hexes);
    neighbours_ms = ph.finish();
  }
  if (smooth && !gradients_beside_build) {  // a time step's array
    Phase ph(progress, "vertex gradients of '" + shown(array) + "'");
    build_gradients();
    ph.finish();
  }
  Scene scene;
  if (!l.tets.empty())
    scene.tets.push_back({l.tets, &tet_bvh, refit ? &tet_ranges : nullptr, march ? &neighbours : nullptr,
                          smooth ? &tet_gradients : nullptr});
  if (!l.hexes.empty())
    scene.hexes.push_back({l.hexes, &hex_bvh, refit ? &hex_ranges : nullptr, smooth ? &hex_gradients : nullptr,
                           hex_march ? &hex_neighbours : nullptr});

  // Camera: the default view puts the eye where the bounds' 8 projected
  // corners span 90% (x --zoom) of the image's shorter side, then what was
  // given applies. An orbit keeps one distance, the largest such fit over
  // its views: no frame is cut and the mesh keeps its size.
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  // The default scene's blobs sit well inside its cube: frame the middle.
  float const framing = o.mesh_path.empty() ? 0.75f : 1.f;
  glm::vec3 const centre = 0.5f * (lo + hi);
  glm::dvec3 const fit_lo(centre + framing * (lo - centre)), fit_hi(centre + framing * (hi - centre));
  int const views = std::max(o.orbit, 1);
  double fit = 0.0;
  int const fits = std::min(views, 720);  // past 720 views, every half degree (about 0.3 ms a fit)
  for (int k = 0; k < fits; ++k)
    fit = std::max(fit, cellray_render::fit_distance(
                            fit_lo, fit_hi, cellray_render::view_direction(o.azimuth + 360.0 * k / fits, o.elevation),
                            0.9 * o.zoom, o.fov, width, height));
  auto fitted_camera = [&](int k) {
    return cellray_render::box_camera(fit_lo, fit_hi,
                                      cellray_render::view_direction(o.azimuth + 360.0 * k / views, o.elevation), fit,
                                      o.fov, width, height);
  };
  Camera cam = fitted_camera(0);
  bool const custom = eye || at || up;
  glm::vec3 const cam_up = up.value_or(glm::vec3(0.f, 1.f, 0.f));
  glm::vec3 const cam_at = at ? frame.point(*at) : centre;
  if (custom) cam = Camera::look_at(eye ? frame.point(*eye) : cam.eye, cam_at, cam_up, o.fov, width, height);
  // The k-th view of an orbit: the default view turned by 360 k / N degrees
  // about +y through the bounds' centre (and centred again), or a given
  // eye, look-at point and up turned likewise; view 0 is `cam` itself.
  auto view_camera = [&](int k) {
    if (k == 0) return cam;
    if (!custom) return fitted_camera(k);
    double const deg = 360.0 * k / views;
    return Camera::look_at(cellray_render::turn_about_y(cam.eye, centre, deg),
                           cellray_render::turn_about_y(cam_at, centre, deg),
                           cellray_render::turn_about_y(cam_up, glm::vec3(0.f), deg), o.fov, width, height);
  };
  float const diagonal = glm::length(hi - lo);

  RenderOptions ro;
  ro.isa = isa;
  ro.traversal = traversal;
  ro.secondary_query = o.secondary == "nearest"     ? SecondaryQuery::nearest
                       : o.secondary == "occlusion" ? SecondaryQuery::occlusion
                       : o.secondary == "sorted"    ? SecondaryQuery::sorted
                       : o.secondary == "march"     ? SecondaryQuery::march
                                                    : SecondaryQuery::grouped;

  IsoParams ip;
  DvrParams dp;
  if (o.mode == "iso") {
    if (isovalues.empty() && o.mesh_path.empty())
      isovalues = {0.3f, 0.45f, 0.6f};  // nested, none cut by the cube (analytic_field)
    else if (isovalues.empty())
      for (double t : {0.25, 0.5, 0.75}) isovalues.push_back(float(vlo + t * (double(vhi) - vlo)));  // no overflow
    else
      for (float& v : isovalues) v = vframe.to_render(v);
    if (vlo == vhi)
      std::cerr << "cellray-render: warning: point array '" << shown(array) << "' is constant ("
                << vframe.to_data(vlo) << "): it has no isosurface\n";
    else
      for (float v : isovalues)
        if (!(v >= vlo && v <= vhi))
          std::cerr << "cellray-render: warning: isovalue " << vframe.to_data(v) << " lies outside the values of '"
                    << shown(array) << "' [" << vframe.to_data(vlo) << ", " << vframe.to_data(vhi)
                    << "]: it draws nothing\n";
    if (!iso_opacity.empty() && iso_opacity.size() != 1 && iso_opacity.size() != isovalues.size())
      throw UsageError("--iso-opacity: give one opacity or one per isovalue (" + std::to_string(isovalues.size()) + ")");
    for (size_t i = 0; i < isovalues.size(); ++i) {
      IsoSurface s;
      s.value = isovalues[i];
      s.color = iso_color(i);
      s.opacity = iso_opacity.empty()       ? (i + 1 == isovalues.size() ? 1.f : 0.4f)
                  : iso_opacity.size() == 1 ? iso_opacity[0]
                                            : iso_opacity[i];
      ip.surfaces.push_back(s);
    }
    if (o.neubauer > 0) {
      ip.roots.method = CellIsoMethod::neubauer;
      ip.roots.neubauer_steps = o.neubauer;
    }
    ip.normals = normals == "central" ? GradientMethod::central
                 : normals == "flat"  ? GradientMethod::analytic
                                      : GradientMethod::smooth;
    if (!o.color_by.empty()) {
      ip.color_by.array = select_array(l, o.color_by, "--color-by");
      float clo = std::numeric_limits<float>::infinity(), chi = -clo;
      for (auto const& a : l.arrays())
        if (a.name == ip.color_by.array)
          for (uint64_t v = 0; v < a.values.size; ++v)
            if (std::isfinite(a.values.data[v])) clo = std::min(clo, a.values.data[v]), chi = std::max(chi, a.values.data[v]);
      if (!(clo <= chi)) throw InvalidMesh(l.name + ": point array '" + shown(o.color_by) + "' has no finite value to colour by");
      ip.color_by.colors = transfer_function_preset(o.color_map, clo, chi);
    }
    ip.clip = clip;
    if (o.clip_caps) {
      if (clip.planes.empty()) throw UsageError("--clip-caps: give --clip or --clip-box");
      ip.clip.caps = true;
      ip.clip.cap_colors = transfer_function_preset(o.color_map, vlo, vhi);
    }
    ip.shadows = o.shadows;  // the light follows each view (below)
    ip.ao_samples = o.ao;
    if (background) ip.background = *background;
  } else {
    float const max_alpha = o.opacity >= 0.f ? o.opacity : 0.8f;
    if (vlo == vhi)
      std::cerr << "cellray-render: warning: point array '" << shown(array) << "' is constant ("
                << vframe.to_data(vlo) << "): the volume is one uniform colour\n";
    if (tf_file) {
      dp.tf = read_paraview_tf(o.tf, vlo, vhi, max_alpha, o.opacity >= 0.f ? o.opacity : 1.f, o.tf_file_range);
      if (o.tf_file_range && vframe.moved) {
        for (float& v : dp.tf.values) v = vframe.to_render(v);
        try {
          dp.tf.check();
        } catch (InvalidArgument const& e) {
          throw IoError(o.tf + ": " + e.what() + " (in the scaled value range of '" + shown(array) + "')");
        }
      }
    } else {
      dp.tf = transfer_function_preset(o.tf, vlo, vhi, max_alpha);
      // The presets hide the lower two thirds of the range, which leaves
      // little of most real fields; ParaView's default linear ramp shows the
      // structure. Exact: the knots include both ends, alpha is linear between.
      double const span = vhi > vlo ? double(vhi) - vlo : 1.0;
      for (size_t i = 0; i < dp.tf.values.size(); ++i)
        dp.tf.rgba[i].a = max_alpha * float(std::clamp((dp.tf.values[i] - double(vlo)) / span, 0.0, 1.0));
    }
    // Opacity accumulates per unit distance: a tenth of the diagonal keeps a
    // mesh's look independent of its units.
    dp.tf.unit_distance = o.unit_distance > 0.f ? frame.length(o.unit_distance) : std::max(diagonal / 10.f, 1e-30f);
    dp.step = frame.length(o.step);
    dp.group_size = o.group_size;
    dp.mode = o.dvr_mode == "segments" ? DvrMode::segments : DvrMode::samples;
    dp.empty_space_skipping = !o.no_skip;
    dp.shading.enabled = o.dvr_shading;
    // Volumes read best on a dark background (ParaView's choice too).
    dp.background = background.value_or(glm::vec4(0.08f, 0.08f, 0.1f, 1.f));
    dp.clip = clip;
  }

  // The legend shows what this render maps values to, in the file's units.
  cellray_render::Legend legend;
  legend.name = array;
  if (o.mode == "iso" && !ip.color_by.array.empty()) {
    // Coloured by another array: the legend is that array's colour map.
    legend.background = ip.background;
    legend.name = ip.color_by.array;
    TransferFunction const& cm = ip.color_by.colors;
    double const clo = cm.values.front(), chi = cm.values.back();
    legend.lo = clo, legend.hi = chi;
    for (int i = 0; i < 256; ++i) legend.ramp.push_back(glm::vec3(cm(float(clo + (chi - clo) * i / 255.0))));
  } else if (o.mode == "iso") {
    legend.background = ip.background;
    legend.lo = vframe.to_data(vlo);
    legend.hi = vframe.to_data(vhi);
    for (auto const& s : ip.surfaces) legend.swatches.push_back({vframe.to_data(s.value), s.color});
  } else {
    legend.background = dp.background;
    double const tlo = dp.tf.values.front(), thi = dp.tf.values.back();  // the map's range (--tf-file-range)
    legend.lo = vframe.to_data(float(tlo));
    legend.hi = vframe.to_data(float(thi));
    for (int i = 0; i < 256; ++i) legend.ramp.push_back(glm::vec3(dp.tf(float(tlo + (thi - tlo) * i / 255.0))));
  }

  // Render: each view --frames times (an orbit: N views once each), one after
  // another; every render already uses all cores.
  Image image;
  std::vector<double> times;
  double write_ms = 0;
  for (int v = 0; v < views; ++v) {
    Camera const view = view_camera(v);
    // A light at the eye casts no visible shadow: with --shadows the light
    // comes from above the camera's left shoulder (shading and shadows).
    if (o.shadows) ip.light_dir = glm::normalize(0.8f * view.up - 0.5f * view.right - 0.4f * view.forward);
    {
      Phase ph(progress, "rendering " + std::to_string(width) + "x" + std::to_string(height) +
                             (o.frames > 1 ? " " + std::to_string(o.frames) + " times" : std::string()) +
                             (o.orbit > 0 ? ", view " + std::to_string(v + 1) + " of " + std::to_string(views)
                                          : std::string()));
      try {
        for (int f = 0; f < o.frames; ++f) {
          auto const t0 = Clock::now();
          if (o.reference)
            image = o.mode == "iso" ? render_iso_reference(scene, view, ip) : render_dvr_reference(scene, view, dp);
          else
            image = o.mode == "iso" ? render_iso(scene, view, ip, ro) : render_dvr(scene, view, dp, ro);
          times.push_back(ms_since(t0));
        }
      } catch (std::bad_alloc const&) {
        throw Error("out of memory rendering " + std::to_string(width) + "x" + std::to_string(height) + " (" +
                    gib(16.0 * double(width) * double(height)) + " for the float image alone; try a smaller --size)");
      }
    }
    if (image.width != width || image.height != height)
      throw Error("the renderer returned a " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                  " image for " + std::to_string(width) + "x" + std::to_string(height));
    if (o.legend) cellray_render::draw_legend(image, *font, legend);
    if (!o.title.empty()) cellray_render::draw_title(image, *font, o.title, legend.background);
    std::string const path = o.orbit > 0 ? orbit_path(o.out, v, o.orbit) : o.out;
    auto const write_t0 = Clock::now();
    write_image(path, image);
    write_ms += ms_since(write_t0);
    if (progress) std::cerr << "cellray-render: wrote " << path << "\n";
  }

  if (o.stats) {
    double const render_ms = median(times);
    uint64_t const bvh_bytes = tet_bvh.memory_bytes() * !l.tets.empty() + hex_bvh.memory_bytes() * !l.hexes.empty();
    nlohmann::ordered_json j;
    j["file"] = o.mesh_path.empty() ? std::string() : o.mesh_path;
    j["mode"] = o.mode;
    if (o.mode == "dvr") {
      j["dvr_mode"] = o.dvr_mode;
      j["dvr_step"] = frame.world_length(dp.step > 0.f ? dp.step : default_dvr_step(dp.mode, diagonal));
      j["dvr_shading"] = o.dvr_shading;
    }
    j["array"] = array;
    j["cells"] = l.cells();
    j["vertices"] = l.vertices();
    j["cell_type"] = l.cell_type();
    if (l.tets_as_hexes) j["tets_as_hexes"] = l.tets_as_hexes;  // a mixed mesh folded into one part
    if (l.grid) {  // the file's cells by VTK type name, and the polyhedra split (wedges, pyramids: hexahedra)
      nlohmann::ordered_json by_type = nlohmann::ordered_json::object();
      for (auto const& [type, count] : l.grid->report.cells_read) by_type[vtk_cell_type_name(type)] = count;
      j["file_cells"] = by_type;
      if (l.grid->report.polyhedra_split) {
        j["polyhedra_split"] = l.grid->report.polyhedra_split;
        j["polyhedron_tets"] = l.grid->report.polyhedron_tets;
        j["polyhedron_pyramids"] = l.grid->report.polyhedron_pyramids;
      }
    }
    j["renderer"] = o.reference ? "reference" : "fast";
    j["isa"] = isa_name(isa);
    j["traversal"] = traversal_name(traversal);
    j["threads"] = threads;
    j["width"] = width;
    j["height"] = height;
    j["secondary"] = secondary_query_name(ro.secondary_query);
    j["load_ms"] = load_ms;
    j["prepare_ms"] = prepare_ms;
    j["validate_ms"] = validate_ms;
    j["builder"] = builder_name(bo.builder);
    j["leaf_size"] = o.leaf_size;
    j["build_ms"] = build_ms;
    j["refit_ms"] = refit_ms;
    j["neighbours_ms"] = neighbours_ms;
    j["neighbours_bytes"] = neighbours.memory_bytes() + hex_neighbours.memory_bytes();
    if (o.mode == "iso") j["normals"] = normals;
    j["gradients_ms"] = gradients_ms;
    j["gradients_bytes"] = tet_gradients.memory_bytes() + hex_gradients.memory_bytes();
    if (gradients_beside_build) j["gradients_beside_build"] = true;  // inside build_ms's wall time
    j["clip_planes"] = clip.planes.size();
    j["bvh_nodes"] = tet_bvh.node_count() * !l.tets.empty() + hex_bvh.node_count() * !l.hexes.empty();
    j["bvh_bytes"] = bvh_bytes;
    j["bvh_bytes_per_cell"] = double(bvh_bytes) / double(l.cells());
    j["frames"] = o.frames;
    if (o.orbit > 0) j["orbit"] = o.orbit;
    j["render_ms"] = render_ms;
    j["render_ms_min"] = *std::min_element(times.begin(), times.end());
    j["render_ms_first"] = times.front();
    j["write_ms"] = write_ms;
    // From before main() (static initialisation) to the image on disk: what
    // a user waits for, less the loader's start-up (a few ms).
    j["total_ms"] = ms_since(process_start);
    j["mrays_per_s"] = double(width) * double(height) / (render_ms * 1e-3) / 1e6;
    j["peak_rss_mb"] = peak_rss_mb();
    std::cout << j.dump() << std::endl;
  }
  return exit_ok;
}

void report_error(std::string const& msg) { std::cerr << "cellray-render: error: " << one_line(msg) << "\n"; }

}  // namespace

int main(int argc, char** argv) {
  // Past a file-size limit, write() then fails with EFBIG and the image
  // writer reports it (exit 3, the old file kept) instead of the process
  // dying half-way through a file.
  std::signal(SIGXFSZ, SIG_IGN);
#if defined(__GLIBC__)
  // Keep freed memory for reuse instead of returning it to the system: the
  // BVH build's 32-byte-a-cell boxes, freed after the build, then hold the
  // nodes, gradients and image. A fresh page costs ~15 us on the VMs of
  // PROFILE.md; glibc otherwise unmaps every block over 128 KB to 32 MB.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
#endif
  CLI::App app{
      "cellray-render: ray traces isosurfaces or a volume (DVR) of an unstructured mesh (tetrahedra, pyramids,\n"
      "wedges, hexahedra, polyhedra) from legacy .vtk, .vtu, .pvtu, gmsh .msh or Exodus II .ex2/.exo/.e to PNG\n"
      "or PPM; without a mesh, renders a generated scene."};
  app.footer(exit_code_help);
  Options o;
  add_options(app, o);
  try {
    app.parse(argc, argv);
  } catch (CLI::CallForHelp const& e) {
    return app.exit(e);
  } catch (CLI::CallForAllHelp const& e) {
    return app.exit(e);
  } catch (CLI::ParseError const& e) {
    report_error(std::string(e.what()) + " (see --help)");
    return exit_usage;
  }
  try {
    return run(o);
  } catch (UsageError const& e) {
    report_error(e.what());
    return exit_usage;
  } catch (InvalidArgument const& e) {
    report_error(e.what());
    return exit_usage;
  } catch (IoError const& e) {
    report_error(e.what());
    return exit_io;
  } catch (std::filesystem::filesystem_error const& e) {
    report_error(e.what());
    return exit_io;
  } catch (InvalidMesh const& e) {
    report_error(e.what());
    return exit_invalid_mesh;
  } catch (std::bad_alloc const&) {
    report_error("out of memory" + (current_phase.empty() ? std::string() : " while " + current_phase));
    return exit_other;
  } catch (std::exception const& e) {
    report_error(e.what());
    return exit_other;
  }
}
