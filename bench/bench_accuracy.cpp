// Speed against accuracy of the fast renderer, measured against the
// double-precision reference renderer (render/reference.hpp), and the
// failure-mode report. Not a Google Benchmark: it times whole frames itself
// (median of --frames renders, TBB on every core) like the example's own
// timing report, and writes
//   --csv PATH      one row per (mesh, configuration): Mrays/s, RMSE / max
//                   error in 8-bit units, % pixels off by more than 1/255,
//                   iso hits missed / spurious (% of pixels)
//   --report PATH   docs/failure_modes.md (measured failure rates)
// Run through scripts/accuracy.sh and scripts/failure-report.sh.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include <cellray/bvh/build.hpp>
#include <cellray/cells/queries.hpp>
#include <cellray/cells/reference.hpp>
#include <cellray/cells/vertex_gradients.hpp>
#include <cellray/io/read_mesh.hpp>
#include <cellray/mesh/generate.hpp>
#include <cellray/render/reference.hpp>

#include "bench_data.hpp"

using namespace cellray;

namespace {

/// One mesh of the sweep: owning storage, tree, field range, an isovalue.
struct Subject {
  std::string name;
  std::unique_ptr<UnstructuredGrid> grid;
  std::unique_ptr<GeneratedMesh<4>> gen_tets;
  std::unique_ptr<GeneratedMesh<8>> gen_hexes;
  std::vector<float> values;  // a replaced field, when used
  TetMesh tets;
  HexMesh hexes;
  bool is_hex = false;
  MinMaxBvh bvh;
  float vmin = 0, vmax = 1, iso = 0.5f;

