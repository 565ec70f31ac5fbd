// The performance targets of issue #9 in one run, printed as a table of
// target, measured value and ratio (not a Google Benchmark: each figure is
// the median of several whole frames, as cellray-render --frames reports).
//
//   ./build/bench/bench_targets            (about 10 minutes on 2 cores)
//   ./build/bench/bench_targets --quick    (128x128 frames, no 5M mesh: a smoke run)
//   ./build/bench/bench_targets --secondary [--rounds N]   (only the shadow + AO line, ~40 s)
//
// Every frame is 1024x1024, one sample per pixel, camera fitted to the mesh
// bounds (fit_camera), as the issue asks. "Per core" figures run TBB with one
// thread. DVR uses the cool-warm preset (opacity over the top third of the
// value range, unit distance = diagonal / 10, as cellray-render) at the
// largest step whose image is within 1/255 RMSE of the reference renderer
// (checked on a 128x128 frame), for point samples (the step is the sample
// spacing) and cell segments (the step is the longest integration piece;
// they march through the mesh's face neighbours, and are timed through the
// tree alone too).
// The shadow + AO line times the secondary rays alone, as differences of
// frames with and without them in interleaved rounds (secondary_rounds).
//
// Issue #23's workloads, beside the rows above: isosurfaces at its fitted
// view (eye = bounds centre + 1.8 x diagonal x normalize(0.6, 0.45, 0.66),
// fov 30) and DVR at its representative transfer function, whose opacity
// lies where the data is (representative_dvr_params).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <tbb/global_control.h>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/vertex_gradients.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/reference.hpp>
#include <cellray/render/render.hpp>

#include "bench_data.hpp"

using namespace cellray;

namespace {

struct Options {
  int size = 1024;      ///< frame side, pixels
  int check_size = 128;  ///< frame side of the accuracy check against the reference
  int frames = 3;
  int rounds = 9;  ///< rounds of the secondary-ray variants (secondary_rounds)
  bool large = true;  ///< include the generated 5M-tet mesh
  bool secondary_only = false;  ///< --secondary: only the shadow + AO line
};

/// One mesh of the targets with its tree and what to show.
struct Subject {
  std::string name;
  GeneratedMesh<4> generated;
  std::unique_ptr<UnstructuredGrid> grid;
  TetMesh tets;
  HexMesh hexes;
  bool hex = false;
  MinMaxBvh bvh;
  TetNeighbours neighbours;  ///< tets: DVR segments march through them
  HexNeighbours hex_neighbours;  ///< hexes: the same
  double neighbours_ms = 0;
  float iso = 0.f;
  float vmin = 0.f, vmax = 0.f;
  VertexGradients gradients;  ///< smooth isosurface normals, cellray-render's default

