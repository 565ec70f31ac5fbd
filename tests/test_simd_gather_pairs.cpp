// The transfer-function tables' pair gather (simd::gather_pairs, PairTable
// in render/render_common.hpp): every ISA's lanes read their own entry and
// the next, in lane order, as the linear lookups of DVR need. The points'
// gather (simd::gather_xyz, the cells' corners): each lane its own point,
// and nothing past the array's end (sanitizer builds); the cells' id rows
// (simd::gather_quads): each lane its own four words, in order.

#include <catch2/catch.hpp>

#include <cstdint>
#include <vector>

#include <cellray/render/render_common.hpp>

#include "support/gather_probe.hpp"
#include "support/test_isa.hpp"

// One namespace per file: a stage's files compile as one unity TU
// (tests/CMakeLists.txt), where file-local names must not meet.
namespace test_simd_gather_pairs {

using namespace cellray;

TEST_CASE("gather_pairs: each lane reads its table entry and the next, in lane order", "[simd][isa]") {
  constexpr int size = 4096;
  std::vector<float> t(size);
  for (int i = 0; i < size; ++i) t[size_t(i)] = 0.25f + 0.5f * float(i);  // distinct, exact
  PairTable const table(t);
  REQUIRE(table.size() == size_t(size));
  // Every lane position sees the first and last entries, neighbours, equal
  // indices and far-apart ones (a lane permutation or a half swapped shows).
  std::vector<int32_t> idx;
  for (int k = 0; k < 64 * 16; ++k) {
    int32_t const pattern[4] = {k % size, size - 1 - (37 * k) % size, (k / 16) * 16 % size, (size - 1) * (k % 2)};
    idx.push_back(pattern[(k / 16) % 4]);
  }
  std::vector<float> first(idx.size()), second(idx.size());
  dispatch<test::GatherPairsProbe>(test::isa(), table.data(), idx.data(), int(idx.size()), first.data(),
                                   second.data());
  int wrong = 0;
  for (size_t k = 0; k < idx.size(); ++k) {
    int32_t const i = idx[k];
    float const next = t[size_t(i + 1 < size ? i + 1 : i)];  // the last entry pairs with itself
    wrong += first[k] != t[size_t(i)] || second[k] != next;
  }
  CHECK(wrong == 0);
  // The scalar lookup reads the same pairs: entry i, f of the way to i + 1.
  CHECK(table.lerp(10, 0.5f) == 0.25f + 0.5f * 10.5f);
  CHECK(table.lerp(size - 1, 0.75f) == t[size - 1]);
}

TEST_CASE("gather_xyz: each lane reads its own point, and the last point without reading past the array",
          "[simd][isa]") {
  constexpr int32_t count = 1000;
  std::vector<float> xyz(3 * size_t(count));  // exactly the points: a read past the end is out of bounds
  for (size_t i = 0; i < xyz.size(); ++i) xyz[i] = 0.5f + float(i);  // distinct, exact
  // Batches of 16 lanes: far-apart and equal points, neighbours, and every
  // fourth batch with the last point in one lane (the 16-byte loads would
  // read 4 bytes past it: the gathers take that batch).
  std::vector<int32_t> idx;
  for (int k = 0; k < 64 * 16; ++k) {
    int const batch = k / 16, lane = k % 16;
    int32_t const pattern[4] = {(37 * k) % (count - 1), k % 3, (count - 2) - k % (count - 1),
                                lane == batch % 16 ? count - 1 : (11 * k) % (count - 1)};
    idx.push_back(pattern[batch % 4]);
  }
  std::vector<float> x(idx.size()), y(idx.size()), z(idx.size());
  dispatch<test::GatherXyzProbe>(test::isa(), xyz.data(), count, idx.data(), int(idx.size()), x.data(), y.data(),
                                 z.data());
  int wrong = 0;
  for (size_t k = 0; k < idx.size(); ++k) {
    size_t const i = 3 * size_t(idx[k]);
    wrong += x[k] != xyz[i] || y[k] != xyz[i + 1] || z[k] != xyz[i + 2];
  }
  CHECK(wrong == 0);
}

TEST_CASE("gather_quads: each lane reads its own row of four words, in order", "[simd][isa]") {
  constexpr int32_t rows = 500;
  std::vector<int32_t> words(4 * size_t(rows));  // exactly the rows: the last row's load ends at the end
  for (size_t i = 0; i < words.size(); ++i) words[i] = int32_t(7 * i + 3);  // distinct
  std::vector<int32_t> idx;
  for (int k = 0; k < 64 * 16; ++k) {
    int32_t const pattern[4] = {(37 * k) % rows, rows - 1, k % 5, (rows - 1) - k % rows};
    idx.push_back(pattern[(k / 16) % 4]);
  }
  std::vector<int32_t> out(4 * idx.size());
  dispatch<test::GatherQuadsProbe>(test::isa(), words.data(), idx.data(), int(idx.size()), out.data());
  int wrong = 0;
  for (size_t k = 0; k < idx.size(); ++k)
    for (size_t j = 0; j < 4; ++j) wrong += out[4 * k + j] != words[4 * size_t(idx[k]) + j];
  CHECK(wrong == 0);
}

}  // namespace test_simd_gather_pairs
