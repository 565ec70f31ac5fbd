#pragma once
// Isosurface rendering (ISA units only): the nearest hit over a scene's
// parts, hit attributes (smooth normals, colour by another array), and the
// tile loop with transparency, shadows and ambient occlusion
// (occlusion_impl.hpp holds the secondary-ray strategies).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "../traverse/cell_ops.hpp"
#include "../traverse/first_hit.hpp"
#include "../traverse/march.hpp"
#include "../traverse/queries_impl.hpp"
#include "occlusion_impl.hpp"
#include "packets_impl.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

/// Per-lane nearest iso hit over every part of the scene.
template <class A> struct SceneHit {
  vfloat<A> t;
  vint<A> iso, item, part;  ///< part: index into PreparedScene::parts
  Vec3<A> grad{};           ///< when asked for: the analytic gradient at the hit (FirstHitQuery::grad)
  Vec3<A> param{};          ///< when asked for, in hexahedral parts: the hit's trilinear coordinates (FirstHitQuery::param)
};

/// The hits of part `part_index`'s query `q` where they are nearer than `best`.
template <class A, int N> inline void keep_nearer(FirstHitQuery<A, N> const& q, int part_index, SceneHit<A>& best) {
  vmask<A> const better = q.hit.t < best.t;
  auto const bi = simd::to_int_mask(better);
  best.t = simd::select(better, q.hit.t, best.t);
  best.iso = simd::select(bi, q.hit.iso, best.iso);
  best.item = simd::select(bi, q.hit.item, best.item);
  best.part = simd::select(bi, vint<A>(part_index), best.part);
  if (q.want_gradient) best.grad = select<A>(better, q.grad, best.grad);
  if (q.want_param) best.param = select<A>(better, q.param, best.param);
}

template <class A, int N>
inline void hit_part(PreparedPart const& part, CellMesh<N> const& mesh, RayPacket<A> const& r, vmask<A> active,
                     IsoSet const& isos, CellIsoOptions const& roots, Traversal how, int threshold, int part_index,
                     SceneHit<A>& best, bool gradient, bool param) {
  FirstHitQuery<A, N> q{part.tree, mesh, r, isos, roots, {best.t, vint<A>(-1), vint<A>(-1)}};
  q.want_gradient = gradient;
  q.want_param = param && CellOps<A, N>::keeps_param;
  switch (how) {
    case Traversal::packet: traverse_packet<A>(part.tree, r, active, q); break;
    case Traversal::hybrid: traverse_packet<A>(part.tree, r, active, q, 0, threshold); break;
    case Traversal::spmd: traverse_spmd<A>(part.tree, r, active, q); break;
  }
  keep_nearer<A>(q, part_index, best);
}

/// `gradient`: hits also bring their analytic gradient (SceneHit::grad);
/// `param`: hits in hexahedra their trilinear coordinates (SceneHit::param).
template <class A>
inline SceneHit<A> nearest_hit(PreparedScene const& s, RayPacket<A> const& r, vmask<A> active, IsoSet const& isos,
                               CellIsoOptions const& roots, Traversal how, int threshold, bool gradient = false,
                               bool param = false) {
  // Members one by one: aggregate initialisation zeroed all 7 vectors with
  // `rep stos` first (g++ 12), a slow start-up on every packet.
  SceneHit<A> best;
  best.t = r.tmax;
  best.iso = best.item = best.part = vint<A>(-1);
  for (size_t p = 0; p < s.parts.size(); ++p) {
    PreparedPart const& part = s.parts[p];
    part.visit([&](auto const& mesh, auto const*) {
      hit_part<A>(part, mesh, r, active, isos, roots, how, threshold, int(p), best, gradient, param);
    });
  }
  return best;
}

/// nearest_hit for K packets at once through each part's tree
/// (traverse_packets, packet traversal): per packet the hits nearest_hit
/// finds. `active[k]`: packet k's lanes.
template <class A, int K>
inline void nearest_hits(PreparedScene const& s, RayPacket<A> const (&r)[K], uint32_t const (&active)[K],
                         IsoSet const& isos, CellIsoOptions const& roots, bool gradient, bool param,
                         SceneHit<A> (&best)[K]) {
  vmask<A> lanes[K];
  for (int k = 0; k < K; ++k) {
    best[k].t = r[k].tmax;
    best[k].iso = best[k].item = best[k].part = vint<A>(-1);
    lanes[k] = simd::mask_from_bits<A>(active[k]);
  }
  for (size_t pi = 0; pi < s.parts.size(); ++pi) {
    PreparedPart const& part = s.parts[pi];
    part.visit([&](auto const& mesh, auto const*) {
      constexpr int N = std::decay_t<decltype(mesh)>::corners;
      auto query = [&](int k) {
        FirstHitQuery<A, N> q{part.tree, mesh, r[k], isos, roots, {best[k].t, vint<A>(-1), vint<A>(-1)}};
        q.want_gradient = gradient;
        q.want_param = param && CellOps<A, N>::keeps_param;
        return q;
      };
      auto q = make_array<K>(query);
      FirstHitGroup<A, N, K> group(q.data(), r, lanes);
      traverse_packets<A, K>(part.tree, r, lanes, group);
      for (int k = 0; k < K; ++k) keep_nearer<A>(q[k], int(pi), best[k]);
    });
  }
}