  Scene scene() const { return hex ? Scene(hexes, bvh) : Scene(tets, bvh); }
  Scene scene_with_gradients() const {
    Scene sc = scene();
    if (hex) sc.hexes[0].gradients = &gradients;
    else sc.tets[0].gradients = &gradients;
    return sc;
  }
  /// With the face neighbours: DVR segments (and a tet mesh's AO rays) march.
  Scene scene_with_neighbours() const {
    return hex ? Scene(hexes, bvh, nullptr, &hex_neighbours) : Scene(tets, bvh, nullptr, &neighbours);
  }
  uint64_t cells() const { return hex ? hexes.cell_count() : tets.cell_count(); }
};

template <class MeshT> void value_range(MeshT const& m, float& lo, float& hi) {
  lo = INFINITY, hi = -INFINITY;
  for (uint64_t i = 0; i < m.vertex_count(); ++i)
    if (float const v = m.values()[i]; std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
}

std::unique_ptr<Subject> load(std::string const& name) {
  auto s = std::make_unique<Subject>();
  s->name = name;
  if (name == "component8_608k") {
    s->grid = std::make_unique<UnstructuredGrid>(read_mesh(bench::data_file("openfoam/component8_heat_608k.vtk")));
    s->tets = s->grid->tet_mesh().with_array("T");
    s->iso = 423.f;
  } else if (name == "boxturb48_dns") {
    s->grid = std::make_unique<UnstructuredGrid>(read_mesh(bench::data_file("openfoam/boxturb48_dns.vtk")));
    s->hexes = s->grid->hex_mesh().with_array("enstrophy");
    s->hex = true;
    s->iso = 0.1f;
  } else {  // gen_tets_<cells>
    s->generated = generate_tets(std::stoull(name.substr(9)));
    s->tets = s->generated.mesh();
    s->iso = 0.45f;
  }
  s->bvh = s->hex ? build_minmax_bvh(s->hexes) : build_minmax_bvh(s->tets);
  auto const t0 = std::chrono::steady_clock::now();
  if (s->hex) s->hex_neighbours = build_hex_neighbours(s->hexes);
  else s->neighbours = build_tet_neighbours(s->tets);
  s->neighbours_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (s->hex) value_range(s->hexes, s->vmin, s->vmax);
  else value_range(s->tets, s->vmin, s->vmax);
  s->gradients = s->hex ? build_vertex_gradients(s->hexes) : build_vertex_gradients(s->tets);
  return s;
}

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

/// Median time of `frames` calls, seconds, on `threads` TBB threads: the
/// process's CPU time for one thread (a figure per core that other work on a
/// shared machine inflates less), wall time for more or when `wall`
/// (thread scaling compares wall times).
double median_seconds(int frames, int threads, std::function<void()> const& f, bool wall = false) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(threads));
  f();  // warm caches and TBB's workers
  std::vector<double> t;
  for (int i = 0; i < frames; ++i) {
    if (threads == 1 && !wall) {
      double const a = process_cpu_seconds();
      f();
      t.push_back(process_cpu_seconds() - a);
      continue;
    }
    auto const a = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count());
  }
  std::nth_element(t.begin(), t.begin() + ptrdiff_t(t.size() / 2), t.end());
  return t[t.size() / 2];
}

Camera camera_for(Subject const& s, int size) {
  glm::vec3 lo, hi;
  s.scene().bounds(lo, hi);
  return fit_camera(lo, hi, size, size);
}

IsoParams iso_params(Subject const& s) {
  IsoParams p;
  p.surfaces.push_back({s.iso, glm::vec3(0.85f), 1.f});
  return p;
}

/// Issue #23's view: closer than fit_camera's, so most rays meet the mesh.
Camera fitted_view(Subject const& s, int size) {
  glm::vec3 lo, hi;
  s.scene().bounds(lo, hi);
  glm::vec3 const centre = 0.5f * (lo + hi);
  float const diag = glm::length(hi - lo);
  glm::vec3 const eye = centre + 1.8f * diag * glm::normalize(glm::vec3(0.6f, 0.45f, 0.66f));
  return Camera::look_at(eye, centre, glm::vec3(0.f, 1.f, 0.f), 30.f, size, size);
}

/// Primary-ray isosurface Mrays/s, at fit_camera's view or issue #23's.
/// `smooth`: smooth normals from vertex gradients, as cellray-render draws
/// by default (else the hit cell's analytic gradient).
double iso_mrays(Subject const& s, Options const& o, int threads, Isa isa, Traversal how, bool wall = false,
                 bool issue23_view = false, bool smooth = false) {
  Scene const scene = smooth ? s.scene_with_gradients() : s.scene();
  Camera const cam = issue23_view ? fitted_view(s, o.size) : camera_for(s, o.size);
  IsoParams p = iso_params(s);
  if (smooth) p.normals = GradientMethod::smooth;
  RenderOptions ro;
  ro.isa = isa;
  ro.traversal = how;
  double const t = median_seconds(o.frames, threads, [&] { render_iso(scene, cam, p, ro); }, wall);
  return double(o.size) * double(o.size) / t * 1e-6;
}

DvrParams dvr_params(Subject const& s) {
  glm::vec3 lo, hi;
  s.scene().bounds(lo, hi);
  DvrParams p;
  p.tf = transfer_function_preset("cool-warm", s.vmin, s.vmax);
  p.tf.unit_distance = glm::length(hi - lo) / 10.f;
  return p;
}

