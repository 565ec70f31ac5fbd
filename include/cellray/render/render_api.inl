// Baseline side of the renderer: checks, scene preparation, TBB tiles.
// Included at the end of render.hpp.

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/blocked_range2d.h>
#include <tbb/parallel_for.h>

namespace cellray {

inline void Scene::bounds(glm::vec3& lo, glm::vec3& hi) const {
  constexpr float inf = std::numeric_limits<float>::infinity();
  lo = glm::vec3(inf);
  hi = glm::vec3(-inf);
  auto add = [&](MinMaxBvh const* bvh) {
    if (!bvh || bvh->empty()) return;
    Node const& r = bvh->root();
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], r.lo[k]), hi[k] = std::max(hi[k], r.hi[k]);
  };
  for_each_cell_type([&](auto n) {
    for (auto const& p : parts<n()>()) add(p.bvh);
  });
}

inline uint64_t Scene::cell_count() const {
  uint64_t n = 0;
  for_each_cell_type([&](auto c) {
    for (auto const& p : parts<c()>()) n += p.mesh.cell_count();
  });
  return n;
}

namespace render_detail {

/// "tetrahedral part 2": how errors name a scene's parts.
template <int N> std::string part_name(size_t index) {
  return std::string(cell_type_adjective(N)) + " part " + std::to_string(index);
}

template <int N> void add_part(ScenePart<N> const& part, PreparedScene& out, size_t index) {
  std::string const what = part_name<N>(index);
  if (!part.bvh) throw InvalidArgument(what + " has no BVH");
  if (!part.mesh.has_values()) throw InvalidMesh(what + " has no scalar values");
  if (part.bvh->item_count() != part.mesh.cell_count())
    throw InvalidArgument(what + ": BVH built over " + std::to_string(part.bvh->item_count()) + " cells, mesh has " +
                          std::to_string(part.mesh.cell_count()));
  ValueRanges const& r = part.ranges ? *part.ranges : part.bvh->ranges();
  PartCells<N> cells{&part.mesh, nullptr};
  if (part.neighbours) {
    if (!part.neighbours->fits(part.mesh))
      throw InvalidArgument(what + ": its face neighbours were built over another mesh (" +
                            std::to_string(part.neighbours->cell_count()) + " cells; this one has " +
                            std::to_string(part.mesh.cell_count()) + ", or other vertex ids)");
  }
  // Beyond 32-bit gather offsets (cell x corners, which bounds cell x faces,
  // and vertex x 3) the march is not available: the tree alone.
  constexpr uint64_t lim = uint64_t(std::numeric_limits<int32_t>::max());
  bool const march_fits = part.mesh.cell_count() * N < lim && part.mesh.vertex_count() * 3 < lim;
  if (march_fits) cells.neighbours = part.neighbours;
  out.parts.push_back(PreparedPart{TreeView(*part.bvh, r), cells});
}

inline PreparedScene prepare(Scene const& scene) {
  PreparedScene s;
  for_each_cell_type([&](auto n) {
    auto const& parts = scene.parts<n()>();
    for (size_t i = 0; i < parts.size(); ++i) add_part(parts[i], s, i);
  });
  // Two parts, tets then hexahedra, whose neighbours were linked to each
  // other: DVR marches across both (MixedMarch).
  if (s.parts.size() == 2 && s.parts[0].marches() && s.parts[1].marches()) {
    auto const* t = s.parts[0].cells_of<4>();
    auto const* h = s.parts[1].cells_of<8>();
    s.mixed_march = t && h && t->neighbours->linked_to(*h->mesh) && h->neighbours->linked_to(*t->mesh);
  }
  scene.bounds(s.lo, s.hi);
  // The diagonal in double: a box of finite floats can have a diagonal over
  // FLT_MAX, and a default step of 1/500 would then never cross it.
  bool const empty = !(s.lo.x <= s.hi.x && s.lo.y <= s.hi.y && s.lo.z <= s.hi.z);
  double const d = glm::length(glm::dvec3(s.hi) - glm::dvec3(s.lo));
  s.diagonal = empty || !(d > 0.0) ? 1.f : float(std::min(d, double(std::numeric_limits<float>::max())));
  return s;
}

inline void check_camera(Camera const& cam) {
  if (cam.width < 1 || cam.height < 1)
    throw InvalidArgument("image size " + std::to_string(cam.width) + "x" + std::to_string(cam.height) +
                          ": both must be at least 1");
}

inline void check_tile(Camera const& cam, Tile const& t) {
  if (t.x0 < 0 || t.y0 < 0 || t.w < 0 || t.h < 0 || t.x0 + t.w > cam.width || t.y0 + t.h > cam.height)
    throw InvalidArgument("tile outside the image");
}

inline void check_iso(IsoParams const& p) {
  if (p.surfaces.empty() || p.surfaces.size() > size_t(IsoSet::max_count))
    throw InvalidArgument("isosurface rendering needs 1 to 8 isovalues, got " + std::to_string(p.surfaces.size()));
  for (auto const& s : p.surfaces)
    if (!std::isfinite(s.value) || !(s.opacity >= 0.f && s.opacity <= 1.f))
      throw InvalidArgument("isovalues must be finite and opacities in [0, 1]");
  if (p.ao_samples < 0 || p.ao_samples > 1024) throw InvalidArgument("ambient occlusion samples must be in 0..1024");
  if (p.roots.method == CellIsoMethod::neubauer && (p.roots.neubauer_steps < 0 || p.roots.neubauer_steps > 64))
    throw InvalidArgument("Neubauer steps must be in 0..64");
  p.clip.check();
}

/// The scene, clip, normals and colouring of an isosurface render.
/// @throws InvalidArgument when smooth normals lack a part's vertex
/// gradients, or a part lacks the array to colour by.
inline PreparedScene prepare_iso(Scene const& scene, IsoParams const& p) {
  PreparedScene s = prepare(scene);
  s.clip = PreparedClip::from(p.clip);
  size_t k = 0;
  auto extras = [&](auto const& part, std::string const& name) {
    PreparedPart& pp = s.parts[k++];
    if (p.normals == GradientMethod::smooth) {
      if (!part.gradients) throw InvalidArgument("smooth normals need vertex gradients (build_vertex_gradients) for " + name);
      if (!part.gradients->fits(part.mesh))
        throw InvalidArgument(name + ": its vertex gradients were built over another mesh (" +
                              std::to_string(part.gradients->vertex_count()) + " vertices, this one has " +
                              std::to_string(part.mesh.vertex_count()) + ")");
      pp.gradients = part.gradients->data();
    }
    if (!p.color_by.array.empty()) {
      for (ScalarArray const& a : part.mesh.arrays())
        if (a.name == p.color_by.array) pp.color_values = a.values.data;
      if (!pp.color_values) throw InvalidArgument(name + " has no point array '" + p.color_by.array + "' to colour by");
    }
  };
  for_each_cell_type([&](auto n) {
    auto const& parts = scene.parts<n()>();
    for (size_t i = 0; i < parts.size(); ++i) extras(parts[i], part_name<n()>(i));
  });
  if (!p.color_by.array.empty()) {
    if (!p.color_by.colors.values.empty()) p.color_by.colors.check();
    s.color_by = true;
    s.colors = ColorTable::of(p.color_by.colors, glm::vec3(0.75f));
  }
  return s;
}

/// Values where the transfer function's opacity is not zero, as merged
/// intervals (at most ValueWindows::max_count; beyond that, gaps merge).
inline ValueWindows opacity_windows(TransferFunction const& tf) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  std::vector<std::pair<float, float>> w;
  auto push = [&](float a, float b) {
    if (!w.empty() && a <= w.back().second) w.back().second = std::max(w.back().second, b);
    else w.emplace_back(a, b);
  };
  if (tf.rgba.front().a > 0.f) push(-inf, tf.values.front());
  for (size_t i = 0; i + 1 < tf.values.size(); ++i)
    if (tf.rgba[i].a > 0.f || tf.rgba[i + 1].a > 0.f) push(tf.values[i], tf.values[i + 1]);
  if (tf.rgba.back().a > 0.f) push(tf.values.back(), inf);
  while (w.size() > size_t(ValueWindows::max_count)) {  // merge across the smallest gap
    size_t best = 0;
    for (size_t i = 1; i + 1 < w.size(); ++i)
      if (w[i + 1].first - w[i].second < w[best + 1].first - w[best].second) best = i;
    w[best].second = w[best + 1].second;
    w.erase(w.begin() + long(best) + 1);
  }
  ValueWindows out;
  out.count = int(w.size());
  for (size_t i = 0; i < w.size(); ++i) out.lo[i] = w[i].first, out.hi[i] = w[i].second;
  return out;
}

