#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include <cellray/bvh/node.hpp>
#include <cellray/memory.hpp>
#include <cellray/render/image.hpp>

// One namespace per file: a stage's files compile as one unity TU.
namespace test_mesh_memory {

using namespace cellray;

TEST_CASE("resize_zeroed keeps the old elements and zeroes the new ones, small and large", "[mesh]") {
  // A LargeVector's resize leaves new elements unset, so only resize_zeroed
  // can zero them: the capacity is dirtied first (fresh pages are zero anyway).
  for (uint64_t n : {uint64_t(3000), uint64_t(3) << 20}) {  // below and above the parallel threshold
    detail::LargeVector<uint32_t> v;
    v.assign(n, 0xdeadbeefu);
    v.resize(1000);
    std::iota(v.begin(), v.end(), 7u);
    detail::resize_zeroed(v, n);
    REQUIRE(v.size() == n);
    for (uint32_t i = 0; i < 1000; ++i) REQUIRE(v[i] == 7u + i);
    uint64_t nonzero = 0;
    for (uint64_t i = 1000; i < n; ++i) nonzero += v[i] != 0;
    CHECK(nonzero == 0);
  }
  std::vector<float> grow(100, 1.f);  // the standard allocator too
  detail::resize_zeroed(grow, uint64_t(1) << 20);
  CHECK(std::count(grow.begin(), grow.end(), 0.f) == (1 << 20) - 100);
  std::vector<float> shrink(100, 1.f);
  detail::resize_zeroed(shrink, 5);
  CHECK(shrink == std::vector<float>(5, 1.f));
}

TEST_CASE("populate_pages and populate_parallel map pages without changing what they hold", "[mesh]") {
  // They only map pages ahead of the writes (a hint); written bytes, the
  // bytes around an unaligned range and a fresh buffer's later writes stay.
  for (uint64_t n : {uint64_t(100), uint64_t(40000), uint64_t(3) << 20}) {
    detail::LargeVector<uint32_t> v(n);  // unset
    for (uint64_t i = 0; i < n / 2; ++i) v[i] = uint32_t(3 * i + 1);
    detail::populate_pages(v.data() + 3, (n - 5) * sizeof(uint32_t));  // unaligned both ends
    detail::populate_parallel(v.data() + 1, (n - 1) * sizeof(uint32_t));
    for (uint64_t i = n / 2; i < n; ++i) v[i] = uint32_t(3 * i + 1);
    uint64_t wrong = 0;
    for (uint64_t i = 0; i < n; ++i) wrong += v[i] != uint32_t(3 * i + 1);
    CHECK(wrong == 0);
  }
  detail::populate_pages(nullptr, 0);
  detail::populate_parallel(nullptr, 0);
}

TEST_CASE("LargeAllocator: large buffers start on a 2 MB boundary, every buffer is usable to its end", "[mesh]") {
  for (uint64_t bytes : {uint64_t(64), uint64_t(1) << 20, detail::large_buffer_bytes, (uint64_t(5) << 20) + 12}) {
    detail::LargeVector<uint32_t> v;
    v.resize(bytes / 4);
    auto const at = reinterpret_cast<uintptr_t>(v.data());
    if (bytes >= detail::large_buffer_bytes) CHECK(at % detail::huge_page_bytes == 0);
    else CHECK(at % 64 == 0);
    for (uint64_t i = 0; i < v.size(); ++i) v[i] = uint32_t(i);
    detail::LargeVector<uint32_t> copy = v;  // copies and frees through the same allocator
    CHECK(copy == v);
    v = {};
    CHECK(copy.back() == uint32_t(copy.size() - 1));
  }
}

TEST_CASE("a new image and new value ranges are zero however large", "[mesh]") {
  Image const img(1024, 1100);  // 18 MB: zeroed in parallel
  uint64_t nonzero = 0;
  for (float c : img.rgba) nonzero += c != 0.f;
  CHECK(img.rgba.size() == uint64_t(1024) * 1100 * 4);
  CHECK(nonzero == 0);
  CHECK_THROWS_AS(Image(-1, 4), InvalidArgument);
  // Value ranges grown again after a shrink reuse their dirty capacity.
  ValueRanges r(uint64_t(1) << 20);
  for (uint64_t i = 0; i < r.size(); ++i) r[i] = {1.f, 2.f};
  r.resize(10);
  r.resize(uint64_t(1) << 20);
  nonzero = 0;
  for (uint64_t i = 10; i < r.size(); ++i) nonzero += r[i].vmin != 0.f || r[i].vmax != 0.f;
  CHECK(nonzero == 0);
  CHECK(r[0].vmin == 1.f);
}

}  // namespace test_mesh_memory
