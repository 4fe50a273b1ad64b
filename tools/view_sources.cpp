#include "view_sources.hpp"

#include "core/error.hpp"
#include "flight_plan.hpp"
#include "techniques/framing.hpp"
#include "techniques/technique.hpp"

namespace linebake::cli {
namespace {

// A registry technique prepared on the window's context: the same calls as `linebake render`.
class TechniqueSource : public ViewSource {
 public:
  TechniqueSource(const Technique& technique, const TechniqueOptions& options,
                  const std::string& memory_budget, std::unique_ptr<PreparedTechnique> prepared,
                  const Bounds& bounds)
      : technique_(technique),
        options_(options),
        memory_budget_(memory_budget),
        prepared_(std::move(prepared)),
        bounds_(bounds) {}
  ViewFrame render(const Camera& camera, const TransferFunction& tf, int width,
                   int height) override {
    TechniqueFrame frame = prepared_->render(camera, tf, width, height);
    return {std::move(frame.image), frame.seconds, frame.frame_bytes};
  }
  Bounds bounds() const override { return bounds_; }
  void fit_frame(int width, int height) override {
    TechniqueOptions o = options_;
    o.width = width, o.height = height;
    check_frame_memory(technique_.info.name, std::to_string(width) + "x" + std::to_string(height),
                       estimate_frame_bytes(technique_, o), memory_budget_);
    // A Vulkan technique set the budget in force when it was prepared (the viewer keeps one at
    // a time); the CPU techniques set none.
    if (vulkan_ && o.context->host_budget() > 0) o.context->set_host_reserve(frame_output_bytes(o));
  }

 private:
  const Technique& technique_;
  TechniqueOptions options_;
  bool vulkan_ = technique_.info.vulkan || options_.on == "gpu";
  std::string memory_budget_;
  std::unique_ptr<PreparedTechnique> prepared_;
  Bounds bounds_;  // the cache's flight_bounds, every technique's
};

}  // namespace

const std::vector<std::string>& view_techniques() {
  // The registry's order; vrc twice (its CPU and its Vulkan compute caster).
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const std::string& name : technique_names()) {
      out.push_back(name);
      if (name == "vrc") out.push_back("vrc-gpu");
    }
    return out;
  }();
  return names;
}

std::unique_ptr<ViewSource> make_view_source(const std::string& technique, const CacheReader& cache,
                                             vk::Context& context, int width, int height,
                                             const std::string& memory_budget) {
  const bool vrc_gpu = technique == "vrc-gpu";
  const Technique& t = find_technique(vrc_gpu ? "vrc" : technique);
  TechniqueOptions options;
  options.context = &context;
  options.width = width, options.height = height;
  set_memory_budget(options, memory_budget);
  if (vrc_gpu) options.on = "gpu";
  if (auto reason = technique_unavailable(t, options, &cache)) throw Error(*reason);
  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  check_frame_memory(t.info.name, size, estimate_frame_bytes(t, options), memory_budget);
  return std::make_unique<TechniqueSource>(t, options, memory_budget,
                                           t.prepare(t.info, cache, cache.path(), options),
                                           flight_bounds(cache));
}

}  // namespace linebake::cli
