#pragma once
// Large transient and long-lived buffers (cell boxes, BVH nodes and item
// lists, images) on the VMs users run on: a fresh 4 KB page's first write
// costs ~14.5 us there (PROFILE.md), so a 20 MB buffer touched by one thread
// takes ~70 ms before any work. Three levers, all measured on a fresh
// `cellray-render` (issue #23): ask for transparent huge pages (one fault per
// 2 MB where the system grants them on request, "madvise" mode), touch new
// pages from all threads, and map a smaller buffer's pages in one call before
// writing them (populate_pages).

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__has_include)
#if __has_include(<sys/mman.h>)
#include <sys/mman.h>
#endif
#endif

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace cellray::detail {

constexpr uint64_t huge_page_bytes = uint64_t(1) << 21;
/// Below this an allocation is not worth a system call (or the pool).
constexpr uint64_t large_buffer_bytes = uint64_t(1) << 22;
/// From this size a new buffer's pages are mapped in one call (populate_pages).
constexpr uint64_t populate_bytes = uint64_t(1) << 16;

/// Advises the whole 2 MB pages inside [p, p + bytes) to be transparent huge
/// pages. A hint only: nothing changes where the system refuses it.
inline void advise_huge_pages([[maybe_unused]] void* p, [[maybe_unused]] uint64_t bytes) noexcept {
#if defined(MADV_HUGEPAGE)
  auto const a = reinterpret_cast<uintptr_t>(p);
  uintptr_t const b = (a + huge_page_bytes - 1) & ~uintptr_t(huge_page_bytes - 1);
  uintptr_t const e = (a + bytes) & ~uintptr_t(huge_page_bytes - 1);
  if (e > b) ::madvise(reinterpret_cast<void*>(b), e - b, MADV_HUGEPAGE);
#endif
}

/// Maps the whole 4 KB pages inside [p, p + bytes) writable at once
/// (MADV_POPULATE_WRITE, Linux 5.14): on the paravirtualised VMs users run
/// on, one call per range costs about half of the faults that first writes
/// take page by page. A hint only: older kernels refuse it and nothing changes.
inline void populate_pages([[maybe_unused]] void* p, [[maybe_unused]] uint64_t bytes) noexcept {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr int populate_write = 23;  // MADV_POPULATE_WRITE; older headers lack the name
  constexpr uintptr_t page = 4096;
  auto const a = reinterpret_cast<uintptr_t>(p);
  uintptr_t const b = (a + page - 1) & ~(page - 1);
  uintptr_t const e = (a + bytes) & ~(page - 1);
  if (e > b) ::madvise(reinterpret_cast<void*>(b), e - b, populate_write);
#endif
}

/// f(b, e) for 256 KB blocks [b, e) of [0, bytes), from all threads.
template <class F> void for_blocks_parallel(uint64_t bytes, F const& f) {
  constexpr uint64_t block = uint64_t(1) << 18;
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, (bytes + block - 1) / block, 1),
                    [&](tbb::blocked_range<uint64_t> const& r) {
                      f(r.begin() * block, std::min(bytes, r.end() * block));
                    });
}

/// populate_pages from all threads, for a buffer that is written whole next
/// (its entries left unset by a LargeVector's resize).
inline void populate_parallel(void* p, uint64_t bytes) {
  if (bytes < populate_bytes) return;
  auto* const c = static_cast<unsigned char*>(p);
  for_blocks_parallel(bytes, [c](uint64_t b, uint64_t e) { populate_pages(c + b, e - b); });
}

/// Zeroes [p, p + bytes) from all threads, so the first-write faults are
/// shared (and the pages land near the threads that will use them).
inline void zero_parallel(void* p, uint64_t bytes) {
  auto* const c = static_cast<unsigned char*>(p);
  for_blocks_parallel(bytes, [c](uint64_t b, uint64_t e) {
    populate_pages(c + b, e - b);
    std::memset(c + b, 0, e - b);
  });
}

/// An allocator for trivially constructible elements: `resize` leaves them
/// unset (they are written next, usually in parallel), and allocations of
/// 4 MB or more are 2 MB-aligned and advised as huge pages.
template <class T> struct LargeAllocator {
  using value_type = T;
  template <class U> struct rebind {
    using other = LargeAllocator<U>;
  };
  LargeAllocator() = default;
  template <class U> LargeAllocator(LargeAllocator<U> const&) noexcept {}

  T* allocate(size_t n) {
    if (n > size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
    size_t const bytes = n * sizeof(T);
    if (bytes < large_buffer_bytes) return static_cast<T*>(::operator new(bytes, std::align_val_t(alignof(T) > 64 ? alignof(T) : 64)));
    // 2 MB-aligned so that all but the tail can be huge pages; the tail stays
    // small pages, so nothing beyond `bytes` is ever touched.
    void* p = ::operator new(bytes, std::align_val_t(huge_page_bytes));
    advise_huge_pages(p, bytes);
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t n) noexcept {
    size_t const bytes = n * sizeof(T);
    if (bytes < large_buffer_bytes) ::operator delete(p, std::align_val_t(alignof(T) > 64 ? alignof(T) : 64));
    else ::operator delete(p, std::align_val_t(huge_page_bytes));
  }
  template <class U> void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args> void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <class U> friend bool operator==(LargeAllocator const&, LargeAllocator<U> const&) noexcept { return true; }
  template <class U> friend bool operator!=(LargeAllocator const&, LargeAllocator<U> const&) noexcept { return false; }
};

/// A vector whose `resize` leaves trivial elements unset.
template <class T> using LargeVector = std::vector<T, LargeAllocator<T>>;

/// v.resize(n) with the new elements zero, for a trivial T in any vector:
/// large growth is advised as huge pages and zeroed from all threads (the
/// capacity is zeroed before resize() constructs into it: for trivial types
/// the bytes are the objects, and the second pass over present pages is
/// cheap).
template <class T, class A> void resize_zeroed(std::vector<T, A>& v, uint64_t n) {
  static_assert(std::is_trivial_v<T>);
  if (n <= v.size() || (n - v.size()) * sizeof(T) < large_buffer_bytes / 4) {
    uint64_t const old = v.size();
    if (n > old && (n - old) * sizeof(T) >= populate_bytes) {
      v.reserve(n);
      populate_pages(v.data() + old, (n - old) * sizeof(T));
    }
    v.resize(n);  // a LargeVector leaves the new elements unset
    if (n > old) std::memset(static_cast<void*>(v.data() + old), 0, (n - old) * sizeof(T));
    return;
  }
  v.reserve(n);
  auto* const bytes = reinterpret_cast<unsigned char*>(v.data()) + v.size() * sizeof(T);
  uint64_t const total = (n - v.size()) * sizeof(T);
  advise_huge_pages(bytes, total);
  zero_parallel(bytes, total);
  v.resize(n);
}

}  // namespace cellray::detail