/// The integrals over u of sigma = -ln(1 - min(a, 0.999999)) / unit (the
/// reference renderer's extinction) and of r, g, b times it, where colour
/// and opacity run linearly from `c0` to `c1` over a width `w` of u, added
/// to `acc`. Exact: -ln(1 - a) is far from linear as a nears 1, and a
/// trapezoid over a table's entries there overstated a narrow opaque peak's
/// optical depth by a third.
inline void add_linear_integrals(glm::dvec4 c0, glm::dvec4 c1, double w, double unit, double (&acc)[4]) {
  if (c0.a <= 0.0 && c1.a <= 0.0) return;  // no extinction (most of a typical function's range)
  constexpr double y_min = 1.0 - 0.999999;  // transmittance per unit distance, at least
  double y0 = 1.0 - c0.a, y1 = 1.0 - c1.a;   // linear in t until clamped
  if (y0 < y_min && y1 < y_min) y0 = y1 = y_min;
  if ((y0 < y_min) != (y1 < y_min)) {
    // Where y passes y_min the clamp starts: y_min (constant) on that side.
    double const t = (y0 - y_min) / (y0 - y1);
    glm::dvec4 const cm = c0 + t * (c1 - c0);
    bool const first = y0 < y_min;  // the clamped side
    double const wc = w * (first ? t : 1.0 - t), sigma = -std::log(y_min) / unit * wc;
    glm::dvec4 const mean = 0.5 * (cm + (first ? c0 : c1));
    acc[0] += sigma, acc[1] += mean.r * sigma, acc[2] += mean.g * sigma, acc[3] += mean.b * sigma;
    glm::dvec4 a = c0, b = c1;
    (first ? a : b) = cm;
    (first ? y0 : y1) = y_min;
    c0 = a, c1 = b, w -= wc;
  }
  double const dy = y1 - y0;
  if (std::fabs(dy) <= 1e-3 * std::min(y0, y1)) {
    // -ln y nearly constant: 3-point Gauss-Legendre in t (exact to ~1e-12 here).
    constexpr double x[3] = {0.5 - 0.3872983346207417, 0.5, 0.5 + 0.3872983346207417};
    constexpr double wt[3] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};
    for (int q = 0; q < 3; ++q) {
      glm::dvec4 const c = c0 + x[q] * (c1 - c0);
      double const sigma = -std::log(y0 + x[q] * dy) / unit * w * wt[q];
      acc[0] += sigma, acc[1] += c.r * sigma, acc[2] += c.g * sigma, acc[3] += c.b * sigma;
    }
    return;
  }
  // With c = alpha + beta y: the antiderivatives of -ln y and -y ln y in y.
  auto f1 = [](double y) { return y - y * std::log(y); };
  auto f2 = [](double y) { return 0.25 * y * y - 0.5 * y * y * std::log(y); };
  double const i1 = (f1(y1) - f1(y0)) / dy, i2 = (f2(y1) - f2(y0)) / dy, k = w / unit;
  acc[0] += k * i1;
  for (int ch = 0; ch < 3; ++ch) {
    double const beta = (c1[ch] - c0[ch]) / dy, alpha = c0[ch] - beta * y0;
    acc[ch + 1] += k * (alpha * i1 + beta * i2);
  }
}