/// Whether the part's hits bring their cell coordinates (CellOps::keeps_param).
inline bool keeps_param(PreparedPart const& part) {
  return part.visit([](auto const& mesh, auto const*) {
    return CellOps<scalar, std::decay_t<decltype(mesh)>::corners>::keeps_param;
  });
}

/// Unit shading normal at a hit point `p` (two-sided: faces against `dir`).
inline glm::vec3 normal_at(PreparedPart const& part, uint64_t slot, glm::vec3 p, glm::vec3 dir, GradientMethod m) {
  uint64_t const cell = part.tree.item(slot);
  Ray const at_hit{p, 0.f, dir, 0.f};  // t = 0 is the hit point itself
  return part.visit([&](auto const& mesh, auto const*) { return hit_normal(mesh, cell, at_hit, 0.f, m); });
}

/// Where `p` lies in `cell`: its vertex ids in the kernels' corner order and
/// the cell's shape functions there, to interpolate any per-vertex quantity
/// at an isosurface hit (smooth normals, colour by another array). NaN
/// weights where a location fails (a hex inversion that did not converge).
/// `param`, if given and in the cell: the cell coordinates at `p`, known
/// already (CellOps::keeps_param: the root search's), so nothing is
/// located: inverting each hexahedral hit again was a quarter of a
/// boxturb48 iso frame. Coordinates outside the cell (a root search that
/// did not converge, in a badly shaped cell) are located again.
template <int N> struct CellWeights {
  uint64_t v[N];
  float w[N];
};
template <int N>
inline CellWeights<N> cell_weights(CellMesh<N> const& mesh, uint64_t cell, glm::vec3 const& p,
                                   glm::vec3 const* param = nullptr) {
  using Ops = CellOps<scalar, N>;
  CellWeights<N> out;
  if constexpr (Ops::keeps_param) {
    if (param && Ops::param_in_cell(Vec3<scalar>{param->x, param->y, param->z})) {
      for (int i = 0; i < N; ++i) out.v[i] = mesh.vertex(cell, i);
      Ops::shape_weights(Vec3<scalar>{param->x, param->y, param->z}, out.w);
      return out;
    }
  }
  ScalarCorners<N> k;
  read_corner_values(mesh, cell, k);
  order_corners(mesh.vertex_count(), k);
  CellCorners<scalar, N> const c = broadcast<scalar, N>(mesh, k);
  Located<scalar> const at = Ops::locate(PointBatch<scalar>{p.x, p.y, p.z}, c);
  for (int i = 0; i < N; ++i) out.v[i] = k.v[i];
  if (!at.converged || !std::isfinite(at.param.x + at.param.y + at.param.z))
    for (float& x : out.w) x = std::numeric_limits<float>::quiet_NaN();
  else
    Ops::shape_weights(at.param, out.w);
  return out;
}

/// At an isosurface hit `p` in the hit cell `slot` of a part, from one point
/// location: the smooth shading normal facing against `dir` (if `normal`;
/// GradientMethod::smooth: the vertex gradients interpolated, or the cell's
/// analytic normal where that is NaN or zero) and the colour array's value
/// (if `value`; NaN where a corner is NaN). `param`: see cell_weights.
inline void hit_attributes(PreparedPart const& part, uint64_t slot, glm::vec3 const& p, glm::vec3 const& dir,
                           glm::vec3* normal, float* value, glm::vec3 const* param = nullptr) {
  uint64_t const cell = part.tree.item(slot);
  glm::vec3 g(0.f);
  part.visit([&](auto const& mesh, auto const*) {
    auto const cw = cell_weights(mesh, cell, p, param);
    float v = 0.f;
    for (int i = 0; i < std::decay_t<decltype(mesh)>::corners; ++i) {
      if (normal)
        for (int a = 0; a < 3; ++a) g[a] += cw.w[i] * part.gradients[3 * cw.v[i] + uint64_t(a)];
      if (value) v += cw.w[i] * part.color_values[cw.v[i]];
    }
    if (value) *value = v;
  });
  if (!normal) return;
  float const gg = glm::dot(g, g);
  if (!(gg > 0.f) || !std::isfinite(gg)) {
    *normal = normal_at(part, slot, p, dir, GradientMethod::analytic);
    return;
  }
  Vec3<scalar> const d{dir.x, dir.y, dir.z};
  Vec3<scalar> const n = face_forward<scalar>(shading_normal<scalar>(Vec3<scalar>{g.x, g.y, g.z}, d), d);
  *normal = {n.x, n.y, n.z};
}

