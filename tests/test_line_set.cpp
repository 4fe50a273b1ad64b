#include <gtest/gtest.h>

#include <cmath>

#include "lines/line_set.hpp"
#include "lines/validate.hpp"

using namespace linebake;

TEST(LineSet, CountsBoundsAndBytes) {
  LineSet lines;
  lines.append_point(0, 0, 0);
  lines.append_point(1, 2, 3);
  lines.append_point(-1, 5, 0);
  lines.end_line();
  lines.append_point(4, -2, 1);
  lines.append_point(4, -2, 2);
  lines.end_line();
  lines.attributes.push_back({"a", {1, 2, NAN, -4, 8}});
  EXPECT_EQ(lines.line_count(), 2u);
  EXPECT_EQ(lines.point_count(), 5u);
  EXPECT_EQ(lines.segment_count(), 3u);  // 2 + 1
  const LineSetStats s = compute_stats(lines);
  EXPECT_EQ(s.bounds.min, (std::array<float, 3>{-1, -2, 0}));
  EXPECT_EQ(s.bounds.max, (std::array<float, 3>{4, 5, 3}));
  EXPECT_EQ(s.position_bytes, 5u * 12);
  EXPECT_EQ(s.offset_bytes, 3u * 8);
  EXPECT_EQ(s.attribute_bytes, 5u * 4);
  ASSERT_EQ(s.attribute_ranges.size(), 1u);
  EXPECT_EQ(s.attribute_ranges[0].second.min, -4);
  EXPECT_EQ(s.attribute_ranges[0].second.max, 8);
  EXPECT_EQ(s.attribute_ranges[0].second.nonfinite, 1u);
}

// linebake-mpi merges each rank's figures: the merged ones are the whole set's, whatever the
// split (the offsets' leading 0 had been counted once a rank: 8 bytes more a rank).
TEST(LineSet, MergedStatisticsAreTheWholeSets) {
  LineSet whole, first, second;
  for (int l = 0; l < 5; ++l) {
    LineSet& part = l < 2 ? first : second;
    for (int p = 0; p <= l; ++p) {
      whole.append_point(float(l), float(p), 0);
      part.append_point(float(l), float(p), 0);
    }
    whole.end_line();
    part.end_line();
  }
  const LineSetStats expected = compute_stats(whole);
  const LineSetStats empty = compute_stats(LineSet{});
  for (const LineSetStats& merged :
       {merge(compute_stats(first), compute_stats(second)),
        merge(merge(compute_stats(first), empty), compute_stats(second))}) {
    EXPECT_EQ(merged.lines, 5u);
    EXPECT_EQ(merged.points, 15u);
    EXPECT_EQ(merged.offset_bytes, 6u * 8);
    EXPECT_EQ(merged.total_bytes(), expected.total_bytes());
    EXPECT_EQ(merged.bounds.max, expected.bounds.max);
  }
}

TEST(LineSet, BoundsSkipTheInvalidPoints) {
  // Validation's invalid points: a NaN or Inf coordinate, or one past 1e10 (the points a bake
  // drops or refuses); 1e10 itself is valid.
  LineSet lines;
  lines.append_point(NAN, 100, 100);
  lines.append_point(1, 1, 1);
  lines.append_point(2, INFINITY, 0);
  lines.append_point(3, 1.5e10f, 0);
  lines.append_point(-2e10f, 0, 0);
  lines.append_point(1e10f, 2, -1);
  lines.end_line();
  const Bounds b = compute_bounds(lines);
  EXPECT_FALSE(b.empty);
  EXPECT_EQ(b.min, (std::array<float, 3>{1, 1, -1}));
  EXPECT_EQ(b.max, (std::array<float, 3>{1e10f, 2, 1}));
  EXPECT_EQ(inspect(lines).invalid_points, 4u);
}

TEST(LineSet, SameDataIsBitExact) {
  LineSet a;
  a.append_point(0.0f, 1, 2);
  a.append_point(1, 1, 2);
  a.end_line();
  LineSet b = a;
  EXPECT_TRUE(a.same_data(b));
  b.positions[0] = -0.0f;  // equal as a float, different bits
  EXPECT_FALSE(a.same_data(b));
  b = a;
  b.attributes.push_back({"x", {1, 2}});
  EXPECT_FALSE(a.same_data(b));
}
