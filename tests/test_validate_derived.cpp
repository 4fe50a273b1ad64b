#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/error.hpp"
#include "lines/derived.hpp"
#include "lines/line_reader.hpp"
#include "lines/validate.hpp"

using namespace linebake;

namespace {
LineSet messy() {
  // line 0: a NaN in the middle splits it into [0,1] and [3,4]
  // line 1: a repeated point (dropped), stays one line of 2 points
  // line 2: a single point (dropped)
  // line 3: two equal points: after dropping the repeat, 1 point: dropped
  LineSet l;
  l.append_point(0, 0, 0);
  l.append_point(1, 0, 0);
  l.append_point(NAN, 0, 0);
  l.append_point(3, 0, 0);
  l.append_point(4, 0, 0);
  l.end_line();
  l.append_point(0, 1, 0);
  l.append_point(0, 1, 0);
  l.append_point(0, 2, 0);
  l.end_line();
  l.append_point(9, 9, 9);
  l.end_line();
  l.append_point(5, 5, 5);
  l.append_point(5, 5, 5);
  l.end_line();
  l.attributes.push_back({"id", {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10}});
  l.line_attributes.push_back({"line", {100, 101, 102, 103}});
  return l;
}
}  // namespace

TEST(Validate, CountsEveryProblem) {
  const ValidationReport r = inspect(messy());
  EXPECT_EQ(r.invalid_points, 1u);
  EXPECT_EQ(r.repeated_points, 2u);
  EXPECT_EQ(r.short_lines, 2u);
  EXPECT_TRUE(r.attribute_length_mismatches.empty());
  EXPECT_FALSE(r.clean());
}

TEST(Validate, RejectThrowsWithSourceName) {
  LineSet l = messy();
  try {
    validate(l, InvalidPolicy::reject, "input.obj");
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("input.obj"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("1 invalid points"), std::string::npos);
  }
}

// The first problem is placed by line and point, counted from the batch's place in the set.
TEST(Validate, TheFirstProblemIsPlaced) {
  EXPECT_EQ(inspect(messy()).first_problem,
            "line 0, point 2 (from 0): (nan, 0, 0), a NaN/Inf coordinate or one past 1e10");
  LineSet l = messy();
  try {
    validate(l, InvalidPolicy::reject, "input.csv (lines 70..73)", 70);
    FAIL() << "expected an error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("; the first: line 70, point 2 (from 0): (nan, 0, 0)"),
              std::string::npos)
        << e.what();
  }
  // Without the NaN line: the repeated point of line 1, then the single point of line 2.
  LineSet rest;
  copy_lines(messy(), 1, 4, rest);
  EXPECT_EQ(inspect(rest, 5).first_problem,
            "line 5, point 1 (from 0): (0, 1, 0), the same as the point before");
  LineSet single;
  copy_lines(messy(), 2, 3, single);
  EXPECT_EQ(inspect(single).first_problem, "line 0: fewer than 2 distinct points");
  // Reports of batches keep the earliest batch's first problem.
  ValidationReport total = inspect(single, 9);
  total.add(inspect(messy(), 20));
  EXPECT_EQ(total.first_problem, "line 9: fewer than 2 distinct points");
  EXPECT_EQ(inspect(LineSet()).first_problem, "");
}

TEST(Validate, RepairSplitsDropsAndKeepsAttributesAligned) {
  LineSet l = messy();
  const ValidationReport r = validate(l, InvalidPolicy::repair, "x");
  EXPECT_TRUE(r.repaired);
  EXPECT_EQ(l.line_count(), 3u);  // line 0 split in two, line 1 kept
  EXPECT_EQ(l.line_offsets, (std::vector<uint64_t>{0, 2, 4, 6}));
  EXPECT_EQ(l.attributes[0].values, (std::vector<float>{0, 1, 3, 4, 5, 7}));
  EXPECT_EQ(l.line_attributes[0].values, (std::vector<float>{100, 100, 101}));
  EXPECT_EQ(r.lines_split, 1u);
  EXPECT_EQ(r.lines_dropped, 2u);
  EXPECT_EQ(r.points_dropped, 5u);  // NaN, 2 repeats, 2 single points
  EXPECT_TRUE(inspect(l).clean());
}

TEST(Validate, AttributeLengthMismatchRejectedOrDropped) {
  LineSet l;
  l.append_point(0, 0, 0);
  l.append_point(1, 0, 0);
  l.end_line();
  l.attributes.push_back({"short", {1}});
  EXPECT_EQ(inspect(l).attribute_length_mismatches, std::vector<std::string>{"short"});
  LineSet copy = l;
  EXPECT_THROW(validate(copy, InvalidPolicy::reject, "x"), InputError);
  const ValidationReport r = validate(l, InvalidPolicy::repair, "x");
  EXPECT_EQ(r.attributes_dropped, 1u);
  EXPECT_TRUE(l.attributes.empty());
}

TEST(Validate, HugeCoordinatesAreInvalid) {
  LineSet l;
  l.append_point(0, 0, 0);
  l.append_point(2e10f, 0, 0);
  l.append_point(1, 0, 0);
  l.end_line();
  EXPECT_EQ(inspect(l).invalid_points, 1u);
}

TEST(Derived, CurvatureOfCircleIsInverseRadius) {
  // Points on a circle of radius 2: every interior vertex has curvature exactly 1/2.
  LineSet l;
  for (int i = 0; i < 12; ++i) {
    const double t = i * std::numbers::pi / 10;
    l.append_point(static_cast<float>(2 * std::cos(t)), static_cast<float>(2 * std::sin(t)), 3);
  }
  l.end_line();
  const Attribute k = derive_attribute(l, "curvature");
  for (float v : k.values) EXPECT_NEAR(v, 0.5f, 1e-5f);
}

TEST(Derived, LengthsAndIndices) {
  LineSet l;
  l.append_point(0, 0, 0);
  l.append_point(3, 4, 0);
  l.append_point(3, 4, 2);
  l.end_line();
  l.append_point(1, 1, 1);
  l.append_point(1, 1, 2);
  l.end_line();
  EXPECT_EQ(derive_attribute(l, "segment_length").values, (std::vector<float>{5, 2, 2, 1, 1}));
  EXPECT_EQ(derive_attribute(l, "arc_length").values, (std::vector<float>{0, 5, 7, 0, 1}));
  EXPECT_EQ(derive_attribute(l, "index_along_line").values, (std::vector<float>{0, 1, 2, 0, 1}));
  EXPECT_EQ(derive_attribute(l, "line_length").values, (std::vector<float>{7, 1}));
  // A straight line has no curvature.
  EXPECT_EQ(derive_attribute(l, "curvature").values[3], 0.0f);
  EXPECT_THROW(derive_attribute(l, "torsion"), Error);
}
