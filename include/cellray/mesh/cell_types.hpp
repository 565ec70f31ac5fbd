#pragma once
// The one list of cell types, and what the stages after mesh/ use instead
// of naming a type: a reference to a view of any listed type (AnyCellMesh),
// a variant holding one T<N> per type (PerCellType), and a loop over the
// list (for_each_cell_type). The BVH, traversals and renderer visit these;
// they never branch on a corner count themselves.

#include <cstdint>
#include <tuple>
#include <type_traits>
#include <utility>
#include <variant>

#include "cell_mesh.hpp"

namespace cellray {

template <int... Corners> struct CellTypeList {};

/// The cell types, by corner count: 4 the tetrahedron (VTK 10), 8 the
/// hexahedron (VTK 12; wedges and pyramids are read as hexahedra with
/// repeated corners, which is VTK's interpolation exactly: vtk_cells.hpp).
/// A new type is its file in cells/ (kernels and `CellOps<A, N>`; what
/// that provides: cells/cell_ops.hpp) and its corner count here.
using CellTypes = CellTypeList<4, 8>;

/// How messages name a type's parts ("tetrahedral part 2").
constexpr char const* cell_type_adjective(int corners) {
  return corners == 4 ? "tetrahedral" : corners == 8 ? "hexahedral" : "unlisted";
}

namespace detail {
template <template <int> class T, class List> struct VariantOver;
template <template <int> class T, int... N> struct VariantOver<T, CellTypeList<N...>> {
  using type = std::variant<T<N>...>;
};
template <int N, int... List> constexpr bool listed(CellTypeList<List...>) { return ((N == List) || ...); }
template <class F, int... N> void for_each_of(F&& f, CellTypeList<N...>) {
  (f(std::integral_constant<int, N>{}), ...);
}
template <template <int> class T, class List> struct TupleOver;
template <template <int> class T, int... N> struct TupleOver<T, CellTypeList<N...>> {
  using type = std::tuple<T<N>...>;
};
template <int N> using MeshPointer = CellMesh<N> const*;
}  // namespace detail

/// Whether meshes of `N` corners are one of the listed types.
template <int N> constexpr bool is_cell_type = detail::listed<N>(CellTypes{});

/// std::variant<T<N>...> over the listed types, in list order.
template <template <int> class T> using PerCellType = typename detail::VariantOver<T, CellTypes>::type;

/// std::tuple<T<N>...> over the listed types: one of each (per-type scratch).
template <template <int> class T> using PerCellTypeTuple = typename detail::TupleOver<T, CellTypes>::type;

/// Calls f(std::integral_constant<int, N>{}) for every listed type, in order.
template <class F> void for_each_cell_type(F&& f) { detail::for_each_of(std::forward<F>(f), CellTypes{}); }

/// A reference to a mesh view of any listed type: what the BVH builder,
/// refits and query entry points take, so each is written once for every
/// type. Holds a pointer; the view must outlive its use.
class AnyCellMesh {
 public:
  template <int N> AnyCellMesh(CellMesh<N> const& m) : mesh_(&m) {  // NOLINT: implicit on purpose
    static_assert(is_cell_type<N>, "not a listed cell type (mesh/cell_types.hpp)");
  }

  /// f(CellMesh<N> const&) for this view's N.
  template <class F> decltype(auto) visit(F&& f) const {
    return std::visit([&](auto const* m) -> decltype(auto) { return f(*m); }, mesh_);
  }
  uint64_t cell_count() const noexcept {
    return std::visit([](auto const* m) { return m->cell_count(); }, mesh_);
  }
  uint64_t vertex_count() const noexcept {
    return std::visit([](auto const* m) { return m->vertex_count(); }, mesh_);
  }

 private:
  PerCellType<detail::MeshPointer> mesh_;
};

}  // namespace cellray