/// hit_attributes for the hit lanes `lanes` of one part at once, where the
/// mesh fits gather_corners' 32-bit offsets (else no lane): tets located in
/// SIMD, hexahedra at `param` (SceneHit::param); `normal` (smooth normals)
/// and `value` (colour by) of the lanes it returns. The rest, per lane
/// (hit_attributes): hex coordinates outside the cell, and, for normals, a
/// zero or non-finite interpolated gradient (the analytic normal's case).
/// Lane by lane in scalar, smooth normals took 15% of a component8 iso frame.
template <class A, int N>
inline vmask<A> hit_attributes_packet(PreparedPart const& part, CellMesh<N> const& mesh, vmask<A> lanes,
                                      vint<A> const& slots, Vec3<A> const& pos, Vec3<A> const& param,
                                      Vec3<A> const& dir, bool smooth, bool colour, Vec3<A>& normal,
                                      vfloat<A>& value) {
  constexpr uint64_t lim = uint64_t(std::numeric_limits<int32_t>::max());
  if (!mesh.has_32bit_indices() || !(mesh.cell_count() * N < lim) || !(mesh.vertex_count() * 3 < lim))
    return simd::no_lanes<A>();
  vint<A> const cells = simd::select(simd::to_int_mask(lanes), slot_cells<A>(part.tree, slots, lanes), vint<A>(0));
  using Ops = CellOps<A, N>;
  vfloat<A> w[N];
  vint<A> id[N];
  if constexpr (Ops::keeps_param) {
    lanes = lanes && Ops::param_in_cell(param);
    if (simd::none(lanes)) return lanes;
    Ops::shape_weights(param, w);
    auto const* idx = reinterpret_cast<int32_t const*>(mesh.indices32());
    for (int i = 0; i < N; ++i) id[i] = simd::gather(idx, cells * vint<A>(N) + vint<A>(i));
  } else {
    CellCorners<A, N> const c = gather_corners<A, N>(mesh, cells, lanes);  // c.id: vertex ids (fast gathers)
    Ops::shape_weights(Ops::locate(PointBatch<A>{pos.x, pos.y, pos.z}, c).param, w);
    for (int i = 0; i < N; ++i) id[i] = c.id[i];
  }
  Vec3<A> g{vfloat<A>(0.f), vfloat<A>(0.f), vfloat<A>(0.f)};
  vfloat<A> sum(0.f);
  for (int i = 0; i < N; ++i) {
    if (smooth) {
      vint<A> const k = id[i] * vint<A>(3);
      g.x = g.x + w[i] * simd::gather(part.gradients, k);
      g.y = g.y + w[i] * simd::gather(part.gradients + 1, k);
      g.z = g.z + w[i] * simd::gather(part.gradients + 2, k);
    }
    if (colour) sum = sum + w[i] * simd::gather(part.color_values, id[i]);
  }
  if (colour) value = sum;
  if (!smooth) return lanes;
  vfloat<A> const gg = dot(g, g);
  lanes = lanes && gg > vfloat<A>(0.f) && gg < vfloat<A>(std::numeric_limits<float>::infinity());  // false for NaN
  normal = face_forward<A>(shading_normal<A>(g, dir), dir);
  return lanes;
}

/// Lane `l` of a Vec3 stored as three arrays.
template <size_t W> inline glm::vec3 lane_vec(std::array<float, W> const (&v)[3], int l) {
  return {v[0][size_t(l)], v[1][size_t(l)], v[2][size_t(l)]};
}

/// The colour of value v in a ColorTable (linear between entries).
inline glm::vec3 table_color(ColorTable const& c, float v) {
  float const x = std::min(std::max((v - c.lo) * c.scale, 0.f), float(ColorTable::entries - 1));
  int const i = std::min(int(x), ColorTable::entries - 2);
  float const f = x - float(i);
  float const* a = c.rgb[i];
  float const* b = c.rgb[i + 1];
  return {a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2])};
}

/// The field at o + t d of each lane in `lanes`, from the first part that
/// holds the point (NaN outside the mesh and in NaN cells).
template <class A>
inline vfloat<A> values_at(PreparedScene const& s, RayPacket<A> const& r, vfloat<A> const& t, vmask<A> const& lanes,
                           Traversal how, int threshold) {
  constexpr int W = width<A>;
  ValueWindows const everything;
  alignas(64) float out[W];
  for (int l = 0; l < W; ++l) out[l] = std::numeric_limits<float>::quiet_NaN();
  for (PreparedPart const& part : s.parts) {
    part.visit([&](auto const& mesh, auto const*) {
      constexpr int N = std::decay_t<decltype(mesh)>::corners;
      SampleQuery<A, N> q(part.tree, mesh, r, everything, t, 0.f, 1, lanes);
      sample_group(q, lanes, how, threshold);
      for (int l = 0; l < W; ++l)
        if (!(out[l] == out[l])) out[l] = q.values[0][l];
    });
  }
  return simd::load<A>(out);
}

