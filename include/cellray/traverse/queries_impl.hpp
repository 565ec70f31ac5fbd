#pragma once
// Bodies of the query entry points (ISA units only).

#include <cmath>

#include <glm/geometric.hpp>

#include "cell_ops.hpp"
#include "first_hit.hpp"
#include "probe.hpp"
#include "sample.hpp"
#include "queries.hpp"

namespace cellray {
inline namespace CELLRAY_ISA_NS {
namespace impl {

/// Central-difference step for a cell: 1% of its first edge, so the
/// stencil stays (mostly) inside the cell the hit lies in.
template <int N> inline float central_step(CellCorners<scalar, N> const& c) {
  float const dx = c.x[1] - c.x[0], dy = c.y[1] - c.y[0], dz = c.z[1] - c.z[0];
  return 0.01f * std::sqrt(dx * dx + dy * dy + dz * dz);
}

/// Unit normal of the field at a hit, facing the ray origin (two-sided).
template <int N>
inline glm::vec3 hit_normal(CellMesh<N> const& mesh, uint64_t cell, Ray const& ray, float t, GradientMethod m) {
  CellCorners<scalar, N> const c = broadcast_corners<scalar, N>(mesh, cell);
  Vec3<scalar> const d{ray.dir.x, ray.dir.y, ray.dir.z};
  Vec3<scalar> const p{ray.org.x + t * d.x, ray.org.y + t * d.y, ray.org.z + t * d.z};
  Vec3<scalar> const g = CellOps<scalar, N>::gradient(c, p, m, central_step(c));
  Vec3<scalar> const n = face_forward<scalar>(shading_normal<scalar>(g, d), d);
  return {n.x, n.y, n.z};
}

template <class A, int N>
void first_hits(TreeView const& tree, CellMesh<N> const& mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                SurfaceHit* out) {
  constexpr int W = width<A>;
  int const threshold = q.hybrid_threshold > 0 ? q.hybrid_threshold : std::max(1, W / 4);
  for (uint64_t base = 0; base < n; base += W) {
    int const cnt = int(std::min<uint64_t>(W, n - base));
    RayPacket<A> const r = load_rays<A>(rays + base, cnt);
    vmask<A> const active = simd::mask_from_bits<A>(cnt >= 32 ? ~0u : (1u << cnt) - 1u) && r.tmin <= r.tmax;
    FirstHitQuery<A, N> fq{tree, mesh, r, q.isos, q.method, {r.tmax, vint<A>(-1), vint<A>(-1)}};
    // Analytic normals come with the hits, as in the renderer: the query
    // keeps the gradient of each hit cell from the corners it loaded (no
    // second corner load and, for hexes, no second point location per ray).
    bool const query_gradient = q.normals != GradientMethod::central;  // smooth: analytic here (no vertex gradients)
    fq.want_gradient = query_gradient;
    switch (q.traversal) {
      case Traversal::packet: traverse_packet<A>(tree, r, active, fq); break;
      case Traversal::hybrid: traverse_packet<A>(tree, r, active, fq, 0, threshold); break;
      case Traversal::spmd: traverse_spmd<A>(tree, r, active, fq); break;
    }
    HitPacket<A> const& hit = fq.hit;
    alignas(64) float t[W];
    alignas(64) int32_t item[W], iso[W];
    simd::store(t, hit.t);
    simd::store(item, hit.item);
    simd::store(iso, hit.iso);
    alignas(64) float nrm[3][W];
    if (query_gradient) {
      Vec3<A> const dir = ray_batch(r).dir();
      Vec3<A> const nv = face_forward<A>(shading_normal<A>(fq.grad, dir), dir);
      simd::store(nrm[0], nv.x), simd::store(nrm[1], nv.y), simd::store(nrm[2], nv.z);
    }
    for (int l = 0; l < cnt; ++l) {
      SurfaceHit h;
      if (item[l] >= 0) {
        h.t = t[l];
        h.iso = iso[l];
        h.cell = tree.item(uint64_t(item[l]));
        h.normal = query_gradient ? glm::vec3(nrm[0][l], nrm[1][l], nrm[2][l])
                                  : hit_normal(mesh, h.cell, rays[base + uint64_t(l)], t[l], q.normals);
      }
      out[base + uint64_t(l)] = h;
    }
  }
}

template <class A, int N>
void sample_rays(TreeView const& tree, CellMesh<N> const& mesh, Ray const* rays, uint64_t n, float step, int per_ray,
                 int group, Traversal how, ValueWindows const& windows, float* out) {
  constexpr int W = width<A>;
  int const threshold = std::max(1, W / 4);
  for (uint64_t base = 0; base < n; base += W) {
    int const cnt = int(std::min<uint64_t>(W, n - base));
    RayPacket<A> const r = load_rays<A>(rays + base, cnt);
    vmask<A> const lanes = simd::mask_from_bits<A>(cnt >= 32 ? ~0u : (1u << cnt) - 1u);
    for (int k0 = 0; k0 < per_ray; k0 += group) {
      int const g = std::min(group, per_ray - k0);
      SampleQuery<A, N> q(tree, mesh, r, windows, r.tmin + vfloat<A>(step * float(k0)), step, g, lanes);
      sample_group(q, lanes, how, threshold);
      for (int l = 0; l < cnt; ++l)
        for (int k = 0; k < g; ++k) out[(base + uint64_t(l)) * uint64_t(per_ray) + uint64_t(k0 + k)] = q.values[k][l];
    }
  }
}

}  // namespace impl
}  // namespace CELLRAY_ISA_NS

template <class Arch>
void FirstHitEntry<Arch>::run(TreeView const& tree, AnyCellMesh mesh, Ray const* rays, uint64_t n, IsoQuery const& q,
                              SurfaceHit* hits) {
  mesh.visit([&](auto const& m) { impl::first_hits<Arch>(tree, m, rays, n, q, hits); });
}

}  // namespace cellray

namespace cellray {
template <class Arch>
void SampleEntry<Arch>::run(TreeView const& tree, AnyCellMesh mesh, Ray const* rays, uint64_t n, float step,
                            int per_ray, int group, Traversal how, ValueWindows const& windows, float* out) {
  mesh.visit(
      [&](auto const& m) { impl::sample_rays<Arch>(tree, m, rays, n, step, per_ray, group, how, windows, out); });
}
}  // namespace cellray

namespace cellray {
template <class Arch>
void ProbeEntry<Arch>::run(TreeView const& tree, AnyCellMesh mesh, float const* xyz, uint64_t n, float* values) {
  mesh.visit([&](auto const& m) { probe_points<Arch>(tree, m, xyz, n, values); });
}
}  // namespace cellray