  Scene scene() const { return is_hex ? Scene(hexes, bvh) : Scene(tets, bvh); }
  uint64_t cells() const { return is_hex ? hexes.cell_count() : tets.cell_count(); }
  float diagonal() const {
    glm::vec3 lo, hi;
    scene().bounds(lo, hi);
    return glm::length(hi - lo);
  }
};

template <int N> void finish(Subject& s, CellMesh<N> const& m, float iso_at = 0.5f) {
  if constexpr (N == 4) s.tets = m;
  else s.hexes = m, s.is_hex = true;
  s.bvh = build_minmax_bvh(m);
  s.vmin = std::numeric_limits<float>::infinity(), s.vmax = -s.vmin;
  for (uint64_t v = 0; v < m.vertex_count(); ++v) {
    float const x = m.value(v);
    if (x == x) s.vmin = std::min(s.vmin, x), s.vmax = std::max(s.vmax, x);
  }
  s.iso = s.vmin + iso_at * (s.vmax - s.vmin);
}

std::unique_ptr<Subject> make_subject(std::string const& key) {
  auto s = std::make_unique<Subject>();
  s->name = key;
  auto read = [&](std::string const& rel) {
    s->grid = std::make_unique<UnstructuredGrid>(read_mesh(bench::data_file(rel)));
  };
  if (key == "gen-tets") {
    s->gen_tets = std::make_unique<GeneratedMesh<4>>(generate_tets(100000));
    finish(*s, s->gen_tets->mesh());
    s->iso = 0.3f;
  } else if (key == "gen-hexes") {
    s->gen_hexes = std::make_unique<GeneratedMesh<8>>(generate_hexes(30000));
    finish(*s, s->gen_hexes->mesh());
    s->iso = 0.3f;
  } else if (key == "gen-wedges" || key == "gen-pyramids" || key == "gen-family") {
    // One row per cell type of the hexahedron family (collapsed hexahedra,
    // mesh/vtk_cells.hpp), and the three mixed: about as many cells as
    // gen-tets, for speed per cell type at equal cell counts.
    s->gen_hexes = std::make_unique<GeneratedMesh<8>>(key == "gen-wedges"     ? generate_wedges(105000)
                                                      : key == "gen-pyramids" ? generate_pyramids(105000)
                                                                              : generate_hex_family(70000));
    finish(*s, s->gen_hexes->mesh());
    s->iso = 0.3f;
  } else if (key == "post") {
    read("vtk-data/post.vtk");
    finish(*s, s->grid->tet_mesh(), 0.45f);
  } else if (key == "disk") {
    read("vtk-data/disk_out_ref.vtu");
    finish(*s, s->grid->hex_mesh().with_array("Temp"), 0.5f);
  } else if (key == "component8") {
    read("openfoam/component8_heat_84k.vtk");
    finish(*s, s->grid->tet_mesh().with_array("T"), 0.4f);
  } else if (key == "boxturb") {
    read("openfoam/boxturb48_dns.vtk");
    finish(*s, s->grid->hex_mesh().with_array("enstrophy"), 0.3f);
  } else {
    throw InvalidArgument("unknown mesh '" + key +
                          "' (gen-tets, gen-hexes, gen-wedges, gen-pyramids, gen-family, post, disk, component8, boxturb)");
  }
  return s;
}

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

/// Median seconds of `frames` runs of f (after one warm-up run whose image is kept).
template <class F> double median_seconds(int frames, F const& f) {
  std::vector<double> t;
  for (int i = 0; i < frames; ++i) {
    double const t0 = now();
    f();
    t.push_back(now() - t0);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

/// Isosurface hit masks from renders on a transparent background.
struct HitStats {
  double missed = 0, spurious = 0;  ///< % of pixels
};
HitStats hit_stats(Image const& fast, Image const& ref) {
  uint64_t missed = 0, spurious = 0, n = uint64_t(fast.width) * uint64_t(fast.height);
  for (uint64_t i = 0; i < n; ++i) {
    bool const f = fast.rgba[4 * i + 3] > 0.5f, r = ref.rgba[4 * i + 3] > 0.5f;
    missed += r && !f;
    spurious += f && !r;
  }
  return {100.0 * double(missed) / double(n), 100.0 * double(spurious) / double(n)};
}

char const* isa_key(Isa i) { return i == Isa::sse4_2 ? "sse4" : i == Isa::avx2 ? "avx2" : i == Isa::avx512 ? "avx512" : "scalar"; }

struct Row {
  std::string mode, mesh, config, isa, traversal, roots, normals, dvr_mode;
  uint64_t cells = 0;
  int step_div = 0, group = 0, ess = 0, is_default = 0;
  double mrays = 0, rmse = 0, max = 0, pct_over = 0, missed = 0, spurious = 0;
};

std::string csv_header() {
  return "mode,mesh,cells,config,isa,traversal,roots,normals,step_div,group,dvr_mode,ess,mrays_per_s,rmse_8bit,"
         "max_8bit,pct_over_1,missed_pct,spurious_pct,is_default";
}
std::string csv_row(Row const& r) {
  char b[512];
  std::snprintf(b, sizeof b, "%s,%s,%llu,%s,%s,%s,%s,%s,%d,%d,%s,%d,%.4f,%.5f,%.3f,%.4f,%.4f,%.4f,%d", r.mode.c_str(),
                r.mesh.c_str(), (unsigned long long)r.cells, r.config.c_str(), r.isa.c_str(), r.traversal.c_str(),
                r.roots.c_str(), r.normals.c_str(), r.step_div, r.group, r.dvr_mode.c_str(), r.ess, r.mrays, r.rmse,
                r.max, r.pct_over, r.missed, r.spurious, r.is_default);
  return b;
}

std::vector<Isa> isas_here() {
  std::vector<Isa> v;
  for (Isa i : {Isa::sse4_2, Isa::avx2, Isa::avx512})
    if (isa_available(i)) v.push_back(i);
  return v;
}

struct Settings {
  int size = 256, frames = 5;
  bool full = false;
};

void sweep_iso(Subject const& s, Settings const& st, std::vector<Row>& rows) {
  Scene const scene = s.scene();
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  Camera const cam = fit_camera(lo, hi, st.size, st.size);
  IsoParams p;
  p.surfaces = {{s.iso, {0.9f, 0.7f, 0.4f}, 1.f}};
  p.background = {0.f, 0.f, 0.f, 0.f};  // alpha = hit mask
  double const t0 = now();
  Image const ref = render_iso_reference(scene, cam, p);
  std::fprintf(stderr, "  %s iso reference: %.1f s\n", s.name.c_str(), now() - t0);
  Isa const best = best_isa();
  struct Roots {
    char const* name;
    CellIsoOptions o;
  };
  std::vector<Roots> const roots = {{"exact", {CellIsoMethod::exact, 2, 2}},
                                    {"neubauer1", {CellIsoMethod::neubauer, 1, 2}},
                                    {"neubauer2", {CellIsoMethod::neubauer, 2, 2}},
                                    {"neubauer4", {CellIsoMethod::neubauer, 4, 2}}};
  for (Isa isa : isas_here())
    for (Traversal tr : {Traversal::packet, Traversal::spmd, Traversal::hybrid}) {
      bool const base = isa == best && tr == Traversal::packet;
      if (!base && !st.full && !(isa == best || tr == Traversal::packet)) continue;
      for (auto const& rt : roots)
        for (GradientMethod nm : {GradientMethod::analytic, GradientMethod::central}) {
          bool const def_acc = rt.o.method == CellIsoMethod::exact && nm == GradientMethod::analytic;
          if (!base && !def_acc && !st.full) continue;  // speed knobs at the default accuracy
          IsoParams q = p;
          q.roots = rt.o;
          q.normals = nm;
          RenderOptions ro;
          ro.isa = isa;
          ro.traversal = tr;
          Image img;
          double const sec = median_seconds(st.frames, [&] { img = render_iso(scene, cam, q, ro); });
          ImageDiff const d = compare_images(img, ref, 1.0);
          HitStats const h = hit_stats(img, ref);
          Row r;
          r.mode = "iso", r.mesh = s.name, r.cells = s.cells(), r.isa = isa_key(isa), r.traversal = traversal_name(tr);
          r.roots = rt.name, r.normals = nm == GradientMethod::analytic ? "analytic" : "central";
          r.config = r.roots + "/" + r.normals + "/" + r.isa + "/" + r.traversal;
          r.is_default = base && def_acc;
          r.mrays = double(cam.width) * cam.height / sec / 1e6;
          r.rmse = d.rmse, r.max = d.max, r.pct_over = 100 * d.frac_over, r.missed = h.missed, r.spurious = h.spurious;
          rows.push_back(r);
          std::printf("%s\n", csv_row(r).c_str());
          std::fflush(stdout);
        }
    }
}

/// Isosurface normals against the exact field's (issue #25): the sphere
/// |p|^2 = 0.36 of generated tets and hexes, rendered opaque white with a
/// headlight; error = RMSE (8-bit) of the shade against the exact sphere's,
/// over pixels both show as sphere and away from the silhouette (|n.v| >=
/// 0.3, where the surface's position, not its normal, decides). Speed
/// includes nothing but the render (vertex gradients are built once).
template <int N> void sweep_normals_on(GeneratedMesh<N> const& g, char const* name, Settings const& st,
                                       std::vector<Row>& rows) {
  std::vector<float> f(g.xyz.size() / 3);
  for (size_t v = 0; v < f.size(); ++v) f[v] = g.xyz[3 * v] * g.xyz[3 * v] + g.xyz[3 * v + 1] * g.xyz[3 * v + 1] + g.xyz[3 * v + 2] * g.xyz[3 * v + 2];
  CellMesh<N> const mesh = g.mesh().with_values(view(f));
  MinMaxBvh const bvh = build_minmax_bvh(mesh);
  VertexGradients const vg = build_vertex_gradients(mesh);
  Scene scene(mesh, bvh);
  if constexpr (N == 4) scene.tets[0].gradients = &vg;
  else scene.hexes[0].gradients = &vg;
  Camera const cam = Camera::look_at({0.f, 0.3f, 3.2f}, {0.f, 0.f, 0.f}, {0.f, 1.f, 0.f}, 30.f, st.size, st.size);
  IsoParams p;
  p.surfaces = {{0.36f, {1.f, 1.f, 1.f}, 1.f}};
  for (GradientMethod nm : {GradientMethod::analytic, GradientMethod::central, GradientMethod::smooth}) {
    p.normals = nm;
    Image img;
    double const sec = median_seconds(st.frames, [&] { img = render_iso(scene, cam, p); });
    double sum = 0, worst = 0;
    int n = 0;
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        glm::dvec3 const o(cam.eye), d = glm::normalize(glm::dvec3(cam.direction(float(x), float(y))));
        double const b = glm::dot(o, d), c = glm::dot(o, o) - 0.36, disc = b * b - c;
        float const* q = img.pixel(x, y);
        if (disc <= 0 || q[0] == p.background.r) continue;
        double const ndl = std::abs(glm::dot(glm::normalize(o + (-b - std::sqrt(disc)) * d), -d));
        if (ndl < 0.3) continue;
        double const shade =
            std::min(1.0, double(p.ambient) + double(p.diffuse) * ndl + double(p.specular) * std::pow(ndl, double(p.shininess)));
        double const e = 255.0 * std::abs(double(q[0]) - shade);
        sum += e * e, worst = std::max(worst, e), ++n;
      }
    Row r;
    r.mode = "normals", r.mesh = name, r.cells = mesh.cell_count(), r.isa = isa_key(best_isa()), r.traversal = "packet";
    r.roots = "exact";
    r.normals = nm == GradientMethod::analytic ? "flat" : nm == GradientMethod::central ? "central" : "smooth";
    r.config = r.normals;
    r.is_default = nm == GradientMethod::smooth;  // cellray-render's default
    r.mrays = double(cam.width) * cam.height / sec / 1e6;
    r.rmse = n ? std::sqrt(sum / n) : 0.0, r.max = worst;
    rows.push_back(r);
    std::printf("%s\n", csv_row(r).c_str());
    std::fflush(stdout);
  }
}

void sweep_normals(Settings const& st, std::vector<Row>& rows) {
  sweep_normals_on(generate_tets(100000, 2), "gen-tets-sphere", st, rows);
  sweep_normals_on(generate_hexes(30000, 2, 0.15f), "gen-hexes-sphere", st, rows);
}

/// A demanding transfer function: opacity over the whole range with kinks,
/// colour changing everywhere, unit distance diagonal / 10 (cellray-render's
/// default). The built-in presets are transparent on two thirds of the range,
/// which hides most of the differences this sweep is after.
TransferFunction sweep_tf(Subject const& s) {
  TransferFunction tf;
  float const k[6] = {0.f, 0.2f, 0.4f, 0.6f, 0.8f, 1.f};
  float const a[6] = {0.05f, 0.3f, 0.1f, 0.6f, 0.2f, 0.9f};
  for (int i = 0; i < 6; ++i) {
    tf.values.push_back(s.vmin + k[i] * (s.vmax - s.vmin));
    tf.rgba.emplace_back(0.2f + 0.7f * k[i], 0.9f - 0.6f * k[i], 0.5f + 0.4f * std::sin(6.f * k[i]), a[i]);
  }
  tf.unit_distance = s.diagonal() / 10.f;
  return tf;
}

void sweep_dvr(Subject const& s, Settings const& st, std::vector<Row>& rows) {
  Scene const scene = s.scene();
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  Camera const cam = fit_camera(lo, hi, st.size, st.size);
  DvrParams p;
  p.tf = sweep_tf(s);
  double const t0 = now();
  Image const ref = render_dvr_reference(scene, cam, p);
  std::fprintf(stderr, "  %s DVR reference: %.1f s\n", s.name.c_str(), now() - t0);
  Isa const best = best_isa();
  struct Cfg {
    int step_div, group;
    DvrMode mode;
    bool ess;
    Isa isa;
    Traversal tr;
  };
  std::vector<Cfg> cfgs;
  for (int div : {25, 50, 125, 250, 500, 1000, 2000})
    for (DvrMode m : {DvrMode::samples, DvrMode::segments})
      for (bool ess : {true, false}) cfgs.push_back({div, 16, m, ess, best, Traversal::packet});
  for (int g : {1, 4, 8, 32}) cfgs.push_back({500, g, DvrMode::samples, true, best, Traversal::packet});
  // Speed knobs in the default mode (cell segments); both modes with --full.
  DvrParams const def;
  // The default step of a mode as a divisor of the diagonal (default_dvr_step).
  auto default_div = [](DvrMode m) { return int(std::lround(1.0 / double(default_dvr_step(m, 1.f)))); };
  for (DvrMode m : {DvrMode::segments, DvrMode::samples}) {
    if (m != def.mode && !st.full) continue;
    for (Isa isa : isas_here())
      for (Traversal tr : {Traversal::packet, Traversal::spmd, Traversal::hybrid})
        if (!(isa == best && tr == Traversal::packet)) cfgs.push_back({default_div(m), 16, m, true, isa, tr});
  }
  for (Cfg const& c : cfgs) {
    DvrParams q = p;
    q.step = s.diagonal() / float(c.step_div);
    q.group_size = c.group;
    q.mode = c.mode;
    q.empty_space_skipping = c.ess;
    RenderOptions ro;
    ro.isa = c.isa;
    ro.traversal = c.tr;
    Image img;
    int const frames = c.step_div >= 1000 ? std::max(1, st.frames / 2) : st.frames;
    double const sec = median_seconds(frames, [&] { img = render_dvr(scene, cam, q, ro); });
    ImageDiff const d = compare_images(img, ref, 1.0);
    Row r;
    r.mode = "dvr", r.mesh = s.name, r.cells = s.cells(), r.isa = isa_key(c.isa), r.traversal = traversal_name(c.tr);
    r.step_div = c.step_div, r.group = c.group, r.ess = c.ess;
    r.dvr_mode = c.mode == DvrMode::samples ? "samples" : "segments";
    r.config = r.dvr_mode + "/d" + std::to_string(c.step_div) + "/g" + std::to_string(c.group) + (c.ess ? "/ess" : "/noess") +
               "/" + r.isa + "/" + r.traversal;
    // cellray-render's default: the library's DvrParams defaults (step 0 =
    // default_dvr_step), best ISA, packet traversal.
    r.is_default = c.step_div == default_div(def.mode) && c.group == def.group_size && c.mode == def.mode &&
                   c.ess == def.empty_space_skipping && c.isa == best && c.tr == Traversal::packet;
    r.mrays = double(cam.width) * cam.height / sec / 1e6;
    r.rmse = d.rmse, r.max = d.max, r.pct_over = 100 * d.frac_over;
    rows.push_back(r);
    std::printf("%s\n", csv_row(r).c_str());
    std::fflush(stdout);
  }
}

// ------------------------------------------------------------ failure modes

struct Line {
  std::string mode, set, method, rate, behaviour;
};

std::string pct(double x) {
  char b[64];
  std::snprintf(b, sizeof b, "%.3f%%", x);
  return b;
}

/// Generated tets or hexes on a regular lattice (no jitter) with s = x: the
/// isosurfaces at lattice planes lie exactly on shared faces, edges and
/// vertices. Opacity 0.5, so a crack shows the background and double
/// coverage a darker pixel.
template <int N> void crack_rows(std::vector<Line>& out, int size) {
  auto g = std::make_unique<GeneratedMesh<N>>();
  if constexpr (N == 4) *g = generate_tets(24000, 1, 0.f);
  else *g = generate_hexes(8000, 1, 0.f);
  std::vector<float> f(g->xyz.size() / 3);
  for (size_t v = 0; v < f.size(); ++v) f[v] = g->xyz[3 * v];
  CellMesh<N> const m = g->mesh().with_values(view(f));
  MinMaxBvh const bvh = build_minmax_bvh(m);
  Scene const scene(m, bvh);
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  Camera const cam = fit_camera(lo, hi, size, size);
  IsoParams p;
  float const h = 2.f / float(g->lattice);
  p.surfaces = {{-1.f + h * float(g->lattice / 2), {0.9f, 0.6f, 0.3f}, 0.5f},
                {-1.f + h * float(g->lattice / 2 + 2), {0.3f, 0.6f, 0.9f}, 0.5f}};
  Image const ref = render_iso_reference(scene, cam, p);
  std::string const set = std::string(N == 4 ? "regular tet lattice (" : "regular hex lattice (") +
                          std::to_string(m.cell_count()) + " cells), s = x, isosurfaces on lattice planes, opacity 0.5";
  for (auto const& [name, o] : std::vector<std::pair<std::string, CellIsoOptions>>{
           {"exact", {CellIsoMethod::exact, 2, 2}}, {"Neubauer N=2", {CellIsoMethod::neubauer, 2, 2}}}) {
    IsoParams q = p;
    q.roots = o;
    ImageDiff const d = compare_images(render_iso(scene, cam, q), ref, 2.0);
    out.push_back({"cracks / double coverage at shared faces (iso)", set, name,
                   pct(100 * d.frac_over) + " of pixels off by > 2/255",
                   "canonical face order: both neighbours compute the same crossing bit for bit; layers closer than "
                   "1e-5 x diagonal merge, so a crossing on a shared face is counted once"});
  }
  DvrParams dp;
  dp.tf.values = {-1.f, 1.f};
  dp.tf.rgba = {{0.2f, 0.5f, 0.8f, 0.3f}, {0.2f, 0.5f, 0.8f, 0.3f}};
  dp.tf.unit_distance = 1.f;
  Image const dref = render_dvr_reference(scene, cam, dp);
  for (DvrMode mode : {DvrMode::samples, DvrMode::segments}) {
    DvrParams q = dp;
    q.mode = mode;
    ImageDiff const d = compare_images(render_dvr(scene, cam, q), dref, 1.0);
    out.push_back({"cracks / double coverage at shared faces (DVR, constant TF)",
                   std::string(N == 4 ? "regular tet lattice" : "regular hex lattice") + ", constant TF: a crack or a doubled segment changes the path length",
                   mode == DvrMode::samples ? "samples, step diag/500" : "segments, step diag/500",
                   pct(100 * d.frac_over) + " of pixels off by > 1/255 (max " + std::to_string(d.max).substr(0, 4) + ")",
                   "a sample on a shared face lies in exactly one cell (face-tie rule); segments chain without gaps"});
  }
}

void root_rows(Subject const& s, std::vector<Line>& out, int size) {
  Scene const scene = s.scene();
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  Camera const cam = fit_camera(lo, hi, size, size);
  IsoParams p;
  p.surfaces = {{s.iso, {0.9f, 0.7f, 0.4f}, 1.f}};
  p.background = {0.f, 0.f, 0.f, 0.f};
  Image const ref = render_iso_reference(scene, cam, p);
  uint64_t ref_hits = 0;
  for (size_t i = 3; i < ref.rgba.size(); i += 4) ref_hits += ref.rgba[i] > 0.5f;
  for (auto const& [name, o] : std::vector<std::pair<std::string, CellIsoOptions>>{
           {"exact", {CellIsoMethod::exact, 2, 2}},
           {"Neubauer N=1", {CellIsoMethod::neubauer, 1, 2}},
           {"Neubauer N=2", {CellIsoMethod::neubauer, 2, 2}},
           {"Neubauer N=4", {CellIsoMethod::neubauer, 4, 2}}}) {
    IsoParams q = p;
    q.roots = o;
    HitStats const h = hit_stats(render_iso(scene, cam, q), ref);
    double const n = double(cam.width) * cam.height;
    out.push_back({"missed / spurious roots (grazing rays, double roots)",
                   s.name + " (" + std::to_string(s.cells()) + " cells), " + std::to_string(size) + "^2 rays",
                   name,
                   "missed " + pct(h.missed * n / std::max<double>(1, double(ref_hits))) + ", spurious " +
                       pct(h.spurious * n / std::max<double>(1, double(ref_hits))) + " of hit pixels",
                   o.method == CellIsoMethod::exact
                       ? "tets: linear root; hexes: cubic through the ray field, split at its extrema, refined on the ray"
                       : "endpoint sign test: a root pair inside one cell (both ends on one side) is missed"});
  }
}

/// Newton non-convergence: random points inside distorted hexes (their
/// trilinear coordinates drawn uniformly, mapped in double), located by the
/// fast kernel.
void newton_rows(Subject const& s, std::vector<Line>& out) {
  HexMesh const& m = s.hexes;
  uint64_t const n = std::min<uint64_t>(m.cell_count(), 20000);
  std::vector<uint32_t> ids(n * 4);
  std::vector<float> pts(n * 4 * 3);
  uint64_t state = 12345;
  auto rnd = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return double(state >> 11) / 9007199254740992.0;
  };
  for (uint64_t i = 0; i < n * 4; ++i) {
    uint64_t const cell = (i / 4) * (m.cell_count() / n);
    ids[i] = uint32_t(cell);
    ref::Hex const h = ref::load(m, cell);
    glm::dvec3 const p = ref::position(h, {rnd(), rnd(), rnd()});
    pts[3 * i] = float(p.x), pts[3 * i + 1] = float(p.y), pts[3 * i + 2] = float(p.z);
  }
  for (Isa isa : isas_here()) {
    std::vector<LocateOut> res(ids.size());
    dispatch<CellQueries>(isa, m, CellSelect{ids.data(), 0}, pts.data(), uint64_t(ids.size()), res.data());
    uint64_t noconv = 0, lost = 0;
    for (auto const& r : res) noconv += !r.converged, lost += !r.inside;
    out.push_back({"Newton non-convergence (hex point location)",
                   s.name + ", " + std::to_string(ids.size()) + " points inside " + std::to_string(n) + " hexes",
                   std::string("float Newton, cap 12, ") + isa_key(isa),
                   pct(100.0 * double(noconv) / double(res.size())) + " not converged, " +
                       pct(100.0 * double(lost) / double(res.size())) + " inside points reported outside",
                   "reports converged = false (no value); callers that must not lose the point fall back to "
                   "ref::locate (double, multi-start)"});
  }
}

/// NaN scalars on a region and degenerate (zero-volume) cells added.
void nan_rows(std::vector<Line>& out, int size) {
  auto g = std::make_unique<GeneratedMesh<4>>(generate_tets(24000));
  std::vector<float> f = g->field;
  uint64_t nans = 0;
  for (size_t v = 0; v < f.size(); ++v)
    if (g->xyz[3 * v] > 0.2f && g->xyz[3 * v + 1] > -0.3f) f[v] = std::numeric_limits<float>::quiet_NaN(), ++nans;
  // Zero-volume tets: every 50th cell duplicated with its last corner replaced by its first.
  std::vector<uint32_t> cells = g->cells;
  uint64_t const orig = cells.size() / 4;
  uint64_t degenerate = 0;
  for (uint64_t c = 0; c < orig; c += 50, ++degenerate)
    cells.insert(cells.end(), {g->cells[4 * c], g->cells[4 * c + 1], g->cells[4 * c + 2], g->cells[4 * c]});
  TetMesh const m(view(g->xyz), view(cells), view(f), "field");
  MinMaxBvh const bvh = build_minmax_bvh(m);
  Scene const scene(m, bvh);
  glm::vec3 lo, hi;
  scene.bounds(lo, hi);
  Camera const cam = fit_camera(lo, hi, size, size);
  std::string const set = "generated tets, " + std::to_string(nans) + " NaN vertices (a corner region), " +
                          std::to_string(degenerate) + " zero-volume tets added";
  IsoParams p;
  p.surfaces = {{0.3f, {0.9f, 0.7f, 0.4f}, 0.6f}, {0.5f, {0.4f, 0.6f, 0.9f}, 1.f}};
  ImageDiff const di = compare_images(render_iso(scene, cam, p), render_iso_reference(scene, cam, p), 2.0);
  out.push_back({"NaN scalars and degenerate cells (iso)", set, "exact roots",
                 pct(100 * di.frac_over) + " of pixels off by > 2/255, " + std::to_string(di.nonfinite) +
                     " non-finite channels",
                 "a cell with a NaN corner value is invisible (empty range); a zero-volume cell has no interval"});
  DvrParams dp;
  dp.tf = transfer_function_preset("viridis", 0.1f, 0.9f, 0.8f);
  dp.tf.unit_distance = 0.35f;
  Image const dref = render_dvr_reference(scene, cam, dp);
  for (DvrMode mode : {DvrMode::samples, DvrMode::segments}) {
    DvrParams q = dp;
    q.mode = mode;
    q.step = glm::length(hi - lo) / 2000.f;
    ImageDiff const d = compare_images(render_dvr(scene, cam, q), dref, 2.0);
    out.push_back({"NaN scalars and degenerate cells (DVR)", set,
                   mode == DvrMode::samples ? "samples, step diag/2000" : "segments, step diag/2000",
                   pct(100 * d.frac_over) + " of pixels off by > 2/255, " + std::to_string(d.nonfinite) +
                       " non-finite channels",
                   "NaN samples are transparent; NaN cells are skipped like empty space"});
  }
}

void write_report(std::string const& path, int size) {
  std::vector<Line> lines;
  std::fprintf(stderr, "cracks...\n");
  crack_rows<4>(lines, size);
  crack_rows<8>(lines, size);
  std::fprintf(stderr, "roots...\n");
  for (char const* k : {"gen-tets", "gen-hexes", "post", "disk"}) root_rows(*make_subject(k), lines, size);
  std::fprintf(stderr, "newton...\n");
  for (char const* k : {"gen-hexes", "disk"}) newton_rows(*make_subject(k), lines);
  std::fprintf(stderr, "nan...\n");
  nan_rows(lines, size);
  std::ofstream f(path);
  f << "# Failure modes, measured\n\n"
       "Generated by `scripts/failure-report.sh` (`bench_accuracy --report`); every rate is measured by comparing "
       "the fast renderer (default ISA: "
    << isa_key(best_isa()) << ", packet traversal) with the double-precision reference renderer "
       "(`render/reference.hpp`) on the same rays, "
    << size << "x" << size
    << " images. The tests in `tests/test_render_reference.cpp` (\"failure modes\") guard these numbers; "
       "cell-level watertightness (rays aimed at shared faces, edges and vertices) is guarded in "
       "`tests/test_cells_watertight.cpp` and Newton statistics per kernel in `tests/test_cells_hex.cpp`.\n\n"
       "| failure mode | test set | method | measured | what the library does |\n|---|---|---|---|---|\n";
  for (auto const& l : lines)
    f << "| " << l.mode << " | " << l.set << " | " << l.method << " | " << l.rate << " | " << l.behaviour << " |\n";
  std::fprintf(stderr, "wrote %s\n", path.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  Settings st;
  std::string csv, report;
  std::vector<std::string> meshes = {"gen-tets",   "gen-hexes", "gen-wedges", "gen-pyramids",
                                     "gen-family", "post",      "disk",       "component8"};
  std::string modes = "iso,dvr,normals";
  for (int i = 1; i < argc; ++i) {
    std::string const a = argv[i];
    auto val = [&]() -> std::string {
      if (i + 1 >= argc) throw InvalidArgument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--csv") csv = val();
    else if (a == "--report") report = val();
    else if (a == "--size") st.size = std::stoi(val());
    else if (a == "--frames") st.frames = std::max(1, std::stoi(val()));
    else if (a == "--full") st.full = true;
    else if (a == "--modes") modes = val();
    else if (a == "--meshes") {
      meshes.clear();
      std::stringstream ss(val());
      for (std::string k; std::getline(ss, k, ',');) meshes.push_back(k);
    } else {
      std::fprintf(stderr,
                   "usage: bench_accuracy [--csv PATH] [--report PATH] [--size N] [--frames N] [--full]\n"
                   "                      [--modes iso,dvr,normals]\n"
                   "                      [--meshes gen-tets,gen-hexes,gen-wedges,gen-pyramids,gen-family,post,disk,component8,boxturb]\n");
      return a == "--help" ? 0 : 2;
    }
  }
  try {
    if (!report.empty()) write_report(report, st.size);
    if (csv.empty() && !report.empty()) return 0;
    std::vector<Row> rows;
    std::printf("%s\n", csv_header().c_str());
    for (auto const& k : meshes) {
      if (modes.find("iso") == std::string::npos && modes.find("dvr") == std::string::npos) break;
      std::fprintf(stderr, "%s...\n", k.c_str());
      auto const s = make_subject(k);
      if (modes.find("iso") != std::string::npos) sweep_iso(*s, st, rows);
      if (modes.find("dvr") != std::string::npos) sweep_dvr(*s, st, rows);
    }
    if (modes.find("normals") != std::string::npos) sweep_normals(st, rows);
    if (!csv.empty()) {
      std::ofstream f(csv);
      f << csv_header() << "\n";
      for (auto const& r : rows) f << csv_row(r) << "\n";
    }
  } catch (std::exception const& e) {
    std::fprintf(stderr, "bench_accuracy: %s\n", e.what());
    return 1;
  }
  return 0;
}
