#pragma once
// What a render prepares once on the calling thread and every tile reads:
// tree views, the scene bounds, the transfer-function table. Plain data,
// shared by the baseline side and the ISA units.

#include <algorithm>
#include <cstdint>
#include <variant>
#include <vector>

#include <glm/vec3.hpp>

#include "../mesh/cell_mesh.hpp"
#include "../mesh/cell_types.hpp"
#include "../mesh/neighbours.hpp"
#include "../traverse/sample.hpp"
#include "../traverse/tree_view.hpp"
#include "clip.hpp"
#include "transfer_function.hpp"

namespace cellray {

/// A part's mesh view and its face neighbours, of one cell type.
template <int N> struct PartCells {
  CellMesh<N> const* mesh = nullptr;
  /// Set when DVR segments and AO rays may march (one part, or two linked).
  FaceNeighbours<N> const* neighbours = nullptr;
};

struct PreparedPart {
  TreeView tree;
  PerCellType<PartCells> cells;
  float const* gradients = nullptr;     ///< iso, smooth normals: 3 per vertex (VertexGradients)
  float const* color_values = nullptr;  ///< iso coloured by another array: 1 per vertex

  /// f(CellMesh<N> const& mesh, FaceNeighbours<N> const* neighbours) for this part's type.
  template <class F> decltype(auto) visit(F&& f) const {
    return std::visit([&](auto const& c) -> decltype(auto) { return f(*c.mesh, c.neighbours); }, cells);
  }
  AnyCellMesh mesh() const {
    return std::visit([](auto const& c) { return AnyCellMesh(*c.mesh); }, cells);
  }
  bool marches() const {
    return std::visit([](auto const& c) { return c.neighbours != nullptr; }, cells);
  }
  /// This part's cells if they are of type N, else nullptr.
  template <int N> PartCells<N> const* cells_of() const { return std::get_if<PartCells<N>>(&cells); }
};

/// A lookup table read linearly between entries: entry i stored beside
/// entry i + 1 (the last beside itself), so a lookup is one 64-bit gather a
/// lane (simd::gather_pairs). Twice the floats of a plain table.
struct PairTable {
  std::vector<float> pairs;  ///< 2 * size(): entry i, entry min(i + 1, size - 1)
  explicit PairTable(std::vector<float> const& t = {}) : pairs(2 * t.size()) {
    for (size_t i = 0; i < t.size(); ++i) pairs[2 * i] = t[i], pairs[2 * i + 1] = t[std::min(i + 1, t.size() - 1)];
  }
  size_t size() const { return pairs.size() / 2; }
  float const* data() const { return pairs.data(); }
  /// Entry i + f of the way to entry i + 1 (0 <= f < 1).
  float lerp(int i, float f) const {
    float const a = pairs[2 * size_t(i)];
    return a + f * (pairs[2 * size_t(i) + 1] - a);
  }
};

/// Transfer function sampled into a table with the opacity corrected for the
/// sample spacing (DVR samples mode), or its integrals over value (cell
/// segments): tf_table makes the one the mode reads.
struct PreparedTf {
  PairTable r, g, b, a;  ///< samples: `size` entries over [lo, lo + (size - 1) / scale]
  /// Cell segments integrate a piece whose value runs from v0 to v1 over the
  /// transfer function between them, not at one point: its optical depth
  /// is exact, and its colour the extinction-weighted mean, however narrow
  /// the opacity peaks it crosses (a midpoint steps over a peak narrower
  /// than a piece's value span: tf_integrals). Per cell, 12 floats: hi[4]
  /// and lo[4], the integral over the cells before it (a double sum as two
  /// floats), then cell[4], over the cell itself; each for the extinction
  /// -ln(1 - opacity) / unit distance, then r, g, b times it. Segments only.
  std::vector<float> integrals;
  static constexpr int integral_stride = 12;
  float lo = 0.f, scale = 1.f;
  int size = 0;  ///< entries; integrals has size + 1 cells
  TransferFunction const* tf = nullptr;
};

struct PreparedScene {
  std::vector<PreparedPart> parts;
  glm::vec3 lo{0.f}, hi{0.f};  ///< bounds of every part
  float diagonal = 1.f;
  float step = 0.f;            ///< DVR sample spacing (world units)
  ValueWindows windows;        ///< DVR: values with nonzero opacity (everything without skipping)
  PreparedTf const* tf = nullptr;
  float inv_gradient_full = 0.f;  ///< DVR shading: 1 / DvrShading::gradient_full after defaults
  PreparedClip clip;              ///< the region kept (no planes: everything)
  /// DVR segments: a tet part (parts[0]) and a hexahedral part (parts[1])
  /// whose face neighbours are linked to each other (link_face_neighbours)
  /// march as one mesh.
  bool mixed_march = false;
  bool color_by = false;          ///< iso: colour by PreparedPart::color_values through `colors`
  ColorTable colors;
};

/// Deterministic per-pixel hash in [0, 1): ambient-occlusion directions
/// must not flicker between frames or differ between ISAs, and the
/// reference renderer draws the same ones (one definition for both).
inline float pixel_hash01(uint32_t a, uint32_t b) {
  uint32_t h = a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u;
  h ^= h >> 15;
  h *= 0x2C1B3C6Du;
  h ^= h >> 12;
  h *= 0x297A2D39u;
  h ^= h >> 15;
  return float(h >> 8) * (1.f / 16777216.f);
}

}  // namespace cellray
