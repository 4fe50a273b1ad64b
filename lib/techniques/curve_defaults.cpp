#include "techniques/curve_defaults.hpp"

#include "tubes/tube_builder.hpp"

namespace linebake {

std::pair<float, std::string> curve_defaults(float radius, std::string attribute,
                                             const std::optional<Provenance>& tube_provenance,
                                             const LineSet& lines) {
  if (attribute.empty())
    attribute = tube_provenance ? tube_provenance->stats.value("attribute", "")
                                : (lines.attributes.empty() ? "" : lines.attributes[0].name);
  if (!(radius > 0) && tube_provenance && tube_provenance->stats.contains("radius_world"))
    radius = tube_provenance->stats["radius_world"].get<float>();
  if (!(radius > 0)) radius = TubeOptions{}.radius * compute_bounds(lines).diagonal();
  return {radius, attribute};
}

}  // namespace linebake
