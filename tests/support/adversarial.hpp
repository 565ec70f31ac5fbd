#pragma once
// Small owning meshes that break naive cell kernels: zero-volume tets,
// flat / inverted / twisted / non-planar hexes, NaN values, plus the random
// helpers the cell tests share (fixed seeds, platform independent), and
// address space for views with more than 2^31 vertices.

#include <sys/mman.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <cellray/cells/queries.hpp>
#include <cellray/cells/reference.hpp>
#include <cellray/mesh/cell_mesh.hpp>

namespace cellray::test {

/// splitmix64 stream: uniform doubles in [0, 1).
struct Rng {
  uint64_t state;
  explicit Rng(uint64_t seed) : state(seed * 0x9e3779b97f4a7c15ull + 1) {}
  uint64_t next() {
    uint64_t x = (state += 0x9e3779b97f4a7c15ull);
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
  }
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  glm::dvec3 in_box(double lo, double hi) { return {uniform(lo, hi), uniform(lo, hi), uniform(lo, hi)}; }
  glm::dvec3 direction() {
    for (;;) {
      glm::dvec3 const v = in_box(-1, 1);
      double const l = glm::length(v);
      if (l > 0.1 && l <= 1) return v / l;
    }
  }
};

/// An owning mesh: arrays plus the view over them.
template <int N> struct OwnedMesh {
  std::vector<float> xyz;
  std::vector<uint32_t> cells;
  std::vector<float> values;
  CellMesh<N> mesh() const { return CellMesh<N>{view(xyz), view(cells), view(values)}; }
  uint32_t add_vertex(glm::dvec3 const& p, double s) {
    xyz.insert(xyz.end(), {float(p.x), float(p.y), float(p.z)});
    values.push_back(float(s));
    return uint32_t(values.size() - 1);
  }
  /// Appends a cell with fresh vertices (ids in corner order, or permuted by
  /// `perm` so the canonical face order is exercised).
  void add_cell(glm::dvec3 const* p, double const* s, int const* perm = nullptr) {
    uint32_t ids[N];
    uint32_t const base = uint32_t(values.size());
    xyz.resize(xyz.size() + 3 * N);
    values.resize(values.size() + N);
    for (int i = 0; i < N; ++i) {
      uint32_t const v = base + uint32_t(perm ? perm[i] : i);
      xyz[3 * v] = float(p[i].x), xyz[3 * v + 1] = float(p[i].y), xyz[3 * v + 2] = float(p[i].z);
      values[v] = float(s[i]);
      ids[i] = v;
    }
    cells.insert(cells.end(), ids, ids + N);
  }
};

/// Unit-cube corners in VTK order.
inline glm::dvec3 unit_corner(int i) {
  static constexpr int u[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  return {double(u[i][0]), double(u[i][1]), double(u[i][2])};
}

enum class HexKind { parallelepiped, jittered, twisted, nearly_flat, non_planar, inverted };
inline char const* hex_kind_name(HexKind k) {
  switch (k) {
    case HexKind::parallelepiped: return "parallelepiped";
    case HexKind::jittered: return "jittered";
    case HexKind::twisted: return "twisted";
    case HexKind::nearly_flat: return "nearly flat";
    case HexKind::non_planar: return "non-planar";
    case HexKind::inverted: return "inverted";
  }
  return "?";
}

/// One distorted hex (corners in VTK order, about unit size, placed and
/// scaled randomly) of the given kind:
/// - parallelepiped: an affine image of the unit cube (trilinear = exact cubic);
/// - jittered: every corner moved up to 0.25;
/// - twisted: top face rotated about the vertical axis by 30 to 80 degrees;
/// - nearly flat: height 1e-3 to 1e-2 of the width;
/// - non-planar: two opposite top corners lifted by 0.3 to 0.6, the others
///   lowered (every face strongly non-planar, cell still valid);
/// - inverted: a jittered hex mirrored (negative Jacobian everywhere).
inline void distorted_hex(Rng& rng, HexKind kind, glm::dvec3 p[8]) {
  for (int i = 0; i < 8; ++i) p[i] = unit_corner(i);
  switch (kind) {
    case HexKind::parallelepiped: {
      glm::dvec3 const a = glm::dvec3(1, 0, 0) + 0.4 * rng.in_box(-1, 1), b = glm::dvec3(0, 1, 0) + 0.4 * rng.in_box(-1, 1),
                       c = glm::dvec3(0, 0, 1) + 0.4 * rng.in_box(-1, 1);
      for (int i = 0; i < 8; ++i) p[i] = p[i].x * a + p[i].y * b + p[i].z * c;
      break;
    }
    case HexKind::jittered:
    case HexKind::inverted:
      for (int i = 0; i < 8; ++i) p[i] += 0.25 * rng.in_box(-1, 1);
      if (kind == HexKind::inverted)
        for (int i = 0; i < 8; ++i) p[i].x = -p[i].x;
      break;
    case HexKind::twisted: {
      double const a = rng.uniform(30, 80) * M_PI / 180;
      for (int i = 4; i < 8; ++i) {
        double const x = p[i].x - 0.5, y = p[i].y - 0.5;
        p[i].x = 0.5 + std::cos(a) * x - std::sin(a) * y;
        p[i].y = 0.5 + std::sin(a) * x + std::cos(a) * y;
      }
      break;
    }
    case HexKind::nearly_flat: {
      double const h = std::pow(10.0, rng.uniform(-3, -2));
      for (int i = 4; i < 8; ++i) p[i].z = h;
      break;
    }
    case HexKind::non_planar: {
      double const lift = rng.uniform(0.3, 0.6);
      p[4].z += lift, p[6].z += lift, p[5].z -= 0.3 * lift, p[7].z -= 0.3 * lift;
      p[1].z -= 0.3 * lift, p[3].z -= 0.3 * lift;
      break;
    }
  }
  glm::dvec3 const shift = rng.in_box(-3, 3);
  double const scale = std::pow(10.0, rng.uniform(-1, 1));
  for (int i = 0; i < 8; ++i) p[i] = shift + scale * p[i];
}

/// `x` rounded to float, as a value the optimiser cannot trace back to `x`.
/// g++ 12.2 miscompiles `double(float(x))` at -O2 and up once its SLP
/// vectoriser packs two such lanes: value numbering (fre5) folds the vector
/// round trip `(vector double)(vector float) v` back to `v`, so a double
/// reference fed from such floats would see the unrounded values instead of
/// what the kernels saw (found in test_cells_watertight.cpp's unity TU: its
/// rays went exactly through the vertex they aimed at). A volatile load is
/// opaque: what is converted back is the float itself.
inline float rounded(double x) {
  float volatile const f = float(x);
  return f;
}

/// Float copy of a ray in double (what the SIMD kernels see), and back.
inline RayQuery to_query(glm::dvec3 const& o, glm::dvec3 const& d) {
  return {rounded(o.x), rounded(o.y), rounded(o.z), rounded(d.x), rounded(d.y), rounded(d.z)};
}
inline ref::Ray to_ref(RayQuery const& q) { return {{q.ox, q.oy, q.oz}, {q.dx, q.dy, q.dz}}; }

inline constexpr float nanf = std::numeric_limits<float>::quiet_NaN();

/// Address space without memory: an anonymous MAP_NORESERVE mapping whose
/// pages are committed only when written, so a view can index 2^31+
/// vertices while a test touches a few. Falsy when the mapping fails.
class Reservation {
 public:
  explicit Reservation(uint64_t bytes) : bytes_(bytes) {
    void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    p_ = p == MAP_FAILED ? nullptr : p;
  }
  ~Reservation() {
    if (p_) munmap(p_, bytes_);
  }
  Reservation(Reservation const&) = delete;
  Reservation& operator=(Reservation const&) = delete;
  template <class T> T* as() const { return static_cast<T*>(p_); }
  explicit operator bool() const { return p_ != nullptr; }

 private:
  void* p_ = nullptr;
  uint64_t bytes_;
};

}  // namespace cellray::test
