#include "view_sources.hpp"

#include "core/error.hpp"
#include "techniques/technique.hpp"

namespace linebake::cli {
namespace {

// A registry technique prepared on the window's context: the same calls as `linebake render`.
class TechniqueSource : public ViewSource {
 public:
  explicit TechniqueSource(std::unique_ptr<PreparedTechnique> prepared)
      : prepared_(std::move(prepared)) {}
  ViewFrame render(const Camera& camera, const TransferFunction& tf, int width,
                   int height) override {
    TechniqueFrame frame = prepared_->render(camera, tf, width, height);
    return {std::move(frame.image), frame.seconds, frame.frame_bytes};
  }
  Bounds bounds() const override { return prepared_->bounds(); }

 private:
  std::unique_ptr<PreparedTechnique> prepared_;
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
                                             vk::Context& context,
                                             const std::string& memory_budget) {
  const bool vrc_gpu = technique == "vrc-gpu";
  const Technique& t = find_technique(vrc_gpu ? "vrc" : technique);
  TechniqueOptions options;
  options.context = &context;
  set_memory_budget(options, memory_budget);
  if (vrc_gpu) options.on = "gpu";
  if (auto reason = technique_unavailable(t, options, &cache)) throw Error(*reason);
  return std::make_unique<TechniqueSource>(t.prepare(t.info, cache, cache.path(), options));
}

}  // namespace linebake::cli
