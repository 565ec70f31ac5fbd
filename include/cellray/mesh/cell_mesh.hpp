#pragma once
// TetMesh and HexMesh: zero-copy views over the host's arrays.

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "../error.hpp"
#include "span.hpp"

namespace cellray {

enum class CellType { tet, hex };

/// One named per-vertex scalar array (float, one value per vertex).
struct ScalarArray {
  std::string name;
  Span<float> values;
};

/// A homogeneous mesh of `Corners`-vertex cells (4 = tetrahedra, 8 =
/// hexahedra in VTK node order: bottom quad 0-1-2-3, top quad 4-5-6-7 with
/// 4 above 0). Holds pointers only: positions (xyz floats, interleaved), cell
/// indices (32- or 64-bit, `Corners` per cell) and named per-vertex scalar
/// arrays, one of which is active. Nothing is copied or reordered; the host
/// keeps the arrays alive and unchanged while the view, a BVH built from it
/// or a render using it exists. Offsets are 64-bit, so index arrays over 2^31
/// entries work. Construction checks only array sizes; `validate()` checks
/// the contents. Cheap to copy; safe to share between threads.
template <int Corners> class CellMesh {
 public:
  static_assert(Corners == 4 || Corners == 8, "tetrahedra or hexahedra");
  static constexpr int corners = Corners;
  static constexpr CellType cell_type = Corners == 4 ? CellType::tet : CellType::hex;

  CellMesh() = default;

  /// @param xyz    3 floats per vertex.
  /// @param cells  `Corners` vertex ids per cell (uint32_t or uint64_t).
  /// @param values one float per vertex (may be empty: geometry only).
  /// @throws InvalidMesh when a size is not a multiple of 3 or `Corners`, or
  ///         `values` has a different length from the vertex count.
  CellMesh(Span<float> xyz, Span<uint32_t> cells, Span<float> values = {}, std::string name = "values")
      : xyz_(xyz), idx32_(cells.data), index_count_(cells.size) {
    check_sizes();
    if (!values.empty()) add_array(std::move(name), values);
  }
  CellMesh(Span<float> xyz, Span<uint64_t> cells, Span<float> values = {}, std::string name = "values")
      : xyz_(xyz), idx64_(cells.data), index_count_(cells.size) {
    check_sizes();
    if (!values.empty()) add_array(std::move(name), values);
  }

  /// Adds a per-vertex array; the first one added becomes active.
  /// @throws InvalidMesh on a length mismatch or a duplicate name.
  CellMesh& add_array(std::string name, Span<float> values) {
    if (values.size != vertex_count())
      throw InvalidMesh("scalar array '" + name + "' has " + std::to_string(values.size) +
                        " values for " + std::to_string(vertex_count()) + " vertices");
    for (auto const& a : arrays_)
      if (a.name == name) throw InvalidMesh("scalar array '" + name + "' added twice");
    arrays_.push_back({std::move(name), values});
    return *this;
  }

  /// A copy whose active array is `name`. @throws InvalidMesh naming the
  /// arrays there are when `name` is not one of them.
  CellMesh with_array(std::string_view name) const {
    for (size_t i = 0; i < arrays_.size(); ++i)
      if (arrays_[i].name == name) {
        CellMesh m = *this;
        m.active_ = i;
        return m;
      }
    std::string known;
    for (auto const& a : arrays_) known += (known.empty() ? "" : ", ") + a.name;
    throw InvalidMesh("no scalar array '" + std::string(name) + "' (the mesh has: " +
                      (known.empty() ? "none" : known) + ")");
  }

  /// A copy whose active values are `values` (e.g. another time step).
  CellMesh with_values(Span<float> values, std::string name = "values") const {
    CellMesh m = *this;
    m.arrays_.clear();
    m.active_ = 0;
    m.add_array(std::move(name), values);
    return m;
  }

  uint64_t vertex_count() const noexcept { return xyz_.size / 3; }
  uint64_t cell_count() const noexcept { return index_count_ / Corners; }
  bool empty() const noexcept { return cell_count() == 0; }

  bool has_32bit_indices() const noexcept { return idx64_ == nullptr; }
  uint32_t const* indices32() const noexcept { return idx32_; }
  uint64_t const* indices64() const noexcept { return idx64_; }

  /// Vertex id of `corner` (0..Corners-1) of `cell`; no range check.
  uint64_t vertex(uint64_t cell, int corner) const noexcept {
    uint64_t const k = cell * Corners + uint64_t(corner);
    return idx64_ ? idx64_[k] : uint64_t(idx32_[k]);
  }

  float const* positions() const noexcept { return xyz_.data; }
  glm::vec3 position(uint64_t v) const noexcept {
    float const* p = xyz_.data + 3 * v;
    return {p[0], p[1], p[2]};
  }

  bool has_values() const noexcept { return !arrays_.empty(); }
  /// The active per-vertex array (nullptr when the mesh has none).
  float const* values() const noexcept { return arrays_.empty() ? nullptr : arrays_[active_].values.data; }
  float value(uint64_t v) const noexcept { return arrays_[active_].values.data[v]; }
  std::string_view active_array() const noexcept {
    return arrays_.empty() ? std::string_view() : std::string_view(arrays_[active_].name);
  }
  std::vector<ScalarArray> const& arrays() const noexcept { return arrays_; }

  /// Bytes of the host arrays this view points at (it owns none of them).
  uint64_t viewed_bytes() const noexcept {
    uint64_t b = xyz_.size * sizeof(float) + index_count_ * (idx64_ ? 8 : 4);
    for (auto const& a : arrays_) b += a.values.size * sizeof(float);
    return b;
  }

 private:
  void check_sizes() const {
    if (xyz_.size % 3 != 0)
      throw InvalidMesh("positions hold " + std::to_string(xyz_.size) + " floats, not a multiple of 3 (x, y, z)");
    if (index_count_ % Corners != 0)
      throw InvalidMesh("cell indices hold " + std::to_string(index_count_) + " entries, not a multiple of " +
                        std::to_string(Corners) + " per cell");
  }

  Span<float> xyz_;
  uint32_t const* idx32_ = nullptr;
  uint64_t const* idx64_ = nullptr;
  uint64_t index_count_ = 0;
  std::vector<ScalarArray> arrays_;
  size_t active_ = 0;
};

using TetMesh = CellMesh<4>;  ///< tetrahedra, 4 vertex ids per cell
using HexMesh = CellMesh<8>;  ///< hexahedra, 8 vertex ids per cell, VTK order

}  // namespace cellray