/// PreparedTf::integrals of `tf` for a table of `size` entries, entry k at
/// value lo + k / scale. Coordinate u = (v - lo) * scale + 1 puts entry k
/// at u = k + 1; cell 0 is u < 1 (the first entry's value below the range),
/// cell c = 1 .. size - 1 is [c, c + 1) (between entries c - 1 and c: the
/// function's exact integrals, split at its control values), cell `size` is
/// u >= size (the last entry's value above it). The integral up to u in
/// cell c is before[c] + (u - c) * cell[c], also outside [0, size + 1), so
/// values beyond the range integrate as the ends continue. `before` sums in
/// double and keeps hi + lo: a difference of two stays exact to float
/// precision of itself, not of the whole sum (faint material valued above
/// a near-opaque band keeps its opacity).
inline std::vector<float> tf_integrals(TransferFunction const& tf, float lo, float scale, int size) {
  constexpr size_t stride = PreparedTf::integral_stride;
  std::vector<float> out((size_t(size) + 1) * stride);
  std::vector<double> cells((size_t(size) + 1) * 4);
  double const unit = tf.unit_distance;
  auto at = [&](double v) { return glm::dvec4(tf(float(v))); };
  auto value = [&](int k) { return double(lo) + double(k) / double(scale); };
  // Each cell's own integrals in parallel (every DVR frame makes these: 0.2
  // ms serial); each cell's arithmetic is the same on any thread count.
  tbb::parallel_for(tbb::blocked_range<int>(0, size + 1, 512), [&](tbb::blocked_range<int> const& range) {
    size_t knot = 0;  // first control value past the cell's start
    for (int c = range.begin(); c < range.end(); ++c) {
      double cell[4] = {0.0, 0.0, 0.0, 0.0};
      if (c == 0 || c == size) {
        glm::dvec4 const e = at(value(c == 0 ? 0 : size - 1));
        add_linear_integrals(e, e, 1.0, unit, cell);
      } else {
        double const v0 = value(c - 1), v1 = value(c), w = 1.0 / (v1 - v0);
        double from = v0;
        glm::dvec4 c_from = at(v0);
        while (knot < tf.values.size() && double(tf.values[knot]) <= v0) ++knot;
        for (; knot < tf.values.size() && double(tf.values[knot]) < v1; ++knot) {
          double const to = tf.values[knot];
          glm::dvec4 const c_to(tf.rgba[knot]);
          add_linear_integrals(c_from, c_to, (to - from) * w, unit, cell);
          from = to, c_from = c_to;
        }
        add_linear_integrals(c_from, at(v1), (v1 - from) * w, unit, cell);
      }
      std::copy(cell, cell + 4, cells.begin() + std::ptrdiff_t(c) * 4);
    }
  });
  double before[4] = {0.0, 0.0, 0.0, 0.0};
  for (int c = 0; c <= size; ++c) {
    float* e = out.data() + size_t(c) * stride;
    double const* cell = cells.data() + size_t(c) * 4;
    for (int ch = 0; ch < 4; ++ch) {
      float const hi = float(before[ch]);
      e[ch] = hi, e[4 + ch] = float(before[ch] - double(hi)), e[8 + ch] = float(cell[ch]);
      before[ch] += cell[ch];
    }
  }
  return out;
}

