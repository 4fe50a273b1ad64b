#include "synth/synth.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <glm/geometric.hpp>

#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/nearest.hpp"
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
  // A mistyped source is a bad input (exit 2), named with the nearest of what there is.
  std::vector<std::string> names;
  for (const DataSetSpec& s : data_sets()) names.push_back(s.name);
  if (std::find(names.begin(), names.end(), params.name) == names.end())
    throw InputError(source, "",
                     "unknown synthetic data set '" + params.name + "' (" + name_list(names) + ")" +
                         did_you_mean(params.name, names));
  if (q == std::string::npos) return params;
  std::string query = rest.substr(q + 1);
  std::vector<std::string> given;  // a key given twice is refused, not the last one taken
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
    if (std::find(given.begin(), given.end(), key) != given.end())
      throw InputError(source, key, "given twice; give it once");
    given.push_back(key);
    if (key == "scale") {
      auto r = std::from_chars(value.data(), end, params.scale);
      if (r.ec != std::errc() || r.ptr != end || !(params.scale >= kMinScale) ||
          !(params.scale <= kMaxScale))
        throw InputError(source, "scale",
                         "'" + value + "' is not a number from 1e-06 to " +
                             std::to_string(int(kMaxScale)) + " (as synth --scale)");
    } else if (key == "seed") {
      auto r = std::from_chars(value.data(), end, params.seed);
      if (r.ec != std::errc() || r.ptr != end)
        throw InputError(source, "seed", "'" + value + "' is not an unsigned integer");
    } else if (key == "step") {
      if (value != "fixed" && value != "adaptive")
        throw InputError(source, "step", "'" + value + "': fixed or adaptive");
      params.adaptive = value == "adaptive";
    } else {
      throw InputError(source, "",
                       "unknown parameter '" + key + "' (scale, seed, step)" +
                           did_you_mean(key, {"scale", "seed", "step"}));
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

// Lines are integrated 2048 at a time in parallel (each from its own seeded generator, so the
// lines do not depend on the thread count) and handed out in index order until the segment
// budget is met; the last line is cut to fit.
class Generator : public LineReader {
 public:
  Generator(const SynthParams& params, ProgressFn progress)
      : params_(params), spec_(find_data_set(params.name)), progress_(std::move(progress)) {
    if (!(params.scale > 0 && params.scale <= kMaxScale))
      throw Error("synthetic scale must be in (0, " + std::to_string(int(kMaxScale)) + "], got " +
                  std::to_string(params.scale));
    recipe_ = make_recipe(spec_, params.seed);
    recipe_.integration.adaptive = params.adaptive;
    target_ = static_cast<uint64_t>(
        std::llround(params.scale * static_cast<double>(spec_.paper_segments)));
    header_.metadata["source"] = "synth:" + spec_.name;
    header_.metadata["synth.scale"] = std::to_string(params.scale);
    header_.metadata["synth.seed"] = std::to_string(params.seed);
    header_.metadata["synth.step"] = params.adaptive ? "adaptive" : "fixed";
    header_.metadata["synth.description"] = spec_.description;
    header_.attributes.push_back({spec_.attribute, {}});
  }

  bool next(LineSet& batch, uint64_t max_points) override {
    copy_lines(header_, 0, 0, batch);
    std::vector<float>& attribute = batch.attributes[0].values;
    const bool derived = spec_.attribute == "curvature";
    while (segments_ < target_) {
      if (queued_ == queue_.size()) {
        refill();
        // Every 2,048 lines, not only per batch: a set of one batch takes seconds to generate.
        if (progress_) progress_(segments_, target_);
      }
      GeneratedLine& line = queue_[queued_];
      const uint64_t n = line.xyz.size() / 3;
      if (n < 2) {
        ++queued_;
        continue;
      }
      const uint64_t take = std::min<uint64_t>(n, target_ - segments_ + 1);
      if (batch.line_count() > 0 && batch.point_count() + take > max_points) break;
      batch.positions.insert(batch.positions.end(), line.xyz.begin(),
                             line.xyz.begin() + static_cast<std::ptrdiff_t>(3 * take));
      if (!derived)
        attribute.insert(attribute.end(), line.attribute.begin(),
                         line.attribute.begin() + static_cast<std::ptrdiff_t>(take));
      batch.end_line();
      segments_ += take - 1;
      ++queued_;
      ++lines_read_;
    }
    if (derived && batch.line_count() > 0)
      batch.attributes[0].values = derive_attribute(batch, "curvature").values;
    if (progress_) progress_(segments_, target_);
    return batch.line_count() > 0;
  }

 private:
  void refill() {
    constexpr size_t kBatch = 2048;
    if (next_index_ > 64 * (target_ + 1)) throw Error("synthetic generation made no progress");
    queue_.resize(kBatch);
    // A batch of long lines takes seconds (aneurysm at scale 1: about one): Ctrl-C between
    // lines, not batches (the lines skipped would otherwise be the last batch's).
    StopLatch stop;
    tbb::parallel_for(size_t{0}, kBatch, [&](size_t i) {
      if (!stop.stopped()) queue_[i] = generate_line(recipe_, spec_, params_.seed, next_index_ + i);
    });
    stop.throw_if_stopped();
    next_index_ += kBatch;
    queued_ = 0;
  }

  SynthParams params_;
  const DataSetSpec& spec_;
  ProgressFn progress_;
  Recipe recipe_;
  uint64_t target_ = 0, segments_ = 0, next_index_ = 0;
  std::vector<GeneratedLine> queue_;
  size_t queued_ = 0;
};

}  // namespace

std::unique_ptr<LineReader> open_generator(const SynthParams& params, const ProgressFn& progress) {
  return std::make_unique<Generator>(params, progress);
}

LineSet generate(const SynthParams& params, const ProgressFn& progress) {
  Generator generator(params, progress);
  return read_all(generator);
}

}  // namespace linebake::synth
