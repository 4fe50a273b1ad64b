#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>

#include "core/error.hpp"
#include "formats/registry.hpp"
#include "lines/validate.hpp"
#include "synth/streamlines.hpp"
#include "synth/synth.hpp"

using namespace linebake;

TEST(Synth, SegmentCountsFollowTheScale) {
  for (const synth::DataSetSpec& spec : synth::data_sets())
    for (double scale : {0.002, 0.01}) {
      const LineSet l = synth::generate({spec.name, scale, 7, false});
      const double expected = scale * static_cast<double>(spec.paper_segments);
      EXPECT_NEAR(static_cast<double>(l.segment_count()), expected, 0.1 * expected) << spec.name;
      // Lines: the paper's count within a factor of two (fewer lines, same character).
      const double paper_lines = scale * static_cast<double>(spec.paper_lines);
      EXPECT_GT(static_cast<double>(l.line_count()), 0.5 * paper_lines) << spec.name;
      EXPECT_LT(static_cast<double>(l.line_count()), 2.0 * paper_lines) << spec.name;
      ASSERT_EQ(l.attributes.size(), 1u);
      EXPECT_EQ(l.attributes[0].name, spec.attribute);
      EXPECT_TRUE(inspect(l).clean()) << spec.name << ": " << inspect(l).summary();
    }
}

TEST(Synth, DeterministicForAnyThreadCount) {
  for (const char* name : {"aneurysm", "clouds"}) {
    LineSet one, two;
    {
      tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
      one = synth::generate({name, 0.005, 3, false});
    }
    {
      tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
      two = synth::generate({name, 0.005, 3, false});
    }
    EXPECT_TRUE(one.same_data(two)) << name;
    const LineSet other_seed = synth::generate({name, 0.005, 4, false});
    EXPECT_FALSE(one.same_data(other_seed)) << name;
  }
}

TEST(Synth, AdaptiveStepStaysAccurate) {
  const LineSet l = synth::generate({"turbulence", 0.002, 1, true});
  EXPECT_NEAR(static_cast<double>(l.segment_count()), 35000, 3500);
  EXPECT_TRUE(inspect(l).clean());
}

TEST(Synth, SourcesAreAddressable) {
  const synth::SynthParams p = synth::parse_synth_source("synth:turbulence?scale=0.1&seed=3");
  EXPECT_EQ(p.name, "turbulence");
  EXPECT_EQ(p.scale, 0.1);
  EXPECT_EQ(p.seed, 3u);
  EXPECT_THROW(synth::parse_synth_source("synth:nothing"), Error);
  EXPECT_THROW(synth::parse_synth_source("synth:clouds?scale=abc"), Error);
  EXPECT_THROW(synth::parse_synth_source("synth:clouds?colour=red"), Error);
  const LineSet l = read_line_set("synth:convection?scale=0.001&seed=2");
  EXPECT_EQ(l.segment_count(), 9900u);
  EXPECT_EQ(source_format_name("synth:convection"), "synth");
}

TEST(Synth, StreamlinesFollowACircularFlow) {
  // Solid-body rotation about z: an RK4 streamline from (1, 0, 0) stays on the unit circle.
  struct Rotation : synth::FlowField {
    synth::dvec3 velocity(const synth::dvec3& p) const override { return {-p.y, p.x, 0}; }
    bool inside(const synth::dvec3& p) const override { return std::abs(p.z) < 1; }
    synth::dvec3 domain_min() const override { return synth::dvec3{-2}; }
    synth::dvec3 domain_max() const override { return synth::dvec3{2}; }
  } field;
  synth::IntegrationOptions o;
  o.step = 0.05;
  o.max_points = 200;
  o.both_directions = false;
  const auto line = synth::integrate_streamline(field, {1, 0, 0}, o);
  ASSERT_EQ(line.size(), 200u);
  for (const auto& p : line) EXPECT_NEAR(std::hypot(p.x, p.y), 1.0, 1e-7);
  // 199 steps of arc length 0.05.
  EXPECT_NEAR(std::atan2(line.back().y, line.back().x), std::remainder(199 * 0.05, 2 * M_PI), 1e-6);
}

TEST(Synth, FlowMeasures) {
  // v = (0, x, 0): vorticity (0, 0, 1); lambda2 of a pure shear is 0.
  struct Shear : synth::FlowField {
    synth::dvec3 velocity(const synth::dvec3& p) const override { return {0, p.x, 0}; }
    bool inside(const synth::dvec3&) const override { return true; }
    synth::dvec3 domain_min() const override { return synth::dvec3{-1}; }
    synth::dvec3 domain_max() const override { return synth::dvec3{1}; }
  } shear;
  const glm::dmat3 g = synth::velocity_gradient(shear, {0.3, 0.2, 0.1}, 1e-3);
  EXPECT_NEAR(synth::vorticity_magnitude(g), 1.0, 1e-9);
  EXPECT_NEAR(synth::lambda2(g), 0.0, 1e-9);
  // Solid-body rotation is a vortex: lambda2 = -omega^2 = -1.
  struct Spin : synth::FlowField {
    synth::dvec3 velocity(const synth::dvec3& p) const override { return {-p.y, p.x, 0}; }
    bool inside(const synth::dvec3&) const override { return true; }
    synth::dvec3 domain_min() const override { return synth::dvec3{-1}; }
    synth::dvec3 domain_max() const override { return synth::dvec3{1}; }
  } spin;
  EXPECT_NEAR(synth::lambda2(synth::velocity_gradient(spin, {0.1, 0.2, 0}, 1e-3)), -1.0, 1e-9);
  const glm::dvec3 e = synth::symmetric_eigenvalues(glm::dmat3(2, 1, 0, 1, 2, 0, 0, 0, 5));
  EXPECT_NEAR(e[0], 1, 1e-12);
  EXPECT_NEAR(e[1], 3, 1e-12);
  EXPECT_NEAR(e[2], 5, 1e-12);
}
