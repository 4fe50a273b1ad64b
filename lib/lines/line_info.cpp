#include "lines/line_info.hpp"

#include "lines/validate.hpp"

namespace linebake {
namespace {

// Without a finite value there is no range: null, not the 0 ValueRange holds (an attribute all
// NaN had read as a constant 0).
nlohmann::json range_json(const std::string& name, const ValueRange& r) {
  const bool any = r.finite > 0;
  return {{"name", name},
          {"min", any ? nlohmann::json(r.min) : nlohmann::json(nullptr)},
          {"max", any ? nlohmann::json(r.max) : nlohmann::json(nullptr)},
          {"nonfinite", r.nonfinite}};
}

nlohmann::json string_or_null(const std::string& s) {
  return s.empty() ? nlohmann::json(nullptr) : nlohmann::json(s);
}

}  // namespace

nlohmann::json line_set_info(const LineSet& lines, const std::string& source,
                             const std::string& format) {
  return line_set_info(compute_stats(lines), inspect(lines), lines.metadata, source, format);
}

nlohmann::json line_set_info(const LineSetStats& s, const ValidationReport& v,
                             const std::map<std::string, std::string>& metadata,
                             const std::string& source, const std::string& format) {
  nlohmann::json j;
  j["linebake_version"] = LINEBAKE_VERSION;
  j["source"] = string_or_null(source);
  j["format"] = string_or_null(format);
  j["lines"] = s.lines;
  j["points"] = s.points;
  j["segments"] = s.segments;
  j["bounds"] = s.bounds.empty ? nlohmann::json(nullptr)
                               : nlohmann::json{{"min", s.bounds.min}, {"max", s.bounds.max}};
  j["attributes"] = nlohmann::json::array();
  for (const auto& [name, r] : s.attribute_ranges) j["attributes"].push_back(range_json(name, r));
  j["line_attributes"] = nlohmann::json::array();
  for (const auto& [name, r] : s.line_attribute_ranges)
    j["line_attributes"].push_back(range_json(name, r));
  j["bytes"] = {{"positions", s.position_bytes},
                {"line_offsets", s.offset_bytes},
                {"attributes", s.attribute_bytes},
                {"total", s.total_bytes()}};
  j["validation"] = {{"clean", v.clean()},
                     {"invalid_points", v.invalid_points},
                     {"repeated_points", v.repeated_points},
                     {"short_lines", v.short_lines},
                     {"attribute_length_mismatches", v.attribute_length_mismatches},
                     {"nonfinite_attribute_values", v.nonfinite_attribute_values}};
  j["metadata"] = metadata;
  return j;
}

}  // namespace linebake