/// 4096 entries: the piecewise-linear function is reproduced to within
/// 1/4096 of its range between control points. Only what `mode` reads, made
/// every frame: the step-corrected entries for samples, the integrals for
/// cell segments (both took 0.6 ms of a DVR frame's setup, serial, and
/// 330 KB).
inline PreparedTf tf_table(TransferFunction const& tf, float step, DvrMode mode) {
  constexpr int size = 4096;
  PreparedTf t;
  t.tf = &tf;
  t.size = size;
  t.lo = tf.values.front();
  float const hi = tf.values.size() > 1 ? tf.values.back() : t.lo + 1.f;
  // In double: hi - lo overflows float for values near +-3e38.
  t.scale = float(double(size - 1) / (double(hi) - double(t.lo)));
  if (mode == DvrMode::segments) {
    t.integrals = tf_integrals(tf, t.lo, t.scale, size);
    return t;
  }
  std::vector<float> r(size), g(size), b(size), a(size);
  for (int i = 0; i < size; ++i) {
    glm::vec4 const c = tf(float(double(t.lo) + double(i) / double(t.scale)));
    r[size_t(i)] = c.r, g[size_t(i)] = c.g, b[size_t(i)] = c.b;
    float const keep = 1.f - std::min(c.a, 0.999999f);  // fraction of light let through per unit distance
    a[size_t(i)] = 1.f - std::pow(keep, step / tf.unit_distance);
  }
  t.r = PairTable(r), t.g = PairTable(g), t.b = PairTable(b), t.a = PairTable(a);
  return t;
}