template <class A>
void render_iso_tile(PreparedScene const& s, Camera const& cam, IsoParams const& p, RenderOptions const& o,
                     Tile const& tile, FrameBuffer const& out) {
  constexpr int W = width<A>;
  int const threshold = o.hybrid_threshold > 0 ? o.hybrid_threshold : std::max(1, W / 4);
  IsoSet isos;
  isos.count = int(p.surfaces.size());
  for (int k = 0; k < isos.count; ++k) isos.values[k] = p.surfaces[size_t(k)].value;
  float const eps = 1e-5f * s.diagonal;
  float const ao_radius = p.ao_radius > 0.f ? p.ao_radius : 0.05f * s.diagonal;
  bool const headlight = !(glm::length(p.light_dir) > 0.f);
  glm::vec3 const light = headlight ? glm::vec3(0.f) : glm::normalize(p.light_dir);
  // Analytic normals come with the hits: the iso query computes the
  // gradient once per hit cell from the corners it already loaded (tets:
  // constant per cell; hexes: at the hit's coordinates). Central differences
  // locate each hit again, per lane (normal_at).
  bool const query_gradient = p.normals == GradientMethod::analytic;
  bool const smooth = p.normals == GradientMethod::smooth;
  // Smooth normals and colour by another array interpolate at the hit;
  // hexahedra bring the hit's coordinates from the root search for it.
  bool const attributes = smooth || s.color_by;
  bool const param_attributes = attributes && std::any_of(s.parts.begin(), s.parts.end(), keeps_param);
  // Any-hit shadow rays need one opacity for every surface (see the shadow block).
  bool const secondary = p.shadows || p.ao_samples > 0;
  // AO rays march from their hit cells where the scene allows (one part,
  // with face neighbours, or a mixed mesh's two parts, linked, as DVR
  // marches them); elsewhere `march` is `grouped`.
  bool const march_ao = o.secondary_query == SecondaryQuery::march &&
                        ((s.parts.size() == 1 && s.parts[0].marches()) || s.mixed_march);
  bool one_opacity = true;
  for (IsoSurface const& surf : p.surfaces) one_opacity = one_opacity && surf.opacity == p.surfaces[0].opacity;
  vfloat<A> const zero(0.f), one(1.f);
  Vec3<A> const eye{vfloat<A>(cam.eye.x), vfloat<A>(cam.eye.y), vfloat<A>(cam.eye.z)};
  bool const clipping = s.clip.count > 0;

  // Eight neighbouring pixel blocks (group_x x group_y) find their hits in
  // one traversal per layer (nearest_hits): their rays are coherent, so
  // nodes and leaves are visited, and cells read and set up, once for the
  // group. Each packet's clip span and caps come first.
  // (Eight blocks in one 128-bit lane set, not a mask per packet, were 7%
  // slower on component8 than four.)
  constexpr int GX = group_x<A>, GY = group_y<A>, K = GX * GY;
  bool const grouped = o.traversal == Traversal::packet;
  for (int gy = tile.y0; gy < tile.y0 + tile.h; gy += GY * block_h<A>)
    for (int gx = tile.x0; gx < tile.x0 + tile.w; gx += GX * block_w<A>) {
      int gpx[K][W], gpy[K][W];
      uint32_t gvalid[K] = {}, glive[K] = {};
      RayPacket<A> gr[K];
      // Per packet before its first hit: colour and depth of the clip's caps.
      vfloat<A> gcr[K], gcg[K], gcb[K], galpha[K], gdepth[K];
      for (int pk = 0; pk < K; ++pk) {
        int const bx = gx + (pk % GX) * block_w<A>, by = gy + (pk / GX) * block_h<A>;
        if (bx >= tile.x0 + tile.w || by >= tile.y0 + tile.h) {
          gr[pk] = gr[0];  // no lanes (block 0 is always in the tile)
          continue;
        }
        gr[pk] = camera_packet<A>(cam, tile, bx, by, gpx[pk], gpy[pk], gvalid[pk]);
        gr[pk].tmin = zero;
        // The host's opaque geometry hides what lies behind it.
        gr[pk].tmax = host_depth<A>(out, gpx[pk], gpy[pk], gvalid[pk]);
        gcr[pk] = gcg[pk] = gcb[pk] = galpha[pk] = zero;
        gdepth[pk] = vfloat<A>(std::numeric_limits<float>::infinity());
        glive[pk] = gvalid[pk];
        if (clipping) {
          RayPacket<A>& r = gr[pk];
          Vec3<A> const dir = ray_batch(r).dir();
          ClipSpan<A> const cs = clip_span<A>(s.clip, r, zero, r.tmax);
          r.tmin = cs.t0, r.tmax = cs.t1;
          glive[pk] &= simd::movemask(cs.t0 <= cs.t1);
          uint32_t const entering = glive[pk] & simd::movemask(simd::to_float_mask(cs.entry >= vint<A>(0)));
          if (s.clip.caps && entering) {
            // A cap: the cut face where the ray enters the region inside the
            // mesh, opaque, in front of everything the region holds.
            auto const v = simd::to_array<A>(values_at<A>(s, r, cs.t0, simd::mask_from_bits<A>(entering), o.traversal,
                                                          threshold));
            auto const plane = simd::to_array<A>(cs.entry);
            std::array<float, W> const dir_x = simd::to_array<A>(dir.x), dir_y = simd::to_array<A>(dir.y),
                                       dir_z = simd::to_array<A>(dir.z);
            alignas(64) float cr_[W] = {}, cg_[W] = {}, cb_[W] = {}, ca_[W] = {};
            uint32_t capped = 0;
            for (uint32_t bits = entering; bits; bits &= bits - 1) {
              int const l = __builtin_ctz(bits);
              if (!std::isfinite(v[size_t(l)])) continue;
              int const k = plane[size_t(l)];
              glm::vec3 const n(s.clip.nx[k], s.clip.ny[k], s.clip.nz[k]);  // faces the eye: the ray enters against it
              glm::vec3 const d = glm::normalize(glm::vec3(dir_x[size_t(l)], dir_y[size_t(l)], dir_z[size_t(l)]));
              glm::vec3 const to_l = headlight ? -d : light;
              float const ndl = std::max(0.f, glm::dot(n, to_l));
              float const ndh = std::max(0.f, glm::dot(n, glm::normalize(to_l - d)));
              float const spec = ndl > 0.f ? p.specular * std::pow(ndh, p.shininess) : 0.f;
              glm::vec3 const c =
                  glm::min(table_color(s.clip.cap_colors, v[size_t(l)]) * (p.ambient + p.diffuse * ndl) + spec, 1.f);
              cr_[l] = c.r, cg_[l] = c.g, cb_[l] = c.b, ca_[l] = 1.f;
              capped |= 1u << l;
            }
            gcr[pk] = simd::load<A>(cr_), gcg[pk] = simd::load<A>(cg_), gcb[pk] = simd::load<A>(cb_);
            galpha[pk] = simd::load<A>(ca_);
            gdepth[pk] = simd::select(simd::mask_from_bits<A>(capped), cs.t0, gdepth[pk]);
            glive[pk] &= ~capped;
          }
        }
      }
      // Front-to-back layers: continue behind semi-transparent surfaces,
      // each layer's hits of the group's packets in one traversal.
      vfloat<A> const depth_at(out.depth_opacity);
      auto const any_live = [&glive] {
        uint32_t any = 0;
        for (uint32_t l : glive) any |= l;
        return any != 0;
      };
      for (int layer = 0; layer < 16 && any_live(); ++layer) {
        SceneHit<A> hits[K];
        if (grouped) nearest_hits<A, K>(s, gr, glive, isos, p.roots, query_gradient, param_attributes, hits);
        for (int pk = 0; pk < K; ++pk) {
          uint32_t& live = glive[pk];
          if (!live) continue;
          int const(&px)[W] = gpx[pk];
          int const(&py)[W] = gpy[pk];
          RayPacket<A>& r = gr[pk];
          Vec3<A> const dir = ray_batch(r).dir();
          vfloat<A>& color_r = gcr[pk];
          vfloat<A>& color_g = gcg[pk];
          vfloat<A>& color_b = gcb[pk];
          vfloat<A>& alpha = galpha[pk];
          vfloat<A>& depth = gdepth[pk];
          SceneHit<A> const h = grouped ? hits[pk]
                                        : nearest_hit<A>(s, r, simd::mask_from_bits<A>(live), isos, p.roots,
                                                         o.traversal, threshold, query_gradient, param_attributes);
          vmask<A> const hit = simd::mask_from_bits<A>(live) && simd::to_float_mask(h.item >= vint<A>(0));
          uint32_t hit_bits = simd::movemask(hit);
          if (!hit_bits) {
            live = 0;
            continue;
          }
          // Hit points, normals and the light, all lanes at once (lanes
          // without a hit compute garbage nobody reads); the shadow and AO
          // rays below read them per lane.
          vfloat<A> const t = simd::select(hit, h.t, zero);
          Vec3<A> const hit_pos = eye + t * dir;
          Vec3<A> normal{};
          if (query_gradient) normal = face_forward<A>(shading_normal<A>(h.grad, dir), dir);
          Vec3<A> const to_light = headlight ? vfloat<A>(-1.f) * normalized<A>(dir)
                                             : Vec3<A>{vfloat<A>(light.x), vfloat<A>(light.y), vfloat<A>(light.z)};
          std::array<float, W> const pos_a[3] = {simd::to_array<A>(hit_pos.x), simd::to_array<A>(hit_pos.y),
                                                 simd::to_array<A>(hit_pos.z)};
          std::array<float, W> const ldir_a[3] = {simd::to_array<A>(to_light.x), simd::to_array<A>(to_light.y),
                                                  simd::to_array<A>(to_light.z)};
          std::array<float, W> nrm_a[3] = {simd::to_array<A>(normal.x), simd::to_array<A>(normal.y),
                                           simd::to_array<A>(normal.z)};
          auto const iso = simd::to_array<A>(h.iso), item = simd::to_array<A>(h.item), part = simd::to_array<A>(h.part);
          // Smooth normals and colour values, part by part for all hit lanes
          // at once; the lanes that leaves go one by one below.
          uint32_t packet_done = 0;
          std::array<float, W> packet_normal[3] = {}, packet_value = {}, param_a[3] = {};
          if (attributes) {
            Vec3<A> pn{};
            vfloat<A> pv(std::numeric_limits<float>::quiet_NaN());
            for (size_t pi = 0; pi < s.parts.size(); ++pi) {
              vmask<A> const in_part = hit && simd::to_float_mask(h.part == vint<A>(int32_t(pi)));
              if (simd::none(in_part)) continue;
              PreparedPart const& pp = s.parts[pi];
              Vec3<A> n{};
              vfloat<A> v(0.f);
              vmask<A> const done = pp.visit([&](auto const& mesh, auto const*) {
                return hit_attributes_packet<A>(pp, mesh, in_part, h.item, hit_pos, h.param, dir, smooth, s.color_by, n,
                                                v);
              });
              pn = select<A>(done, n, pn);
              pv = simd::select(done, v, pv);
              packet_done |= simd::movemask(done);
            }
            packet_normal[0] = simd::to_array<A>(pn.x), packet_normal[1] = simd::to_array<A>(pn.y),
            packet_normal[2] = simd::to_array<A>(pn.z), packet_value = simd::to_array<A>(pv);
            if (param_attributes && (hit_bits & ~packet_done))
              param_a[0] = simd::to_array<A>(h.param.x), param_a[1] = simd::to_array<A>(h.param.y),
              param_a[2] = simd::to_array<A>(h.param.z);
          }
          glm::vec3 pos[W], nrm[W], ldir[W];
          alignas(64) float base_r[W] = {}, base_g[W] = {}, base_b[W] = {}, opacity[W] = {};
          std::array<float, W> dir_a[3];
          if (!query_gradient) dir_a[0] = simd::to_array<A>(dir.x), dir_a[1] = simd::to_array<A>(dir.y),
                               dir_a[2] = simd::to_array<A>(dir.z);
          for (uint32_t bits = hit_bits; bits; bits &= bits - 1) {
            int const l = __builtin_ctz(bits);
            PreparedPart const& hit_part = s.parts[size_t(part[l])];
            glm::vec3 n(0.f);
            float colour_value = std::numeric_limits<float>::quiet_NaN();
            if (attributes && (packet_done >> l & 1u)) {
              if (smooth) n = lane_vec<W>(packet_normal, l);
              if (s.color_by) colour_value = packet_value[size_t(l)];
            } else if (attributes) {  // one location of the hit for both
              bool const with_param = keeps_param(hit_part);
              glm::vec3 const param = with_param ? lane_vec<W>(param_a, l) : glm::vec3(0.f);
              hit_attributes(hit_part, uint64_t(item[l]), lane_vec<W>(pos_a, l),
                             // dir_a is filled when normals are not analytic
                             smooth ? lane_vec<W>(dir_a, l) : glm::vec3(0.f),
                             smooth ? &n : nullptr, s.color_by ? &colour_value : nullptr,
                             with_param ? &param : nullptr);
            }
            if (!query_gradient) {
              if (!smooth)
                n = normal_at(hit_part, uint64_t(item[l]), lane_vec<W>(pos_a, l), lane_vec<W>(dir_a, l), p.normals);
              nrm_a[0][size_t(l)] = n.x, nrm_a[1][size_t(l)] = n.y, nrm_a[2][size_t(l)] = n.z;
            }
            // Per-lane copies only for the shadow and AO rays below.
            if (secondary)
              pos[l] = lane_vec<W>(pos_a, l), ldir[l] = lane_vec<W>(ldir_a, l), nrm[l] = lane_vec<W>(nrm_a, l);
            IsoSurface const& surf = p.surfaces[size_t(iso[l])];
            glm::vec3 const base = std::isfinite(colour_value) ? table_color(s.colors, colour_value) : surf.color;
            base_r[l] = base.r, base_g[l] = base.g, base_b[l] = base.b;
            opacity[l] = surf.opacity;
          }
          if (!query_gradient) normal = {simd::load<A>(nrm_a[0].data()), simd::load<A>(nrm_a[1].data()),
                                         simd::load<A>(nrm_a[2].data())};
          float visibility[W], occlusion[W];
          for (int l = 0; l < W; ++l) visibility[l] = 1.f, occlusion[l] = 0.f;
          // Shadow and AO rays (RenderOptions::secondary_query). Any-hit
          // queries give the nearest hit's answer whenever only its existence
          // matters: AO always, shadows when every surface has one opacity.
          bool const any_hit = o.secondary_query != SecondaryQuery::nearest;
          if (hit_bits && p.shadows) {
            Ray sr[W];
            for (int l = 0; l < W; ++l) {
              bool const h1 = (hit_bits >> l) & 1u;
              glm::vec3 const o = pos[l] + eps * nrm[l];
              float const far = clipping && h1 ? clip_exit(s.clip, o, ldir[l], std::numeric_limits<float>::infinity())
                                               : std::numeric_limits<float>::infinity();
              sr[l] = Ray{h1 ? o : cam.eye, h1 ? eps : 0.f, h1 ? ldir[l] : glm::vec3(0, 0, 1),
                          h1 ? std::max(eps, far) : -1.f};
            }
            RayPacket<A> const srp = load_rays<A>(sr, W);
            if (any_hit && one_opacity) {
              vmask<A> const lanes = simd::mask_from_bits<A>(hit_bits);
              // Every any-hit query (grouped too) traces a pixel block's shadow
              // rays as one packet: they leave nearby points in one direction,
              // so the packet clip's lanes are mostly busy. (Through
              // occluded_packets' (cell, ray) pairs instead: 20% fewer
              // instructions, callgrind AVX2, but a 2.5-3% slower frame,
              // AVX-512 and AVX2 on an AMD EPYC, component8 and a 2M-tet mesh.)
              uint32_t const occ =
                  simd::movemask(scene_occluded<A>(s, srp, lanes, isos, p.roots, o.secondary_traversal, threshold));
              for (int l = 0; l < W; ++l)
                if ((hit_bits & occ) >> l & 1u) visibility[l] = 1.f - p.surfaces[0].opacity;
            } else {
              SceneHit<A> const sh = nearest_hit<A>(s, srp, simd::mask_from_bits<A>(hit_bits), isos, p.roots,
                                                    o.secondary_traversal, threshold);
              auto const sitem = simd::to_array<A>(sh.item), siso = simd::to_array<A>(sh.iso);
              for (int l = 0; l < W; ++l)
                if (((hit_bits >> l) & 1u) && sitem[l] >= 0) visibility[l] = 1.f - p.surfaces[size_t(siso[l])].opacity;
            }
          }
          // AO ray k of lane l (a hit lane): cosine-weighted about the normal,
          // directions from the pixel's hash (the same on every ISA).
          auto const ao_ray = [&](int l, int k) {
            uint32_t const pix = uint32_t(py[l]) * uint32_t(cam.width) + uint32_t(px[l]);
            float const u1 = pixel_hash01(pix, uint32_t(2 * k + 64 * layer));
            float const u2 = pixel_hash01(pix, uint32_t(2 * k + 1 + 64 * layer));
            float const rr = std::sqrt(u1), phi = 6.2831853f * u2;
            glm::vec3 const n = nrm[l];
            glm::vec3 const a = std::fabs(n.x) > 0.5f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
            glm::vec3 const tx = glm::normalize(glm::cross(a, n)), ty = glm::cross(n, tx);
            glm::vec3 const d =
                rr * std::cos(phi) * tx + rr * std::sin(phi) * ty + std::sqrt(std::max(0.f, 1.f - u1)) * n;
            glm::vec3 const o = pos[l] + eps * nrm[l];
            return Ray{o, eps, d, clipping ? std::max(eps, clip_exit(s.clip, o, d, ao_radius)) : ao_radius};
          };
          bool const regroup = o.secondary_query == SecondaryQuery::sorted ||
                               o.secondary_query == SecondaryQuery::grouped ||
                               (o.secondary_query == SecondaryQuery::march && !march_ao);
          if (hit_bits && p.ao_samples > 0 && march_ao) {
            // Each hit lane's AO rays march from its hit cell; what a march
            // cannot finish (it left the mesh, or its origin lies just outside
            // the hit cell) goes on from where it got to through the grouped
            // query, a chunk of samples at a time.
            constexpr int chunk = std::min(4, max_sorted_rays / W);
            PreparedPart const& part = s.parts[0];
            vmask<A> const lanes = simd::mask_from_bits<A>(hit_bits);
            // h.item: item-list slots of the hit's part (a mixed march: the
            // tets, part 0, or the hexahedra, part 1)
            vmask<A> const in_second = lanes && simd::to_float_mask(h.part == vint<A>(1));
            vint<A> hit_cells = slot_cells<A>(part.tree, h.item, lanes && !in_second);
            if (s.mixed_march && simd::any(in_second))
              hit_cells = simd::select(simd::to_int_mask(in_second), slot_cells<A>(s.parts[1].tree, h.item, in_second),
                                       hit_cells);
            Ray rest[W * chunk];
            uint8_t owner[W * chunk];
            uint64_t occ_rest[(W * chunk + 63) / 64];
            for (int k0 = 0; k0 < p.ao_samples; k0 += chunk) {
              int n = 0;
              for (int k = k0; k < std::min(p.ao_samples, k0 + chunk); ++k) {
                Ray ar[W];
                for (int l = 0; l < W; ++l)
                  ar[l] = (hit_bits >> l) & 1u ? ao_ray(l, k) : Ray{cam.eye, 0.f, glm::vec3(0, 0, 1), -1.f};
                RayPacket<A> const arp = load_rays<A>(ar, W);
                vmask<A> undecided;
                vfloat<A> t_done;
                vmask<A> occ_lanes;
                if (s.mixed_march) {
                  PartCells<4> const& t = *s.parts[0].cells_of<4>();  // prepare() checked both
                  PartCells<8> const& hx = *s.parts[1].cells_of<8>();
                  occ_lanes = march_occluded<A>(s.parts[0].tree, *t.mesh, *t.neighbours, s.parts[1].tree, *hx.mesh,
                                                *hx.neighbours, arp, lanes, hit_cells, in_second, isos, p.roots,
                                                undecided, t_done);
                } else {
                  occ_lanes = part.visit([&](auto const& mesh, auto const* neighbours) {
                    return march_occluded<A>(part.tree, mesh, *neighbours, arp, lanes, hit_cells, isos, p.roots,
                                             undecided, t_done);
                  });
                }
                uint32_t const occ = simd::movemask(occ_lanes) & hit_bits;
                for (int l = 0; l < W; ++l)
                  if (occ >> l & 1u) occlusion[l] += 1.f / float(p.ao_samples);
                auto const from = simd::to_array<A>(t_done);
                for (uint32_t b = simd::movemask(undecided); b; b &= b - 1) {
                  int const l = __builtin_ctz(b);
                  rest[n] = ar[l], rest[n].tmin = from[size_t(l)], owner[n] = uint8_t(l), ++n;
                }
              }
              if (n == 0) continue;
              scene_occluded_sorted<A>(s, rest, n, isos, p.roots, o.secondary_traversal, threshold, true, occ_rest);
              for (int i = 0; i < n; ++i)
                if (occ_rest[i / 64] >> (i % 64) & 1u) occlusion[owner[i]] += 1.f / float(p.ao_samples);
            }
          }
          if (hit_bits && p.ao_samples > 0 && regroup) {
            // A chunk of samples of every hit lane, regrouped by direction.
            constexpr int chunk = std::min(4, max_sorted_rays / W);
            Ray ar[W * chunk];
            uint8_t owner[W * chunk];
            uint64_t occ[(W * chunk + 63) / 64];
            for (int k0 = 0; k0 < p.ao_samples; k0 += chunk) {
              int n = 0;
              for (int k = k0; k < std::min(p.ao_samples, k0 + chunk); ++k)
                for (uint32_t b = hit_bits; b; b &= b - 1) {
                  int const l = __builtin_ctz(b);
                  ar[n] = ao_ray(l, k), owner[n] = uint8_t(l), ++n;
                }
              scene_occluded_sorted<A>(s, ar, n, isos, p.roots, o.secondary_traversal, threshold,
                                       o.secondary_query == SecondaryQuery::grouped, occ);
              for (int i = 0; i < n; ++i)
                if (occ[i / 64] >> (i % 64) & 1u) occlusion[owner[i]] += 1.f / float(p.ao_samples);
            }
          }
          for (int k = 0; hit_bits && k < p.ao_samples && !regroup && !march_ao; ++k) {
            Ray ar[W];
            for (int l = 0; l < W; ++l)
              ar[l] = (hit_bits >> l) & 1u ? ao_ray(l, k) : Ray{cam.eye, 0.f, glm::vec3(0, 0, 1), -1.f};
            RayPacket<A> const arp = load_rays<A>(ar, W);
            uint32_t occ = 0;
            if (any_hit) {
              occ = simd::movemask(scene_occluded<A>(s, arp, simd::mask_from_bits<A>(hit_bits), isos, p.roots,
                                                     o.secondary_traversal, threshold));
            } else {
              SceneHit<A> const ah = nearest_hit<A>(s, arp, simd::mask_from_bits<A>(hit_bits), isos, p.roots,
                                                    o.secondary_traversal, threshold);
              occ = simd::movemask(simd::to_float_mask(ah.item >= vint<A>(0)));
            }
            for (int l = 0; l < W; ++l)
              if ((hit_bits & occ) >> l & 1u) occlusion[l] += 1.f / float(p.ao_samples);
          }
          // Lambert + Blinn-Phong, W lanes at once.
          Vec3<A> const to_eye = vfloat<A>(-1.f) * normalized<A>(dir);
          vfloat<A> const ndl = simd::max(zero, dot(normal, to_light));
          vfloat<A> const ndh = simd::max(zero, dot(normal, normalized<A>(to_light + to_eye)));
          vfloat<A> const vis = simd::load<A>(visibility);
          vfloat<A> const spec =
              simd::select(ndl > zero, vfloat<A>(p.specular) * pow_batch<A>(ndh, p.shininess) * vis, zero);
          vfloat<A> const light_in =
              vfloat<A>(p.ambient) * (one - simd::load<A>(occlusion)) + vfloat<A>(p.diffuse) * ndl * vis;
          // Ambient + diffuse + specular can sum past 1 (defaults: 0.2 + 0.7 +
          // 0.25); the image holds [0, 1] (image.hpp), so clamp here, before
          // compositing, not only when writing 8 bits.
          vfloat<A> const a = simd::select(hit, simd::load<A>(opacity) * (one - alpha), zero);
          color_r = color_r + a * simd::min(simd::load<A>(base_r) * light_in + spec, one);
          color_g = color_g + a * simd::min(simd::load<A>(base_g) * light_in + spec, one);
          color_b = color_b + a * simd::min(simd::load<A>(base_b) * light_in + spec, one);
          depth = simd::select(hit && alpha < depth_at && alpha + a >= depth_at, t, depth);
          alpha = alpha + a;
          vmask<A> const next = hit && alpha < vfloat<A>(0.99f);
          r.tmin = simd::select(next, t + simd::max(vfloat<A>(eps), vfloat<A>(1e-5f) * t), r.tmin);
          live = simd::movemask(next);
        }
      }
      for (int pk = 0; pk < K; ++pk) {
        if (!gvalid[pk]) continue;
        int const(&px)[W] = gpx[pk];
        int const(&py)[W] = gpy[pk];
        uint32_t const valid = gvalid[pk];
        vfloat<A> const color_r = gcr[pk], color_g = gcg[pk], color_b = gcb[pk], alpha = galpha[pk];
        vfloat<A> const depth = gdepth[pk];
        vfloat<A> const bg_a(p.background.a), rest = (one - alpha) * bg_a;
        auto const cr = simd::to_array<A>(color_r + rest * vfloat<A>(p.background.r));
        auto const cg = simd::to_array<A>(color_g + rest * vfloat<A>(p.background.g));
        auto const cb = simd::to_array<A>(color_b + rest * vfloat<A>(p.background.b));
        auto const ca = simd::to_array<A>(alpha + rest);
        auto const cd = simd::to_array<A>(depth);
        for (uint32_t bits = valid; bits; bits &= bits - 1) {
          int const l = __builtin_ctz(bits);
          put_pixel(out, px[l], py[l], cr[size_t(l)], cg[size_t(l)], cb[size_t(l)], ca[size_t(l)]);
          if (out.depth_out) put_depth(out, px[l], py[l], cd[size_t(l)]);
        }
      }
    }
}

}  // namespace impl
}  // namespace CELLRAY_ISA_NS
}  // namespace cellray
