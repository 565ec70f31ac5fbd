#pragma once
// A minimal read-only span (C++17 has no std::span): pointer + element count.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cellray {

/// Non-owning view of `size` contiguous `T`. The host keeps the memory alive.
template <class T> struct Span {
  T const* data = nullptr;
  uint64_t size = 0;

  constexpr Span() = default;
  constexpr Span(T const* d, uint64_t n) : data(d), size(n) {}
  Span(std::vector<T> const& v) : data(v.data()), size(v.size()) {}  // NOLINT: implicit on purpose

  constexpr T const& operator[](uint64_t i) const { return data[i]; }
  constexpr T const* begin() const { return data; }
  constexpr T const* end() const { return data + size; }
  constexpr bool empty() const { return size == 0; }
};

/// Spans over host vectors, spelled as in the README example.
template <class T> Span<T> view(std::vector<T> const& v) { return Span<T>(v); }
template <class T> Span<T> view(T const* p, uint64_t n) { return Span<T>(p, n); }

}  // namespace cellray