template <class F> void for_tiles(Camera const& cam, int tile_size, F const& f) {
  int const ts = std::max(4, tile_size);
  int const nx = (cam.width + ts - 1) / ts, ny = (cam.height + ts - 1) / ts;
  tbb::parallel_for(tbb::blocked_range2d<int>(0, ny, 1, 0, nx, 1), [&](tbb::blocked_range2d<int> const& r) {
    for (int ty = r.rows().begin(); ty < r.rows().end(); ++ty)
      for (int tx = r.cols().begin(); tx < r.cols().end(); ++tx) {
        Tile const t{tx * ts, ty * ts, std::min(ts, cam.width - tx * ts), std::min(ts, cam.height - ty * ts)};
        f(t);
      }
  });
}

/// DVR shading: 1 / DvrShading::gradient_full after its default (the
/// transfer function's value span / scene diagonal); +inf when that is 0
/// (shading then applies in full wherever the gradient is nonzero).
/// @throws InvalidArgument for negative or non-finite shading parameters.
inline float inverse_gradient_full(DvrParams const& p, float diagonal) {
  DvrShading const& sh = p.shading;
  if (!sh.enabled) return 0.f;
  for (float x : {sh.ambient, sh.diffuse, sh.specular, sh.shininess, sh.gradient_full})
    if (!(x >= 0.f) || !std::isfinite(x))
      throw InvalidArgument("DVR shading parameters must be finite and non-negative");
  float const span = p.tf.values.back() - p.tf.values.front();
  float const full = sh.gradient_full > 0.f ? sh.gradient_full : span / diagonal;
  return full > 0.f && std::isfinite(full) ? 1.f / full : std::numeric_limits<float>::infinity();
}

inline void prepare_dvr(Scene const& scene, DvrParams const& p, DvrSetup& out) {
  p.tf.check();
  if (p.group_size < 1 || p.group_size > max_sample_group)
    throw InvalidArgument("sample group size " + std::to_string(p.group_size) + " outside 1..32");
  if (!(p.termination > 0.f && p.termination <= 1.f)) throw InvalidArgument("termination opacity must be in (0, 1]");
  p.clip.check();
  out.scene = prepare(scene);
  out.scene.clip = PreparedClip::from(p.clip);
  out.scene.clip.caps = false;  // the volume starts at the cut
  float const step = p.step > 0.f ? p.step : default_dvr_step(p.mode, out.scene.diagonal);
  if (!std::isfinite(step) || !(step > 0.f)) throw InvalidArgument("DVR step must be positive and finite");
  if (out.scene.diagonal / step > 1e7f) throw InvalidArgument("DVR step too small for the scene (over 10^7 samples per ray)");
  out.scene.step = step;
  out.scene.windows = p.empty_space_skipping ? opacity_windows(p.tf) : ValueWindows{};
  out.table = tf_table(p.tf, step, p.mode);
  out.scene.tf = &out.table;
  out.scene.inv_gradient_full = inverse_gradient_full(p, out.scene.diagonal);
}

