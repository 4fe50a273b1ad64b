// The GPU radix sort (render/vulkan/radix_sort.hpp) against std::stable_sort on the CPU.

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <string>

#include "render/vulkan/context.hpp"
#include "render/vulkan/radix_sort.hpp"

using namespace linebake;

namespace {

// The expected result: pairs ordered by the key's low `bits` rounded up to whole 8-bit digits,
// equal keys in input order.
void expect_sorted_like_std(vk::RadixSorter& sorter, std::vector<uint32_t> keys, uint32_t bits) {
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

// Both paths of the sort: shared memory, and subgroups where the device has them (lavapipe
// does: subgroups of 8 with ballots; SubgroupPathWhereTheDeviceHasIt says when it does not).
void expect_sorted_like_std(std::vector<uint32_t> keys, uint32_t bits) {
  vk::Context ctx;
  for (const bool subgroups : {false, true}) {
    vk::RadixSorter sorter(ctx, subgroups);
    if (subgroups && sorter.subgroup_size() == 0) continue;
    SCOPED_TRACE(subgroups ? "subgroups of " + std::to_string(sorter.subgroup_size())
                           : std::string("shared memory"));
    expect_sorted_like_std(sorter, keys, bits);
  }
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

TEST(RadixSort, SizesAtTheChunksAndBlocksEdges) {
  // Chunks of 256 keys, blocks of 4,096: one short of, at and one past each edge, exact
  // multiples of a block, and a last block of one chunk and a bit.
  for (const size_t n :
       {2u, 255u, 256u, 257u, 4095u, 4096u, 4097u, 8192u, 8193u, 3u * 4096u + 256u}) {
    SCOPED_TRACE(n);
    expect_sorted_like_std(random_keys(n, 0xFFFFFFFFu, uint32_t(n)), 32);
  }
  // Three full blocks of one key, then of the largest digit: stability across blocks.
  expect_sorted_like_std(std::vector<uint32_t>(3 * 4096, 42u), 32);
  expect_sorted_like_std(std::vector<uint32_t>(3 * 4096 + 1, 0xFFFFFFFFu), 32);
}

// Dispatches go in rows of at most 65,535 workgroups (Vulkan's least promise a dimension);
// rows of 1, 2 and 3 here, with spare workgroups in the last row, sort as one row does.
TEST(RadixSort, WorkgroupsInRows) {
  vk::Context ctx;
  for (const bool subgroups : {false, true}) {
    vk::RadixSorter sorter(ctx, subgroups);
    if (subgroups && sorter.subgroup_size() == 0) continue;
    // 9 blocks of 4,096; 3 scan partitions.
    const std::vector<uint32_t> keys = random_keys(9 * 4096 - 100, 0xFFFFFFFFu, 11);
    std::vector<uint32_t> expected_keys = keys, expected_values(keys.size());
    std::iota(expected_values.begin(), expected_values.end(), 0u);
    sorter.sort(expected_keys, expected_values, 32);
    for (const uint32_t row : {1u, 2u, 3u}) {
      std::vector<uint32_t> k = keys, v(keys.size());
      std::iota(v.begin(), v.end(), 0u);
      sorter.sort(k, v, 32, row);
      EXPECT_EQ(k, expected_keys) << row << (subgroups ? " subgroups" : " shared");
      EXPECT_EQ(v, expected_values) << row;
    }
    EXPECT_TRUE(std::is_sorted(expected_keys.begin(), expected_keys.end()));
  }
}

TEST(RadixSort, RandomFullRangeKeys) {
  // Not a multiple of the block (4096) or the chunk (256): partial blocks and chunks.
  expect_sorted_like_std(random_keys(100'003, 0xFFFFFFFFu, 1), 32);
}

TEST(RadixSort, ManyDuplicatesStayInOrder) {
  // 16 distinct keys over 70,000 pairs: stability across chunks, blocks and passes.
  expect_sorted_like_std(random_keys(70'000, 15, 2), 32);
  std::vector<uint32_t> same(5'000, 0xABCD1234u);
  expect_sorted_like_std(same, 32);
}

TEST(RadixSort, LowBitsOnly) {
  // 8 bits: one pass (and the copy that brings the pairs back); 20 bits: three passes, by the
  // low 24 bits.
  expect_sorted_like_std(random_keys(9'000, 0xFFFFFFFFu, 3), 8);
  expect_sorted_like_std(random_keys(9'000, 0xFFFFFFFFu, 4), 20);
}

TEST(RadixSort, DescendingInputAndAllDigits) {
  std::vector<uint32_t> keys(300'000);
  for (size_t i = 0; i < keys.size(); ++i) keys[i] = uint32_t(keys.size() - i) * 2654435761u;
  expect_sorted_like_std(keys, 32);
}

TEST(RadixSort, SubgroupPathWhereTheDeviceHasIt) {
  vk::DeviceInfo info;
  info.subgroup_size = 32;
  info.subgroup_ballot_arithmetic = true;
  info.compute_full_subgroups = true;
  EXPECT_TRUE(vk::RadixSorter::subgroups_supported(info));
  for (const uint32_t size : {8u, 64u, 128u}) {
    info.subgroup_size = size;
    EXPECT_TRUE(vk::RadixSorter::subgroups_supported(info)) << size;
  }
  // Smaller subgroups than the shaders' shared arrays hold, larger than a ballot's 128 bits, or
  // a size that does not divide the workgroup.
  for (const uint32_t size : {0u, 4u, 24u, 256u}) {
    info.subgroup_size = size;
    EXPECT_FALSE(vk::RadixSorter::subgroups_supported(info)) << size;
  }
  info.subgroup_size = 32;
  info.compute_full_subgroups = false;
  EXPECT_FALSE(vk::RadixSorter::subgroups_supported(info));
  info.compute_full_subgroups = true;
  info.subgroup_ballot_arithmetic = false;
  EXPECT_FALSE(vk::RadixSorter::subgroups_supported(info));

  // The device here: the sorter takes the path the device allows, and never against the caller.
  vk::Context ctx;
  const bool supported = vk::RadixSorter::subgroups_supported(ctx.info());
  EXPECT_EQ(vk::RadixSorter(ctx).subgroup_size(), supported ? ctx.info().subgroup_size : 0u);
  EXPECT_EQ(vk::RadixSorter(ctx, false).subgroup_size(), 0u);
  if (!supported)
    GTEST_SKIP() << ctx.info().name << " has no subgroup path: the sorts above ran "
                 << "the shared-memory path only";
}
