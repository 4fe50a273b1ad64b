// The GPU radix sort (render/vulkan/radix_sort.hpp) against std::stable_sort on the CPU.

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "render/vulkan/context.hpp"
#include "render/vulkan/radix_sort.hpp"

using namespace linebake;

namespace {

// The expected result: pairs ordered by the key's low `bits` rounded up to whole 8-bit digits,
// equal keys in input order.
void expect_sorted_like_std(std::vector<uint32_t> keys, uint32_t bits) {
  vk::Context ctx;
  vk::RadixSorter sorter(ctx);
  std::vector<uint32_t> values(keys.size());
  std::iota(values.begin(), values.end(), 0u);
  const uint32_t digits = (bits + 7) / 8;
  const uint32_t mask = digits >= 4 ? 0xFFFFFFFFu : (1u << (8 * digits)) - 1u;
  std::vector<uint32_t> order(keys.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return (keys[a] & mask) < (keys[b] & mask); });
  std::vector<uint32_t> expected_keys(keys.size());
  for (size_t i = 0; i < order.size(); ++i) expected_keys[i] = keys[order[i]];
  sorter.sort(keys, values, bits);
  EXPECT_EQ(values, order);
  EXPECT_EQ(keys, expected_keys);
}

std::vector<uint32_t> random_keys(size_t n, uint32_t range, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<uint32_t> pick(0, range);
  std::vector<uint32_t> keys(n);
  for (uint32_t& k : keys) k = pick(rng);
  return keys;
}

}  // namespace

TEST(RadixSort, EmptyAndSingle) {
  expect_sorted_like_std({}, 32);
  expect_sorted_like_std({7}, 32);
}

TEST(RadixSort, RandomFullRangeKeys) {
  // Not a multiple of the block (1024) or the chunk (256): partial blocks and chunks.
  expect_sorted_like_std(random_keys(100'003, 0xFFFFFFFFu, 1), 32);
}

TEST(RadixSort, ManyDuplicatesStayInOrder) {
  // 16 distinct keys over 70,000 pairs: stability across chunks, blocks and passes.
  expect_sorted_like_std(random_keys(70'000, 15, 2), 32);
  std::vector<uint32_t> same(5'000, 0xABCD1234u);
  expect_sorted_like_std(same, 32);
}

TEST(RadixSort, LowBitsOnly) {
  // 8 bits: one pass (and the pass that brings the pairs back); 20 bits: three passes, by the
  // low 24 bits.
  expect_sorted_like_std(random_keys(9'000, 0xFFFFFFFFu, 3), 8);
  expect_sorted_like_std(random_keys(9'000, 0xFFFFFFFFu, 4), 20);
}

TEST(RadixSort, DescendingInputAndAllDigits) {
  std::vector<uint32_t> keys(300'000);
  for (size_t i = 0; i < keys.size(); ++i) keys[i] = uint32_t(keys.size() - i) * 2654435761u;
  expect_sorted_like_std(keys, 32);
}