inline void check_frame_buffer(Camera const& cam, FrameBuffer const& f) {
  if (f.width != cam.width || f.height != cam.height)
    throw InvalidArgument("frame buffer " + std::to_string(f.width) + "x" + std::to_string(f.height) +
                          " for a " + std::to_string(cam.width) + "x" + std::to_string(cam.height) + " camera");
  if (!f.rgba) throw InvalidArgument("frame buffer without an RGBA buffer");
  size_t const pixel = f.format == FrameBuffer::Format::rgba8 ? 4 : 16;
  if (f.row_bytes != 0 && f.row_bytes < pixel * size_t(f.width))
    throw InvalidArgument("frame buffer rows of " + std::to_string(f.row_bytes) + " bytes hold fewer than " +
                          std::to_string(f.width) + " pixels");
  if ((f.depth_in && f.depth_in_row != 0 && f.depth_in_row < size_t(f.width)) ||
      (f.depth_out && f.depth_out_row != 0 && f.depth_out_row < size_t(f.width)))
    throw InvalidArgument("depth buffer rows shorter than the image width");
  if (f.depth_out && !(f.depth_opacity > 0.f && f.depth_opacity <= 1.f))
    throw InvalidArgument("depth opacity must be in (0, 1]");
}

}  // namespace render_detail

inline IsoFrame::IsoFrame(Scene const& scene, IsoParams const& p) : p_(&p) {
  render_detail::check_iso(p);
  scene_ = render_detail::prepare_iso(scene, p);
}

inline DvrFrame::DvrFrame(Scene const& scene, DvrParams const& p)
    : setup_(std::make_unique<render_detail::DvrSetup>()), p_(&p) {
  render_detail::prepare_dvr(scene, p, *setup_);
}

inline void render_tile(IsoFrame const& f, Camera const& cam, Tile tile, FrameBuffer const& out, RenderOptions const& o) {
  render_detail::check_camera(cam);
  render_detail::check_tile(cam, tile);
  render_detail::check_frame_buffer(cam, out);
  dispatch<RenderTileEntry>(o.isa, f.prepared(), cam, f.params(), o, tile, out);
}

inline void render_tile(DvrFrame const& f, Camera const& cam, Tile tile, FrameBuffer const& out, RenderOptions const& o) {
  render_detail::check_camera(cam);
  render_detail::check_tile(cam, tile);
  render_detail::check_frame_buffer(cam, out);
  dispatch<RenderTileEntry>(o.isa, f.prepared(), cam, f.params(), o, tile, out);
}

inline void render(Scene const& scene, Camera const& cam, IsoParams const& p, FrameBuffer const& out,
                   RenderOptions const& o) {
  render_detail::check_camera(cam);
  render_detail::check_frame_buffer(cam, out);
  IsoFrame const f(scene, p);
  render_detail::for_tiles(cam, o.tile_size, [&](Tile const& t) {
    dispatch<RenderTileEntry>(o.isa, f.prepared(), cam, p, o, t, out);
  });
}

inline void render(Scene const& scene, Camera const& cam, DvrParams const& p, FrameBuffer const& out,
                   RenderOptions const& o) {
  render_detail::check_camera(cam);
  render_detail::check_frame_buffer(cam, out);
  DvrFrame const f(scene, p);
  render_detail::for_tiles(cam, o.tile_size, [&](Tile const& t) {
    dispatch<RenderTileEntry>(o.isa, f.prepared(), cam, p, o, t, out);
  });
}

inline Image render_iso(Scene const& scene, Camera const& cam, IsoParams const& p, RenderOptions const& o) {
  render_detail::check_camera(cam);
  Image img(cam.width, cam.height);
  render(scene, cam, p, FrameBuffer::of(img), o);
  return img;
}

inline Image render_dvr(Scene const& scene, Camera const& cam, DvrParams const& p, RenderOptions const& o) {
  render_detail::check_camera(cam);
  Image img(cam.width, cam.height);
  render(scene, cam, p, FrameBuffer::of(img), o);
  return img;
}

