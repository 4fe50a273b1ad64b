#include "render_option_ranges.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "cli_contract.hpp"
#include "flight_plan.hpp"
#include "techniques/technique.hpp"

namespace linebake::cli {

namespace {

// CLI::Range over real numbers, refusing NaN too (no comparison with NaN is true, so CLI::Range
// lets it through), in CLI::Range's words.
RenderOptionCheck real_range(const std::string& option, double lo, double hi) {
  const CLI::Range range(lo, hi);
  return {option, CLI::Validator(
                      [range, lo, hi](std::string& text) -> std::string {
                        double value = 0;
                        if (CLI::detail::lexical_cast(text, value) && std::isnan(value))
                          return "Value " + text + " not in range " + std::to_string(lo) + " to " +
                                 std::to_string(hi);
                        return range(text);
                      },
                      range.get_description())};
}

}  // namespace

const std::vector<RenderOptionCheck>& render_option_checks() {
  static const std::vector<RenderOptionCheck> table = {
      {"--technique", one_of(technique_names())},
      {"--on", one_of({"cpu", "gpu"})},
      {"--rtx-geometry", one_of({"triangles", "capsules"})},
      {"--tiles-geometry", one_of({"capsules", "triangles"})},
      {"--tiles-sort", one_of({"auto", "subgroups", "shared"})},
      {"--tiles-strips", one_of({"none", "crowded", "all"})},
      {"--max-iterations", CLI::Range(1, 1 << 20)},
      {"--sort", one_of({"insertion", "shell", "heap", "quick-hybrid"})},
      {"--node-bytes", CLI::IsMember({24, 12})},
      {"--capacity", unsigned_integer()},
      {"--max-layers", CLI::Range(1, 100000)},
      {"--layers", CLI::Range(1, 64)},
      real_range("--tau-alpha", 0.0, 1.0),
      real_range("--tau-opaque", 0.0, 1.0),
      real_range("--beta", 0.0, 1.0),
      {"--moments", CLI::IsMember({4, 6, 8})},
      {"--moment-basis", one_of({"power", "trigonometric"})},
      real_range("--moment-bias", 0.0, 0.5),
      {"--wboit-weight", CLI::IsMember({0, 7, 8, 9})},
      {"--embree-geometry", one_of({"linear", "bezier", "capsules"})},
      {"--embree-quality", one_of({"low", "medium", "high"})},
      // A float option: a positive double past float's range (1e39) would become infinity.
      {"--radius", positive_float()},
      {"--frame-count", CLI::Range(1, 100000)},
      {"--frame", CLI::Range(0, 99999)},
      {"--frames", one_of({"all"})},
      {"--size", image_size_check()},
      {"--png-bits", CLI::IsMember({8, 16})},
      {"--hits", one_of({"filter", "stepping"})},
      {"--memory-budget", memory_budget_size()},
  };
  return table;
}

namespace {

const RenderOptionCheck* find_check(const std::string& option) {
  for (const RenderOptionCheck& c : render_option_checks())
    if (c.option == option) return &c;
  return nullptr;
}

}  // namespace

const CLI::Validator& render_option_check(const std::string& option) {
  if (const RenderOptionCheck* c = find_check(option)) return c->check;
  throw std::logic_error("render_option_check: no check for " + option);
}

std::string render_option_problem(const std::string& option, const std::string& value) {
  const RenderOptionCheck* c = find_check(option);
  if (!c) return {};
  std::string text = value;
  std::string problem;
  try {
    problem = c->check(text);
  } catch (const CLI::ValidationError& e) {  // as CLI11's Option::_validate reports it
    problem = e.what();
  }
  return problem.empty() ? problem : option + ": " + problem;
}

}  // namespace linebake::cli
