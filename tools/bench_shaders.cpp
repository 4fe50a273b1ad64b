#include "bench_shaders.hpp"

#include <algorithm>
#include <cctype>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_contract.hpp"
#include "core/error.hpp"
#include "core/json_file.hpp"
#include "core/nearest.hpp"
#include "render/vulkan/shader_statistics.hpp"

namespace linebake::cli {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// Whether `name` contains one of `parts` (case-insensitive; no parts: yes).
bool matches(const std::string& name, const std::vector<std::string>& parts) {
  if (parts.empty()) return true;
  return std::any_of(parts.begin(), parts.end(), [&](const std::string& part) {
    return lower(name).find(lower(part)) != std::string::npos;
  });
}

std::string format_value(const vk::ShaderStatistic& s) {
  std::ostringstream out;
  if (s.integer)
    out << int64_t(s.value);
  else
    out << s.value;
  return out.str();
}

// The compute shaders the arguments name; a part that names none is a usage error.
std::vector<std::string> chosen_shaders(const std::vector<std::string>& parts) {
  const std::vector<std::string> all = vk::compute_shader_names();
  for (const std::string& part : parts)
    if (std::none_of(all.begin(), all.end(),
                     [&](const std::string& n) { return matches(n, {part}); })) {
      throw UsageError("--shaders: no compute shader's name contains '" + part +
                       "'; the compute shaders: " + name_list(all));
    }
  std::vector<std::string> chosen;
  for (const std::string& n : all)
    if (matches(n, parts)) chosen.push_back(n);
  return chosen;
}

}  // namespace

void bench_shaders(const BenchShadersArgs& args) {
  const std::vector<std::string> shaders = chosen_shaders(args.shaders);
  vk::ContextOptions options;
  options.device = args.device;
  options.shader_statistics = true;
  options.compile_only = true;
  vk::Context context(options);
  const vk::DeviceInfo& device = context.info();
  if (!device.shader_statistics)
    throw Error("bench shaders: " + device.name + " (" + device.driver +
                ") does not report its compiler's statistics: it has no "
                "VK_KHR_pipeline_executable_properties (lavapipe does not; RADV, NVIDIA's and "
                "AMD's drivers do)");
  nlohmann::ordered_json json = {{"device", device.name}, {"driver", device.driver}};
  json["shaders"] = nlohmann::json::array();
  if (!args.json) std::cout << "device: " << device.name << " (" << device.driver << ")\n";
  std::vector<std::string> reported;  // every statistic name the driver gave, in its order
  for (const std::string& name : shaders) {
    for (const vk::ShaderExecutable& e : vk::compute_shader_statistics(context, name)) {
      nlohmann::ordered_json statistics = nlohmann::ordered_json::object();
      std::vector<std::string> items;
      for (const vk::ShaderStatistic& s : e.statistics) {
        if (std::find(reported.begin(), reported.end(), s.name) == reported.end())
          reported.push_back(s.name);
        if (!matches(s.name, args.statistics)) continue;
        if (s.integer)
          statistics[s.name] = int64_t(s.value);
        else
          statistics[s.name] = s.value;
        // Hashes identify a binary; they say nothing to a reader of the table.
        if (args.statistics.empty() && lower(s.name).find("hash") != std::string::npos) continue;
        items.push_back(s.name + " " + format_value(s));
      }
      json["shaders"].push_back({{"shader", e.shader},
                                 {"executable", e.executable},
                                 {"subgroup_size", e.subgroup_size},
                                 {"statistics", statistics}});
      if (args.json) continue;
      std::cout << e.shader << " (" << e.executable << ", subgroup " << e.subgroup_size << ")\n";
      // Wrapped at about 100 columns.
      std::string row;
      for (size_t i = 0; i < items.size(); ++i) {
        const std::string item = items[i] + (i + 1 < items.size() ? "," : "");
        if (!row.empty() && row.size() + item.size() > 98)
          std::cout << " " << row << "\n", row.clear();
        row += " " + item;
      }
      if (!row.empty()) std::cout << " " << row << "\n";
    }
  }
  if (args.json) std::cout << json_text(json, 2) << "\n";
  // A --statistics part that names none of the driver's statistics (each driver has its own).
  for (const std::string& part : args.statistics)
    if (std::none_of(reported.begin(), reported.end(),
                     [&](const std::string& n) { return matches(n, {part}); })) {
      warn("bench shaders --statistics: " + device.driver + " reports no statistic named like '" +
           part + "'; it reports: " + name_list(reported));
    }
}

}  // namespace linebake::cli
