#pragma once
// One scalar first-hit query per pixel of a camera (FirstHitQuery over a
// tree, packet traversal of one ray), for tests of what the query keeps at
// its hits (gradients, hexahedron coordinates).

#include <cstdint>
#include <initializer_list>

#include <cellray/render/camera.hpp>
#include <cellray/traverse/first_hit.hpp>

namespace cellray::test {

inline IsoSet iso_set(std::initializer_list<float> values) {
  IsoSet s;
  for (float v : values) s.values[s.count++] = v;
  return s;
}

/// For each pixel of `cam`: a query over `tree` set up by `setup(query)`,
/// then `visit(query, ray)` where the ray hits. Returns the hits.
template <int N, class Setup, class Visit>
int for_each_first_hit(TreeView const& tree, CellMesh<N> const& mesh, IsoSet const& isos, CellIsoOptions const& roots,
                       Camera const& cam, Setup const& setup, Visit const& visit) {
  int hits = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      Ray const ray{cam.eye, 0.f, cam.direction(float(x), float(y)), 1e30f};
      RayPacket<scalar> const r = load_rays<scalar>(&ray, 1);
      FirstHitQuery<scalar, N> q{tree, mesh, r, isos, roots, {r.tmax, -1, -1}};
      setup(q);
      traverse_packet<scalar>(tree, r, true, q);
      if (q.hit.item < 0) continue;
      ++hits;
      visit(q, ray);
    }
  return hits;
}

}  // namespace cellray::test