inline void render_tile(Scene const& scene, Camera const& cam, IsoParams const& p, Tile tile, Image& out,
                        RenderOptions const& o) {
  if (out.width != cam.width || out.height != cam.height) throw InvalidArgument("image size differs from the camera's");
  render_tile(IsoFrame(scene, p), cam, tile, FrameBuffer::of(out), o);
}

inline void render_tile(Scene const& scene, Camera const& cam, DvrParams const& p, Tile tile, Image& out,
                        RenderOptions const& o) {
  if (out.width != cam.width || out.height != cam.height) throw InvalidArgument("image size differs from the camera's");
  render_tile(DvrFrame(scene, p), cam, tile, FrameBuffer::of(out), o);
}

inline std::vector<SurfaceHit> first_hits(Scene const& scene, std::vector<Ray> const& rays, IsoParams const& p,
                                          RenderOptions const& o) {
  render_detail::check_iso(p);
  PreparedScene const s = render_detail::prepare(scene);
  IsoQuery q;
  q.isos.count = int(p.surfaces.size());
  for (int k = 0; k < q.isos.count; ++k) q.isos.values[k] = p.surfaces[size_t(k)].value;
  q.method = p.roots;
  q.normals = p.normals;
  q.traversal = o.traversal;
  q.hybrid_threshold = o.hybrid_threshold;
  std::vector<SurfaceHit> hits(rays.size());
  constexpr uint64_t chunk = 1024;
  uint64_t const n = rays.size();
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, (n + chunk - 1) / chunk), [&](tbb::blocked_range<uint64_t> const& r) {
    std::vector<SurfaceHit> part_hits(chunk);
    for (uint64_t c = r.begin(); c < r.end(); ++c) {
      uint64_t const b = c * chunk, m = std::min(chunk, n - b);
      for (size_t pi = 0; pi < s.parts.size(); ++pi) {
        PreparedPart const& part = s.parts[pi];
        dispatch<FirstHitEntry>(o.isa, part.tree, part.mesh(), rays.data() + b, m, q, part_hits.data());
        for (uint64_t i = 0; i < m; ++i)
          if (part_hits[i].t < hits[b + i].t) hits[b + i] = part_hits[i], hits[b + i].piece = uint32_t(pi);
      }
    }
  });
  return hits;
}

inline void sample_points(Scene const& scene, float const* xyz, uint64_t n, float* out, RenderOptions const& o) {
  PreparedScene const s = render_detail::prepare(scene);
  if (n == 0) return;
  if (!xyz || !out) throw InvalidArgument("sample_points: no points or no output");
  detail::probe_in_order(xyz, n, out, s.lo, s.hi, true, [&](float const* p, uint64_t m, float* v) {
    for (PreparedPart const& part : s.parts) dispatch<ProbeEntry>(o.isa, part.tree, part.mesh(), p, m, v);
  });
}

inline std::vector<float> sample_points(Scene const& scene, std::vector<float> const& xyz, RenderOptions const& o) {
  std::vector<float> out(xyz.size() / 3);
  sample_points(scene, xyz.data(), out.size(), out.data(), o);
  return out;
}

inline void integrate_rays(DvrFrame const& f, Ray const* rays, uint64_t n, float* rgba, float* depth, float depth_at,
                           RenderOptions const& o) {
  if (n == 0) return;
  if (!rays || !rgba) throw InvalidArgument("integrate_rays: no rays or no output");
  if (depth && !(depth_at > 0.f && depth_at <= 1.f)) throw InvalidArgument("depth opacity must be in (0, 1]");
  constexpr uint64_t chunk = 256;  // a multiple of every packet width
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, (n + chunk - 1) / chunk), [&](tbb::blocked_range<uint64_t> const& r) {
    for (uint64_t c = r.begin(); c < r.end(); ++c) {
      uint64_t const b = c * chunk, m = std::min(chunk, n - b);
      dispatch<RayVolumeEntry>(o.isa, f.prepared(), f.params(), o, rays + b, m, rgba + 4 * b, depth ? depth + b : nullptr,
                               depth_at);
    }
  });
}

}  // namespace cellray