/// Issue #23's representative transfer function: cool-warm colours over the
/// data range, opacity a trapezoid over [iso, iso + range / 3] (component8: T
/// in [423, 523], boxturb48: enstrophy in [0.1, 0.34]) rising from 0 to 0.3
/// over its first quarter and falling back over its last, unit distance =
/// diagonal / 35.
DvrParams representative_dvr_params(Subject const& s) {
  glm::vec3 lo, hi;
  s.scene().bounds(lo, hi);
  DvrParams p;
  TransferFunction const colours = transfer_function_preset("cool-warm", s.vmin, s.vmax);
  float const a = s.iso, w = (s.vmax - s.vmin) / 3.f;
  std::vector<float> const at = {s.vmin, a, a + w / 4.f, a + 3.f * w / 4.f, a + w, s.vmax};
  std::vector<float> const alpha = {0.f, 0.f, 0.3f, 0.3f, 0.f, 0.f};
  for (size_t i = 0; i < at.size(); ++i) {
    if (!p.tf.values.empty() && !(at[i] > p.tf.values.back())) continue;  // iso at an end of the range
    glm::vec4 c = colours(at[i]);
    c.a = alpha[i];
    p.tf.values.push_back(at[i]);
    p.tf.rgba.push_back(c);
  }
  p.tf.unit_distance = glm::length(hi - lo) / 35.f;
  return p;
}

struct DvrResult {
  std::string mode;
  float step = 0.f;  ///< 0 for segments
  double rmse = 0, mrays = 0;
};

/// The fastest DVR configuration within 1/255 RMSE of the reference.
/// Segments march through face neighbours; the tree-only segments are timed
/// too at the same step, for the ratio.
DvrResult best_dvr(Subject const& s, Options const& o, DvrParams p, char const* what) {
  Scene const scene = s.scene_with_neighbours(), tree_only = s.scene();
  Camera const check_cam = camera_for(s, o.check_size), cam = camera_for(s, o.size);
  Image const reference = render_dvr_reference(scene, check_cam, p);
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  float const diag = glm::length(hi - lo);
  std::vector<DvrResult> ok;
  auto mrays = [&](Scene const& sc) {
    double const t = median_seconds(o.frames, 1, [&] { render_dvr(sc, cam, p); });
    return double(o.size) * double(o.size) / t * 1e-6;
  };
  for (DvrMode mode : {DvrMode::segments, DvrMode::samples}) {
    p.mode = mode;
    for (float div : {25.f, 50.f, 100.f, 200.f, 400.f, 800.f, 1600.f, 3200.f}) {
      p.step = diag / div;
      double const rmse = compare_images(render_dvr(scene, check_cam, p), reference).rmse;
      if (rmse <= 1.0) {
        bool const march = mode == DvrMode::segments;
        ok.push_back({march ? "segments, march" : mode == DvrMode::segments ? "segments" : "samples", p.step, rmse,
                      mrays(scene)});
        if (march) ok.push_back({"segments, tree only", p.step, rmse, mrays(tree_only)});
        break;
      }
    }
  }
  for (auto const& c : ok)
    std::printf("DVR candidate %s, %s: %s, step %.3g, RMSE %.3f/255, %.3f Mrays/s\n", s.name.c_str(), what,
                c.mode.c_str(), c.step, c.rmse, c.mrays);
  std::printf("DVR %s: face neighbours built in %.0f ms, %.1f MB\n", s.name.c_str(), s.neighbours_ms,
              double(s.neighbours.memory_bytes() + s.hex_neighbours.memory_bytes()) / 1e6);
  if (ok.empty()) return {"none within 1/255", 0.f, -1, 0};
  return *std::max_element(ok.begin(), ok.end(), [](auto const& a, auto const& b) { return a.mrays < b.mrays; });
}

/// The secondary rays of the targets: hard shadows from the light
/// cellray-render --shadows uses (above the camera's left shoulder, behind
/// the viewer: not the headlight, whose shadow rays retrace the camera rays
/// and are as coherent as they), plus 4 AO rays per hit.
IsoParams lit_params(Subject const& s, Camera const& cam) {
  IsoParams p = iso_params(s);
  p.shadows = true;
  p.ao_samples = 4;
  p.light_dir = glm::normalize(0.8f * cam.up - 0.5f * cam.right - 0.4f * cam.forward);
  return p;
}

/// Process CPU time of one call, seconds.
double cpu_seconds(std::function<void()> const& f) {
  double const a = process_cpu_seconds();
  f();
  return process_cpu_seconds() - a;
}

