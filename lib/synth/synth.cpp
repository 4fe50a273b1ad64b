#include "synth/synth.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <glm/geometric.hpp>

#include "core/error.hpp"
#include "lines/derived.hpp"
#include "synth/streamlines.hpp"

namespace linebake::synth {

const std::vector<DataSetSpec>& data_sets() {
  static const std::vector<DataSetSpec> specs{
      {"aneurysm", 9200, 2300000, "vorticity",
       "streamlines in a vessel with a saccular bulge, swirl inside the bulge"},
      {"convection", 100000, 9900000, "curvature",
       "short streamlines in Rayleigh-Benard-like rolls in a flat box"},
      {"turbulence", 80000, 17500000, "lambda2_max",
       "long streamlines in multi-scale divergence-free turbulence"},
      {"clouds", 400000, 39600000, "vorticity",
       "streamlines in a sheared boundary layer with convective plumes"},
  };
  return specs;
}

const DataSetSpec& find_data_set(const std::string& name) {
  for (const DataSetSpec& s : data_sets())
    if (s.name == name) return s;
  throw Error("unknown synthetic data set '" + name +
              "' (expected aneurysm, convection, turbulence or clouds)");
}

bool is_synth_source(const std::string& source) {
  return source.rfind("synth:", 0) == 0;
}

SynthParams parse_synth_source(const std::string& source) {
  if (!is_synth_source(source)) throw Error("not a synthetic source: " + source);
  const std::string rest = source.substr(6);
  const size_t q = rest.find('?');
  SynthParams params;
  params.name = rest.substr(0, q);
  find_data_set(params.name);
  if (q == std::string::npos) return params;
  std::string query = rest.substr(q + 1);
  size_t start = 0;
  while (start <= query.size()) {
    const size_t amp = std::min(query.find('&', start), query.size());
    const std::string pair = query.substr(start, amp - start);
    start = amp + 1;
    if (pair.empty()) continue;
    const size_t eq = pair.find('=');
    const std::string key = pair.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : pair.substr(eq + 1);
    const char* end = value.data() + value.size();
    if (key == "scale") {
      auto r = std::from_chars(value.data(), end, params.scale);
      if (r.ec != std::errc() || r.ptr != end) throw Error(source + ": bad scale '" + value + "'");
    } else if (key == "seed") {
      auto r = std::from_chars(value.data(), end, params.seed);
      if (r.ec != std::errc() || r.ptr != end) throw Error(source + ": bad seed '" + value + "'");
    } else if (key == "step") {
      if (value != "fixed" && value != "adaptive")
        throw Error(source + ": step must be fixed or adaptive");
      params.adaptive = value == "adaptive";
    } else {
      throw Error(source + ": unknown parameter '" + key + "' (expected scale, seed, step)");
    }
  }
  return params;
}

namespace {

struct Recipe {
  std::unique_ptr<FlowField> field;
  IntegrationOptions integration;
  uint32_t mean_points;  // the paper's mean points per line
  double gradient_step;  // finite-difference step for flow measures
};

Recipe make_recipe(const DataSetSpec& spec, uint64_t seed) {
  Recipe r;
  r.mean_points = static_cast<uint32_t>(spec.paper_segments / spec.paper_lines + 1);
  if (spec.name == "aneurysm") {
    r.field = make_aneurysm_field(seed);
    r.integration.step = 0.04;
  } else if (spec.name == "convection") {
    r.field = make_convection_field(seed);
    r.integration.step = 0.03;
  } else if (spec.name == "turbulence") {
    r.field = make_turbulence_field(seed);
    r.integration.step = 0.02;
  } else {
    r.field = make_clouds_field(seed);
    r.integration.step = 0.1;
  }
  r.gradient_step = r.integration.step * 0.25;
  return r;
}

struct GeneratedLine {
  std::vector<float> xyz;
  std::vector<float> attribute;  // per point; empty for curvature (derived afterwards)
};

GeneratedLine generate_line(const Recipe& recipe, const DataSetSpec& spec, uint64_t seed,
                            uint64_t index) {
  Rng rng(seed * 0x9E3779B97F4A7C15ull ^ (index + 1) * 0xD1B54A32D192ED03ull);
  IntegrationOptions options = recipe.integration;
  // Lengths vary around the paper's mean: uniform in [0.4, 1.6] x mean.
  options.max_points =
      std::max<uint32_t>(2, static_cast<uint32_t>(recipe.mean_points * rng.uniform(0.4, 1.6)));
  const dvec3 seed_point = recipe.field->seed(rng);
  std::vector<dvec3> points = integrate_streamline(*recipe.field, seed_point, options);

  GeneratedLine line;
  if (points.size() < 2) return line;
  line.xyz.reserve(points.size() * 3);
  for (const dvec3& p : points)
    line.xyz.insert(line.xyz.end(),
                    {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});
  if (spec.attribute == "vorticity") {
    for (const dvec3& p : points)
      line.attribute.push_back(static_cast<float>(
          vorticity_magnitude(velocity_gradient(*recipe.field, p, recipe.gradient_step))));
  } else if (spec.attribute == "lambda2_max") {
    double strongest = 0;
    for (const dvec3& p : points)
      strongest =
          std::max(strongest, -lambda2(velocity_gradient(*recipe.field, p, recipe.gradient_step)));
    line.attribute.assign(points.size(), static_cast<float>(strongest));
  }
  return line;
}

}  // namespace

LineSet generate(const SynthParams& params, const ProgressFn& progress) {
  const DataSetSpec& spec = find_data_set(params.name);
  if (!(params.scale > 0 && params.scale <= 4))
    throw Error("synthetic scale must be in (0, 4], got " + std::to_string(params.scale));
  Recipe recipe = make_recipe(spec, params.seed);
  recipe.integration.adaptive = params.adaptive;
  const auto target =
      static_cast<uint64_t>(std::llround(params.scale * static_cast<double>(spec.paper_segments)));

  LineSet lines;
  lines.metadata["source"] = "synth:" + spec.name;
  lines.metadata["synth.scale"] = std::to_string(params.scale);
  lines.metadata["synth.seed"] = std::to_string(params.seed);
  lines.metadata["synth.step"] = params.adaptive ? "adaptive" : "fixed";
  lines.metadata["synth.description"] = spec.description;
  const uint64_t expected_points = target + target / recipe.mean_points + 16;
  lines.positions.reserve(3 * expected_points);
  std::vector<float> attribute;
  attribute.reserve(expected_points);

  uint64_t segments = 0, next_index = 0;
  constexpr size_t kBatch = 2048;
  std::vector<GeneratedLine> batch(kBatch);
  while (segments < target) {
    tbb::parallel_for(size_t{0}, kBatch, [&](size_t i) {
      batch[i] = generate_line(recipe, spec, params.seed, next_index + i);
    });
    next_index += kBatch;
    for (GeneratedLine& line : batch) {
      const uint64_t n = line.xyz.size() / 3;
      if (n < 2 || segments >= target) continue;
      const uint64_t take = std::min<uint64_t>(n, target - segments + 1);
      lines.positions.insert(lines.positions.end(), line.xyz.begin(),
                             line.xyz.begin() + static_cast<std::ptrdiff_t>(3 * take));
      if (!line.attribute.empty())
        attribute.insert(attribute.end(), line.attribute.begin(),
                         line.attribute.begin() + static_cast<std::ptrdiff_t>(take));
      lines.end_line();
      segments += take - 1;
    }
    if (progress) progress(segments, target);
    if (next_index > 64 * (target + 1)) throw Error("synthetic generation made no progress");
  }
  if (spec.attribute == "curvature") {
    lines.attributes.push_back(derive_attribute(lines, "curvature"));
  } else {
    lines.attributes.push_back({spec.attribute, std::move(attribute)});
  }
  return lines;
}

}  // namespace linebake::synth
