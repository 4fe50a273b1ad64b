// What linebake holds and this machine can run: `linebake techniques` (the technique registry),
// `linebake formats` (the format table), `linebake version`, `linebake help [COMMAND]`.

#include <H5public.h>
#include <embree3/rtcore_config.h>

#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.hpp"
#include "core/error.hpp"
#include "core/json_file.hpp"
#include "core/nearest.hpp"
#include "formats/registry.hpp"
#include "source_revision.hpp"
#include "techniques/technique.hpp"

namespace linebake::cli {
namespace {

std::string joined(const std::vector<std::string>& items, const char* separator = ", ") {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : separator) + item;
  return out;
}

// What a technique needs of the machine, in words.
std::string needs(const TechniqueInfo& info) {
  if (info.ray_tracing) return "Vulkan ray tracing";
  if (info.vulkan) return "Vulkan";
  if (info.name == "vrc") return "CPU (--on gpu: Vulkan)";
  return "CPU";
}

}  // namespace

Command add_techniques(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "techniques", "The rendering techniques: what each reads, needs, and whether it runs here");
  auto json = std::make_shared<bool>(false);
  auto device = std::make_shared<std::string>();
  sub->add_flag("--json", *json, "As JSON on stdout");
  sub->add_option("--device", *device, "Vulkan device to check against (part of its name)");
  return [json, device] {
    nlohmann::json rows = nlohmann::json::array();
    for (const Technique& t : techniques()) {
      TechniqueOptions options;
      options.device = *device;
      const std::optional<std::string> why = technique_unavailable(t, options);
      std::vector<std::string> own;
      for (const std::string& o : t.info.options) own.push_back("--" + o);
      rows.push_back({{"name", t.info.name},
                      {"summary", t.info.summary},
                      {"reads", t.info.assets},
                      {"needs", needs(t.info)},
                      {"exact", t.info.exact},
                      {"options", own},
                      {"available", !why},
                      {"unavailable_reason", why ? *why : ""}});
    }
    if (*json) {
      std::cout << json_text(rows, 2) << "\n";
      return;
    }
    std::cout << std::left << std::setw(10) << "technique" << std::setw(8) << "reads"
              << std::setw(24) << "needs" << std::setw(7) << "exact"
              << "here\n";
    for (const nlohmann::json& r : rows) {
      std::cout << std::setw(10) << r["name"].get<std::string>() << std::setw(8)
                << joined(r["reads"].get<std::vector<std::string>>()) << std::setw(24)
                << r["needs"].get<std::string>() << std::setw(7)
                << (r["exact"].get<bool>() ? "yes" : "no")
                << (r["available"].get<bool>()
                        ? std::string("yes")
                        : "no: " + r["unavailable_reason"].get<std::string>())
                << "\n";
      std::cout << "          " << r["summary"].get<std::string>() << "\n";
      const auto own = r["options"].get<std::vector<std::string>>();
      if (!own.empty()) std::cout << "          options: " << joined(own) << "\n";
    }
  };
}

Command add_formats(CLI::App& app) {
  auto* sub = app.add_subcommand("formats",
                                 "The line-set formats: extensions, read, write, "
                                 "what each holds");
  auto json = std::make_shared<bool>(false);
  sub->add_flag("--json", *json, "As JSON on stdout");
  return [json] {
    nlohmann::json rows = nlohmann::json::array();
    for (const FormatInfo& f : format_table()) {
      std::vector<std::string> extensions(f.extensions.begin(), f.extensions.end());
      rows.push_back({{"name", f.name},
                      {"extensions", extensions},
                      {"read", f.readable},
                      {"write", f.writable},
                      {"line_attributes", f.line_attributes},
                      {"metadata", f.metadata}});
    }
    rows.push_back({{"name", "synth"},
                    {"extensions", {"synth:NAME?scale=S&seed=N"}},
                    {"read", true},
                    {"write", false},
                    {"line_attributes", false},
                    {"metadata", true}});
    if (*json) {
      std::cout << json_text(rows, 2) << "\n";
      return;
    }
    const auto yes = [](const nlohmann::json& v) { return v.get<bool>() ? "yes" : "no"; };
    std::cout << std::left << std::setw(10) << "format" << std::setw(27) << "extensions"
              << std::setw(6) << "read" << std::setw(7) << "write" << std::setw(16)
              << "line attributes"
              << "metadata\n";
    for (const nlohmann::json& r : rows)
      std::cout << std::setw(10) << r["name"].get<std::string>() << std::setw(27)
                << joined(r["extensions"].get<std::vector<std::string>>(), " ") << std::setw(6)
                << yes(r["read"]) << std::setw(7) << yes(r["write"]) << std::setw(16)
                << yes(r["line_attributes"]) << yes(r["metadata"]) << "\n";
    std::cout << "Every format holds positions and vertex attributes (binlines version 1 without "
                 "their names). A linebake cache (.lbc.h5, or any name) reads as hdf5.\n";
  };
}

Command add_version(CLI::App& app) {
  auto* sub =
      app.add_subcommand("version", "linebake's version and the libraries it was built with");
  auto json = std::make_shared<bool>(false);
  sub->add_flag("--json", *json, "As JSON on stdout");
  return [json] {
    unsigned major = 0, minor = 0, release = 0;
    H5get_libversion(&major, &minor, &release);
    const nlohmann::json v = {{"linebake", LINEBAKE_VERSION},
                              {"source_revision", LINEBAKE_SOURCE_REVISION},
                              {"hdf5", std::to_string(major) + "." + std::to_string(minor) + "." +
                                           std::to_string(release)},
                              {"embree", RTC_VERSION_STRING}};
    if (*json) {
      std::cout << json_text(v, 2) << "\n";
      return;
    }
    std::cout << "linebake " << LINEBAKE_VERSION << " (HDF5 " << v["hdf5"].get<std::string>()
              << ", Embree " << RTC_VERSION_STRING << "), source " << LINEBAKE_SOURCE_REVISION
              << "\n";
  };
}

Command add_help(CLI::App& app) {
  auto* sub = app.add_subcommand("help", "Help for a command: linebake help render");
  auto command = std::make_shared<std::vector<std::string>>();
  sub->add_option("command", *command, "A command, and a bench kind (help bench voxels)");
  return [&app, command] {
    const CLI::App* target = &app;
    for (const std::string& name : *command) {
      std::vector<std::string> names;
      const CLI::App* found = nullptr;
      for (const CLI::App* s : target->get_subcommands({})) {
        names.push_back(s->get_name());
        if (s->get_name() == name) found = s;
      }
      if (!found)
        throw UsageError("help: unknown command '" + name + "'" + did_you_mean(name, names));
      target = found;
    }
    // The usage line names the whole command, as `COMMAND --help` prints it.
    std::string prefix;
    for (const CLI::App* p = target->get_parent(); p; p = p->get_parent())
      prefix = p->get_name() + (prefix.empty() ? "" : " " + prefix);
    std::cout << target->help(prefix);
  };
}

}  // namespace linebake::cli