/// Shadow + AO ray time of each of `queries` x `hows` (one TBB thread,
/// process CPU time): per round and variant, a frame without secondary rays
/// and one with them back to back (in alternating order), their difference
/// the variant's secondary time in that round. Rounds visit every variant,
/// so a slow minute of a shared machine hits all of them; `times[v]` gets
/// one difference per round.
void secondary_rounds(Subject const& s, Options const& o, std::vector<std::pair<SecondaryQuery, Traversal>> const& variants,
                      int rounds, std::vector<std::vector<double>>& times) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
  Scene const scene = s.scene_with_neighbours();  // with the face neighbours: `march` uses them, the others not
  Camera const cam = camera_for(s, o.size / 2);
  IsoParams const plain = iso_params(s), lit = lit_params(s, cam);
  times.assign(variants.size(), {});
  std::vector<RenderOptions> ro(variants.size());
  for (size_t v = 0; v < variants.size(); ++v) {
    ro[v].secondary_query = variants[v].first;
    ro[v].secondary_traversal = variants[v].second;
    render_iso(scene, cam, lit, ro[v]);  // warm caches
  }
  for (int round = 0; round < rounds; ++round)
    for (size_t v = 0; v < variants.size(); ++v) {
      double const a = cpu_seconds([&] { render_iso(scene, cam, round % 2 ? plain : lit, ro[v]); });
      double const b = cpu_seconds([&] { render_iso(scene, cam, round % 2 ? lit : plain, ro[v]); });
      times[v].push_back(std::max(round % 2 ? b - a : a - b, 1e-9));
    }
}

double median_of(std::vector<double> t) {
  std::nth_element(t.begin(), t.begin() + ptrdiff_t(t.size() / 2), t.end());
  return t[t.size() / 2];
}

/// One configuration of a scaling line: ISA and TBB threads.
struct ScalingVariant {
  Isa isa;
  int threads;
};

/// Speed of each variant over the first one (component8 iso primary rays,
/// packet traversal): per round, one frame of every variant back to back,
/// the ratio first-time / variant-time within the round, then the median
/// over 2 * frames + 1 rounds, so the machine's drift between rounds
/// cancels. Process CPU time, or wall time when `wall` (thread scaling).
std::vector<double> scaling_ratios(Subject const& s, Options const& o, std::vector<ScalingVariant> const& variants,
                                   bool wall) {
  Scene const scene = s.scene();
  Camera const cam = camera_for(s, o.size);
  IsoParams const p = iso_params(s);
  auto frame = [&](ScalingVariant const& v) {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(v.threads));
    RenderOptions ro;
    ro.isa = v.isa;
    ro.traversal = Traversal::packet;
    render_iso(scene, cam, p, ro);  // warm caches and TBB's workers
    if (!wall) return cpu_seconds([&] { render_iso(scene, cam, p, ro); });
    auto const a = std::chrono::steady_clock::now();
    render_iso(scene, cam, p, ro);
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
  };
  std::vector<std::vector<double>> ratio(variants.size());
  for (int round = 0; round < 2 * o.frames + 1; ++round) {
    std::vector<double> t;
    for (ScalingVariant const& v : variants) t.push_back(frame(v));
    for (size_t v = 0; v < variants.size(); ++v) ratio[v].push_back(t[0] / t[v]);
  }
  std::vector<double> out;
  for (auto const& r : ratio) out.push_back(median_of(r));
  return out;
}

struct Row {
  std::string target, measured_as;
  double measured, goal;
  bool higher_is_better = true;
};

void print(std::vector<Row> const& rows) {
  std::printf("\n| target | measured | goal | ratio | |\n|---|---:|---:|---:|---|\n");
  for (auto const& r : rows) {
    double const ratio = r.higher_is_better ? r.measured / r.goal : r.goal / r.measured;
    std::printf("| %s | %.2f %s | %.2f | %.2f | %s |\n", r.target.c_str(), r.measured, r.measured_as.c_str(), r.goal,
                ratio, ratio >= 1.0 ? "met" : "**missed**");
  }
  std::fflush(stdout);
}

/// The shadow + AO line: every variant's secondary time (median over the
/// rounds, [fastest, slowest]) and the best variant against "packet": the
/// nearest-hit query (SecondaryQuery::nearest) with packet traversal, one
/// pixel block's W shadow rays, or one AO sample of its W hits, per packet,
/// in pixel order: the first-hit traversal of the primary rays, and the
/// renderer's default up to session 4. The ratio is the median over rounds
/// of (packet / variant) within one round, so the machine's drift between
/// rounds cancels; [lo, hi] is its spread over the rounds.
Row secondary_row(Subject const& s, Options const& o) {
  struct Variant {
    char const* name;
    SecondaryQuery query;
    Traversal how;
  };
  // The default (grouped) right after packet: their per-round ratio spans
  // the shortest time.
  Variant const variants[] = {{"packet", SecondaryQuery::nearest, Traversal::packet},
                              {"grouped", SecondaryQuery::grouped, Traversal::packet},
                              {"march", SecondaryQuery::march, Traversal::packet},
                              {"sorted", SecondaryQuery::sorted, Traversal::packet},
                              {"occlusion", SecondaryQuery::occlusion, Traversal::packet},
                              {"spmd", SecondaryQuery::nearest, Traversal::spmd},
                              {"hybrid", SecondaryQuery::nearest, Traversal::hybrid}};
  std::vector<std::pair<SecondaryQuery, Traversal>> pairs;
  for (Variant const& v : variants) pairs.push_back({v.query, v.how});
  std::vector<std::vector<double>> times;
  secondary_rounds(s, o, pairs, o.rounds, times);
  std::printf("\nshadow (light above the left shoulder) + 4 AO rays per hit, %s, %dx%d, 1 thread, secondary CPU time, "
              "median of %d rounds [min, max], ratio packet/variant per round:\n",
              s.name.c_str(), o.size / 2, o.size / 2, o.rounds);
  double best = 0;
  std::string best_name;
  for (size_t v = 0; v < pairs.size(); ++v) {
    std::vector<double> ratio;
    for (size_t r = 0; r < times[v].size(); ++r) ratio.push_back(times[0][r] / times[v][r]);
    double const med = median_of(ratio);
    std::printf("  %-9s %6.1f ms [%.1f, %.1f]  x%.3f [%.3f, %.3f]\n", variants[v].name, median_of(times[v]) * 1e3,
                *std::min_element(times[v].begin(), times[v].end()) * 1e3,
                *std::max_element(times[v].begin(), times[v].end()) * 1e3, med,
                *std::min_element(ratio.begin(), ratio.end()), *std::max_element(ratio.begin(), ratio.end()));
    if (v > 0 && med > best) best = med, best_name = variants[v].name;
  }
  std::printf("  (default: %s, %s traversal)\n", secondary_query_name(RenderOptions{}.secondary_query),
              traversal_name(RenderOptions{}.secondary_traversal));
  std::fflush(stdout);
  return {"shadow+AO rays, best variant (" + best_name + ") / packet", "x", best, 1.5};
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) o.size = 128, o.check_size = 64, o.frames = 1, o.rounds = 1, o.large = false;
    else if (!std::strcmp(argv[i], "--secondary")) o.secondary_only = true;
    else if (!std::strcmp(argv[i], "--rounds") && i + 1 < argc) o.rounds = std::max(1, std::atoi(argv[++i]));
    else {
      std::fprintf(stderr, "usage: %s [--quick] [--secondary] [--rounds N]\n", argv[0]);
      return 2;
    }
  }
  int const all = int(std::thread::hardware_concurrency());
  std::printf("# cellray performance targets (issue #9): %dx%d frames, median of %d, %d hardware threads, best ISA %s\n"
              "# 1-thread figures: process CPU time; all-thread figures: wall time\n",
              o.size, o.size, o.frames, all, isa_name(best_isa()));
  std::vector<Row> rows;
  if (o.secondary_only) {
    rows.push_back(secondary_row(*load("component8_608k"), o));
    print(rows);
    return 0;
  }
  std::vector<std::string> names = {"component8_608k", "boxturb48_dns"};
  if (o.large) names.push_back("gen_tets_5000000");

  for (auto const& name : names) {
    std::fprintf(stderr, "loading %s\n", name.c_str());
    auto const s = load(name);
    size_t const first = rows.size();
    double const iso = iso_mrays(*s, o, 1, best_isa(), Traversal::packet);
    rows.push_back({"iso primary, 1 thread, " + name, "Mrays/s", iso, 10.0});
    bool const generated = name.rfind("gen_", 0) == 0;
    if (!generated) {  // issue #23's goals are for the two real meshes
      double const iso23 = iso_mrays(*s, o, 1, best_isa(), Traversal::packet, false, true);
      rows.push_back({"iso primary, 1 thread, #23 fitted view, " + name, "Mrays/s", iso23, s->hex ? 15.0 : 25.0});
      double const smooth23 = iso_mrays(*s, o, 1, best_isa(), Traversal::packet, false, true, true);
      rows.push_back({"iso primary, 1 thread, #23 fitted view, smooth normals (cellray-render's default), " + name,
                      "Mrays/s", smooth23, s->hex ? 15.0 : 25.0});
    }
    auto dvr_row = [&](DvrParams const& p, char const* what, std::string const& label, double goal) {
      DvrResult const d = best_dvr(*s, o, p, what);
      char how[96];
      std::snprintf(how, sizeof how, "Mrays/s (%s, step %.3g, RMSE %.2f/255)", d.mode.c_str(), d.step, d.rmse);
      rows.push_back({label + name, how, d.mrays, goal});
    };
    dvr_row(dvr_params(*s), "cool-warm preset", "DVR, 1 thread, ", 2.0);
    if (!generated)
      dvr_row(representative_dvr_params(*s), "#23 representative TF", "DVR, 1 thread, #23 representative TF, ",
              s->hex ? 3.0 : 5.0);
    print({rows.begin() + ptrdiff_t(first), rows.end()});
  }

  // SIMD and thread scaling of the packet isosurface traversal, as medians
  // of per-round ratios (scaling_ratios): two medians taken minutes apart
  // swung these lines by +-20% on the shared VM.
  auto const c8 = load("component8_608k");
  {
    std::vector<ScalingVariant> isas = {{Isa::sse4_2, 1}};
    if (isa_available(Isa::avx2)) isas.push_back({Isa::avx2, 1});
    if (isa_available(Isa::avx512)) isas.push_back({Isa::avx512, 1});
    std::vector<double> const r = scaling_ratios(*c8, o, isas, false);
    for (size_t v = 1; v < isas.size(); ++v)
      rows.push_back({isas[v].isa == Isa::avx2 ? "AVX2 / SSE4.2, packet iso, component8"
                                               : "AVX-512 / SSE4.2, packet iso, component8",
                      "x", r[v], isas[v].isa == Isa::avx2 ? 1.5 : 2.0});
    std::vector<double> const t = scaling_ratios(*c8, o, {{best_isa(), 1}, {best_isa(), all}}, true);
    rows.push_back({std::to_string(all) + " threads / 1 thread, iso, component8", "x", t[1], 1.8});
  }

  rows.push_back(secondary_row(*c8, o));

  // Time to the first image of a new 1M-cell mesh: build + render vs render.
  {
    auto const gen = generate_tets(1000000);
    TetMesh const m = gen.mesh();
    MinMaxBvh bvh;
    glm::vec3 lo(-1.f), hi(1.f);
    Camera const cam = fit_camera(lo, hi, o.size, o.size);
    IsoParams p;
    p.surfaces.push_back({0.45f, glm::vec3(0.85f), 1.f});
    double const build = median_seconds(o.frames, all, [&] { bvh = build_minmax_bvh(m); });
    Scene const scene(m, bvh);
    double const render = median_seconds(o.frames, all, [&] { render_iso(scene, cam, p); });
    char how[96];
    std::snprintf(how, sizeof how, "x (build %.0f ms, render %.0f ms)", build * 1e3, render * 1e3);
    rows.push_back({"(build + render) / render, 1M tets, all threads", how, (build + render) / render, 3.0, false});
    // The same with the Morton build, as cellray-render builds for one
    // image: its build and a frame on its tree, over the binned SAH tree's
    // frame (a slower frame on the quicker tree is not a gain).
    MinMaxBvh quick;
    BuildOptions morton;
    morton.builder = BvhBuilder::morton;
    double const build_m = median_seconds(o.frames, all, [&] { quick = build_minmax_bvh(m, morton); });
    Scene const quick_scene(m, quick);
    double const render_m = median_seconds(o.frames, all, [&] { render_iso(quick_scene, cam, p); });
    std::snprintf(how, sizeof how, "x (Morton build %.0f ms, render %.0f ms)", build_m * 1e3, render_m * 1e3);
    rows.push_back({"(Morton build + render) / render, 1M tets, all threads", how, (build_m + render_m) / render, 3.0,
                    false});
  }
  print(rows);
  return 0;
}
