#include "pipeline/pipeline.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>
#include <sstream>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/json_file.hpp"
#include "core/nearest.hpp"
#include "pipeline/bake.hpp"
#include "render/camera.hpp"
#include "render/transfer_function.hpp"
#include "techniques/technique.hpp"

namespace linebake {
namespace {

// A number as a command-line value: integers whole (signed or not), others to the last bit
// (%.17g; infinities as inf, which the options' parsers read). List items are written otherwise
// (options_to_args), as they always were: the steps' keys hold the command lines.
std::string number_argument(const nlohmann::json& value) {
  if (value.is_number_unsigned()) return std::to_string(value.get<uint64_t>());
  if (value.is_number_integer()) return std::to_string(value.get<int64_t>());
  char text[64];
  std::snprintf(text, sizeof text, "%.17g", value.get<double>());
  return text;
}

// {"grid": 32, "early-termination": true, "assets": ["tubes", "voxels"]} -> --grid 32
// --early-termination --assets tubes,voxels: a pipeline's options are the CLI's long options.
std::vector<std::string> options_to_args(const nlohmann::json& options, const std::string& file,
                                         const std::string& where) {
  std::vector<std::string> args;
  if (options.is_null()) return args;
  if (!options.is_object()) throw InputError(file, where, "options must be an object");
  for (const auto& [name, value] : options.items()) {
    const std::string flag = "--" + name;
    if (value.is_boolean()) {
      if (value.get<bool>()) args.push_back(flag);
    } else if (value.is_string()) {
      args.insert(args.end(), {flag, value.get<std::string>()});
    } else if (value.is_number()) {
      args.insert(args.end(), {flag, number_argument(value)});
    } else if (value.is_array()) {
      std::string joined;
      for (const auto& v : value) {
        if (!v.is_string() && !v.is_number())
          throw InputError(file, where + "." + name, "list items must be strings or numbers");
        // Finite numbers as JSON writes them (the shortest that reads back; the steps' keys
        // hold these command lines), infinities as the options' parsers read them.
        const bool finite = !v.is_number_float() || std::isfinite(v.get<double>());
        joined += (joined.empty() ? "" : ",") + (v.is_string() ? v.get<std::string>()
                                                 : finite      ? json_text(v)
                                                               : number_argument(v));
      }
      args.insert(args.end(), {flag, joined});
    } else {
      throw InputError(file, where + "." + name, "must be a boolean, number, string or list");
    }
  }
  return args;
}

std::string string_at(const nlohmann::json& j, const char* key, const std::string& fallback,
                      const std::string& file, const std::string& where) {
  if (!j.contains(key)) return fallback;
  if (!j[key].is_string())
    throw InputError(file, where.empty() ? std::string(key) : where + "." + key,
                     "must be a string");
  return j[key].get<std::string>();
}

bool safe_name(const std::string& name) {
  if (name.empty() || name == "." || name == "..") return false;
  for (char c : name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'))
      return false;
  return true;
}

std::vector<std::string> names_at(const nlohmann::json& j, const char* key,
                                  const std::set<std::string>& allowed, const std::string& file,
                                  const std::string& where) {
  std::vector<std::string> names;
  if (!j.contains(key)) return names;
  const std::string at = where.empty() ? std::string(key) : where + "." + key;
  if (!j[key].is_array() || j[key].empty()) throw InputError(file, at, "a non-empty list of names");
  for (const auto& v : j[key]) {
    if (!v.is_string() || !allowed.count(v.get<std::string>()))
      throw InputError(file, at, json_text(v) + " is not one of the pipeline's " + key);
    names.push_back(v.get<std::string>());
  }
  return names;
}

bool listed(const std::vector<std::string>& only, const std::string& name) {
  return only.empty() || std::find(only.begin(), only.end(), name) != only.end();
}

std::string key_of(const std::vector<std::string>& parts) {
  Hasher h;
  for (const std::string& p : parts) h.update(std::string_view(p));
  return h.hex();
}

// A transfer function's part of its outputs' names: a file's name without folder and ".json"
// (semi-vivid.json: "semi-vivid"), so outputs stay in the dataset's folder with readable names.
std::string transfer_function_stem(const std::string& tf) {
  const std::filesystem::path path(tf);
  return path.extension() == ".json" ? path.stem().string() : tf;
}

std::string error_gain_argument() {
  char text[32];
  std::snprintf(text, sizeof text, "%g", kErrorImageGain);
  return text;
}

}  // namespace

Pipeline parse_pipeline(const nlohmann::json& j, const std::string& file) {
  if (!j.is_object())
    throw InputError(file, "", "a pipeline is an object (a JSON object or a YAML mapping)");
  static const std::set<std::string> known{
      "name",   "output", "datasets", "assets", "techniques", "transfer_functions",
      "flight", "frames", "warm_up",  "size",   "reference"};
  for (const auto& [key, value] : j.items())
    if (!known.count(key)) throw InputError(file, key, "unknown pipeline key");
  Pipeline p;
  p.file = file;
  p.name = string_at(j, "name", std::filesystem::path(file).stem().string(), file, "");
  // The default output is out/<name>: a name may not lead it elsewhere.
  if (p.name.empty() || p.name == "." || p.name == ".." ||
      p.name.find_first_of("/\\") != std::string::npos)
    throw InputError(file, "name",
                     "'" + p.name +
                         "': a name without '/' or '\\', not empty, '.' or '..' (the "
                         "default output directory is out/<name>)");
  p.output = string_at(j, "output", "out/" + p.name, file, "");
  if (p.output.empty()) throw InputError(file, "output", "an empty output directory");
  if (!j.contains("datasets") || !j["datasets"].is_array() || j["datasets"].empty())
    throw InputError(file, "datasets", "a list of at least one {name, source} is needed");
  const std::filesystem::path base = std::filesystem::path(file).parent_path();
  std::set<std::string> names;
  for (size_t i = 0; i < j["datasets"].size(); ++i) {
    const auto& d = j["datasets"][i];
    const std::string where = "datasets[" + std::to_string(i) + "]";
    if (!d.is_object()) throw InputError(file, where, "must be an object {name, source}");
    PipelineDataset ds;
    ds.name = string_at(d, "name", "", file, where);
    ds.source = string_at(d, "source", "", file, where);
    if (!safe_name(ds.name))
      throw InputError(file, where + ".name", "a name of letters, digits, '-', '_' or '.'");
    if (ds.source.empty()) throw InputError(file, where + ".source", "missing");
    if (!names.insert(ds.name).second)
      throw InputError(file, where + ".name", "'" + ds.name + "' appears twice");
    // A data set's outputs are <output>/<name>.lbc.h5 and the folder <output>/<name>/.
    for (const std::string& other : names)
      if (other == ds.name + ".lbc.h5" || ds.name == other + ".lbc.h5")
        throw InputError(file, where + ".name",
                         "'" + ds.name + "' and '" + other +
                             "': one data set's folder would be the other's cache file");
    if (ds.source.rfind("synth:", 0) != 0 && std::filesystem::path(ds.source).is_relative())
      ds.source = (base / ds.source).lexically_normal().string();
    p.datasets.push_back(ds);
  }
  p.bake_options = options_to_args(j.value("assets", nlohmann::json()), file, "assets");
  if (j.contains("transfer_functions")) {
    const auto& tfs = j["transfer_functions"];
    if (!tfs.is_array() || tfs.empty())
      throw InputError(file, "transfer_functions", "a list of presets or files");
    p.transfer_functions.clear();
    for (const auto& tf : tfs) {
      if (!tf.is_string()) throw InputError(file, "transfer_functions", "names must be strings");
      if (std::find(p.transfer_functions.begin(), p.transfer_functions.end(),
                    tf.get<std::string>()) != p.transfer_functions.end())
        throw InputError(
            file, "transfer_functions",
            "'" + tf.get<std::string>() + "' appears twice (every step would run twice)");
      // Two whose outputs would be the same files (render_stem) are refused.
      for (const std::string& other : p.transfer_functions)
        if (transfer_function_stem(other) == transfer_function_stem(tf.get<std::string>()))
          throw InputError(file, "transfer_functions",
                           "'" + other + "' and '" + tf.get<std::string>() +
                               "' would write the same files (a file's outputs take its name "
                               "without .json)");
      p.transfer_functions.push_back(tf.get<std::string>());
      const std::string& name = p.transfer_functions.back();
      if (!safe_name(name))
        throw InputError(file, "transfer_functions",
                         "'" + name +
                             "': a preset name (opaque, semi, "
                             "transparent) or a file name without directories");
      // A name no file can have (longer than the file system allows) is no file here: the
      // error_code overload, as the throwing one escapes as std::filesystem_error.
      std::error_code not_a_file;
      if (!is_transfer_function_preset(name) &&
          std::filesystem::is_regular_file(base / name, not_a_file))
        p.transfer_function_files[name] = (base / name).lexically_normal().string();
    }
  }
  const std::set<std::string> tf_names(p.transfer_functions.begin(), p.transfer_functions.end());
  if (!j.contains("techniques") || !j["techniques"].is_array() || j["techniques"].empty())
    throw InputError(file, "techniques", "a list of at least one technique is needed");
  std::set<std::string> labels;
  for (size_t i = 0; i < j["techniques"].size(); ++i) {
    const auto& t = j["techniques"][i];
    const std::string where = "techniques[" + std::to_string(i) + "]";
    PipelineTechnique pt;
    if (t.is_string()) {
      pt.technique = t.get<std::string>();
    } else if (t.is_object()) {
      pt.technique = string_at(t, "technique", "", file, where);
      pt.label = string_at(t, "label", "", file, where);
      pt.options = options_to_args(t.value("options", nlohmann::json()), file, where + ".options");
      pt.only_datasets = names_at(t, "datasets", names, file, where);
      pt.only_transfer_functions = names_at(t, "transfer_functions", tf_names, file, where);
      for (const auto& [key, value] : t.items())
        if (key != "technique" && key != "label" && key != "options" && key != "datasets" &&
            key != "transfer_functions")
          throw InputError(file, where + "." + key, "unknown technique key");
    } else {
      throw InputError(file, where,
                       "a technique name or {technique, label, options, datasets, "
                       "transfer_functions}");
    }
    if (pt.technique.empty()) throw InputError(file, where + ".technique", "missing");
    try {
      find_technique(pt.technique);
    } catch (const Error& e) {
      throw InputError(file, t.is_string() ? where : where + ".technique", e.what());
    }
    if (pt.label.empty()) pt.label = pt.technique;
    if (!safe_name(pt.label))
      throw InputError(file, where + ".label", "a name of letters, digits, '-', '_' or '.'");
    if (!labels.insert(pt.label).second)
      throw InputError(file, where, "label '" + pt.label + "' appears twice; give a \"label\"");
    p.techniques.push_back(pt);
  }
  p.flight = string_at(j, "flight", p.flight, file, "");
  // A keyframe file beside the pipeline file, as data sets and transfer functions are found.
  std::error_code not_a_file;
  if (parse_flight_kind(p.flight) == FlightKind::Keyframes &&
      std::filesystem::path(p.flight).is_relative() &&
      std::filesystem::is_regular_file(base / p.flight, not_a_file))
    p.flight = (base / p.flight).lexically_normal().string();
  if (j.contains("frames")) {
    if (!j["frames"].is_number_integer() || j["frames"].get<int64_t>() < 1 ||
        j["frames"].get<int64_t>() > 100000)
      throw InputError(file, "frames", "an integer 1..100000");
    p.frame_count = int(j["frames"].get<int64_t>());
  }
  if (j.contains("warm_up")) {
    if (!j["warm_up"].is_number_integer() || j["warm_up"].get<int64_t>() < 0 ||
        j["warm_up"].get<int64_t>() > 100)
      throw InputError(file, "warm_up", "an integer 0..100");
    p.warm_up = int(j["warm_up"].get<int64_t>());
  }
  p.size = string_at(j, "size", p.size, file, "");
  p.reference = string_at(j, "reference", p.reference, file, "");
  bool has_reference = false;
  for (const PipelineTechnique& t : p.techniques) has_reference |= t.label == p.reference;
  if (!has_reference)
    throw InputError(file, "reference", "'" + p.reference + "' is not one of the techniques");
  return p;
}

namespace {

// The most nodes a YAML pipeline may expand to: aliases repeat a node wherever they stand, so a
// dozen lines of nested aliases expand to billions (a pipeline of 100 data sets and techniques
// has a few thousand).
constexpr uint64_t kMaxYamlNodes = 100000;
constexpr int kMaxYamlDepth = 256;

// YAML pipelines are read into the same JSON tree. Plain scalars get YAML 1.2 core types
// (true/false, integers, floats, null); quoted scalars stay strings. Refuses more than
// kMaxYamlNodes nodes (`nodes` counts them) and a key given twice in one mapping.
nlohmann::json yaml_to_json(const YAML::Node& node, const std::string& file, uint64_t& nodes,
                            int depth = 0) {
  if (++nodes > kMaxYamlNodes)
    throw InputError(file, "",
                     "expands to more than " + std::to_string(kMaxYamlNodes) +
                         " YAML nodes (aliases repeat what they name): not a pipeline");
  // An alias inside the node it names (`datasets: &a [*a]`) never ends: it would overflow the
  // stack long before the node count.
  if (depth > kMaxYamlDepth)
    throw InputError(file, "",
                     "nests deeper than " + std::to_string(kMaxYamlDepth) +
                         " levels (an alias inside what it names?): not a pipeline");
  switch (node.Type()) {
    case YAML::NodeType::Null:
    case YAML::NodeType::Undefined:
      return nullptr;
    case YAML::NodeType::Sequence: {
      nlohmann::json array = nlohmann::json::array();
      for (const YAML::Node& item : node)
        array.push_back(yaml_to_json(item, file, nodes, depth + 1));
      return array;
    }
    case YAML::NodeType::Map: {
      nlohmann::json object = nlohmann::json::object();
      for (const auto& entry : node) {
        const std::string key = entry.first.as<std::string>();
        if (object.contains(key))
          throw InputError(
              file, "line " + std::to_string(entry.first.Mark().line + 1) + ", key '" + key + "'",
              "given twice in one mapping (YAML readers keep either); give it once");
        object[key] = yaml_to_json(entry.second, file, nodes, depth + 1);
      }
      return object;
    }
    case YAML::NodeType::Scalar:
      break;
  }
  const std::string text = node.Scalar();
  if (node.Tag() == "!") return text;  // quoted
  if (text == "true" || text == "True" || text == "TRUE") return true;
  if (text == "false" || text == "False" || text == "FALSE") return false;
  if (text == "null" || text == "~" || text.empty()) return nullptr;
  const std::string where = "line " + std::to_string(node.Mark().line + 1) + ", column " +
                            std::to_string(node.Mark().column + 1);
  // What YAML 1.1 (PyYAML) reads otherwise than YAML 1.2 is refused, not guessed: its booleans
  // (`early-termination: yes` meant true and reached the flag as a value) and its octal
  // integers with a leading zero (012: 10 there, 12 here).
  static const std::set<std::string> yaml11_booleans = {"yes", "Yes", "YES", "no",  "No",  "NO",
                                                        "on",  "On",  "ON",  "off", "Off", "OFF"};
  if (yaml11_booleans.count(text))
    throw InputError(file, where,
                     "plain '" + text +
                         "' is a boolean in YAML 1.1 and a string in YAML 1.2 (which pipelines "
                         "read): write true or false, or quote it for the string");
  const size_t sign = text[0] == '-' || text[0] == '+' ? 1 : 0;
  if (text.size() > sign + 1 && text[sign] == '0' &&
      text.find_first_not_of("0123456789", sign) == std::string::npos)
    throw InputError(file, where,
                     "plain '" + text +
                         "' has a leading zero: octal in YAML 1.1, decimal in YAML 1.2 (which "
                         "pipelines read); write it without the zero, or with 0o for octal");
  const char* begin = text.c_str();
  char* end = nullptr;
  // YAML 1.2's core integers: 0o octal and 0x hexadecimal (to 64 bits, unsigned), decimal.
  const auto prefixed = [&](const char* prefix, const char* digits) {
    return text.size() > 2 && text.compare(0, 2, prefix) == 0 &&
           text.find_first_not_of(digits, 2) == std::string::npos;
  };
  const int base = prefixed("0o", "01234567")                 ? 8
                   : prefixed("0x", "0123456789abcdefABCDEF") ? 16
                                                              : 10;
  if (base != 10) {
    errno = 0;
    const unsigned long long value = std::strtoull(begin + 2, &end, base);
    if (errno == ERANGE)
      throw InputError(file, where, "plain '" + text + "' needs more than 64 bits");
    if (value <= uint64_t(std::numeric_limits<int64_t>::max())) return int64_t(value);
    return uint64_t(value);
  }
  errno = 0;
  const long long integer = std::strtoll(begin, &end, 10);
  if (errno == 0 && end == begin + text.size()) return integer;
  if (errno == ERANGE && end == begin + text.size() && text[0] != '-') {
    errno = 0;  // past int64 and within uint64: an integer still, as 0x writes it
    const unsigned long long large = std::strtoull(begin, &end, 10);
    if (errno == 0) return uint64_t(large);
  }
  // and its infinities (strtod's own spelling, inf, is a string there)
  for (const char* spelling : {".inf", ".Inf", ".INF"}) {
    const std::string infinity = spelling;
    if (text == infinity || text == "+" + infinity) return std::numeric_limits<double>::infinity();
    if (text == "-" + infinity) return -std::numeric_limits<double>::infinity();
  }
  errno = 0;
  const double real = std::strtod(begin, &end);
  if (errno == 0 && end == begin + text.size() &&
      text.find_first_of("0123456789") != std::string::npos &&
      text.find_first_of("xX") == std::string::npos)  // C's hexadecimal floats are strings
    return real;
  return text;
}

// The line (from 1) where a second YAML document's content starts: content after a `---` line
// that follows content; 0 for none. Comments, blank lines and directives are not content, so a
// leading `---` and a trailing one (some emitters write it) start no second document.
uint64_t second_document_line(const std::string& text) {
  // A marker line: `---` or `...` and nothing after it but blanks or a comment. `---` may carry
  // its document's content on the same line; `...` may not.
  const auto marker_line = [](const std::string& line, const char* mark, bool& inline_content) {
    if (line.compare(0, 3, mark) != 0) return false;
    if (line.size() > 3 && line[3] != ' ' && line[3] != '\t' && line[3] != '\r') return false;
    const size_t rest = line.find_first_not_of(" \t\r", 3);
    inline_content = rest != std::string::npos && line[rest] != '#';
    return true;
  };
  bool content = false, ended = false;  // content seen; a marker after it
  uint64_t number = 0;
  size_t at = 0;
  while (at < text.size()) {
    const size_t end = std::min(text.find('\n', at), text.size());
    std::string line = text.substr(at, end - at);
    at = end + 1;
    ++number;
    if (line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);  // a byte-order mark
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#' || line[0] == '%') continue;
    bool inline_content = false;
    if (marker_line(line, "---", inline_content)) {
      if (content && inline_content) return number;
      ended = content;
      content = content || inline_content;
      continue;
    }
    if (marker_line(line, "...", inline_content)) {
      if (inline_content) return number;
      ended = content;
      continue;
    }
    if (ended) return number;
    content = true;
  }
  return 0;
}

bool is_yaml(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  return ext == ".yaml" || ext == ".yml";
}

}  // namespace

std::vector<std::string> pipeline_assets(const Pipeline& p) {
  std::vector<std::string> assets = BakeOptions{}.assets;
  for (size_t i = 0; i + 1 < p.bake_options.size(); ++i)
    if (p.bake_options[i] == "--assets") {
      assets.clear();
      std::stringstream list(p.bake_options[i + 1]);
      for (std::string a; std::getline(list, a, ',');) assets.push_back(a);
    }
  return assets;
}

std::string find_pipeline(const std::string& path, const std::string& shipped_dir) {
  const auto in = [](const std::filesystem::path& base) -> std::string {
    std::error_code absent;  // a name too long for the file system is not there either
    if (std::filesystem::is_regular_file(base, absent)) return base.string();
    for (const char* ext : {".json", ".yaml", ".yml"}) {
      std::string named = base.string() + ext;
      if (std::filesystem::is_regular_file(named, absent)) return named;
    }
    return "";
  };
  std::string found = in(path);
  const std::filesystem::path name(path);
  if (found.empty() && !shipped_dir.empty() &&
      (!name.has_parent_path() || name.parent_path() == "pipelines"))
    found = in(std::filesystem::path(shipped_dir) / name.filename());
  return found.empty() ? path : found;
}

Pipeline load_pipeline(const std::string& given) {
  const std::string path = find_pipeline(given);
  std::error_code not_a_directory;
  if (std::filesystem::is_directory(path, not_a_directory))
    throw InputError(path, "", "is a directory; give a pipeline file (.json, .yaml)");
  nlohmann::json j;
  if (is_yaml(path)) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, "", "cannot open the pipeline file");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // One document: YAML::Load reads the first and ignores the rest, however malformed.
    // (YAML::LoadAll is not used: yaml-cpp 0.7's ran out of memory on a fuzzed file, producing
    // documents without end.)
    if (const uint64_t line = second_document_line(text))
      throw InputError(path, "line " + std::to_string(line),
                       "a second YAML document (after ---): a pipeline file holds one");
    try {
      uint64_t nodes = 0;
      j = yaml_to_json(YAML::Load(text), path, nodes);
    } catch (const YAML::Exception& e) {
      throw InputError(path,
                       "line " + std::to_string(e.mark.line + 1) + ", column " +
                           std::to_string(e.mark.column + 1),
                       "not YAML: " + e.msg);
    }
  } else {
    j = read_json_file(path, "pipeline file");
  }
  // What the checks let through to nlohmann::json (a key or text that is not UTF-8, for one) is
  // still the file's fault.
  try {
    return parse_pipeline(j, path);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path, "", std::string("unexpected JSON value: ") + e.what());
  }
}

std::string transfer_function_argument(const Pipeline& p, const std::string& tf) {
  const auto file = p.transfer_function_files.find(tf);
  return file == p.transfer_function_files.end() ? tf : file->second;
}

std::string cache_path(const Pipeline& p, const std::string& dataset) {
  return p.output + "/" + dataset + ".lbc.h5";
}

std::string render_stem(const Pipeline& p, const std::string& dataset, const std::string& label,
                        const std::string& tf) {
  return p.output + "/" + dataset + "/" + label + "-" + transfer_function_stem(tf);
}

std::string frame_file(const std::string& stem, int frame, const char* suffix) {
  char number[16];
  std::snprintf(number, sizeof number, "_%03d", frame);
  return stem + number + suffix;
}

std::string frame_output(const Pipeline& p, const std::string& stem, int frame,
                         const char* suffix) {
  return p.frame_count > 1 ? frame_file(stem, frame, suffix) : stem + suffix;
}

std::vector<PipelineStep> plan_pipeline(const Pipeline& p, const PlanContext& context) {
  std::vector<PipelineStep> steps;
  const bool several = p.frame_count > 1;
  const auto frame_png = [&](const std::string& stem, int f) {
    return frame_output(p, stem, f, ".png");
  };
  for (const PipelineDataset& d : p.datasets) {
    PipelineStep bake;
    bake.id = "bake/" + d.name;
    bake.kind = "bake";
    bake.args = {"bake", d.source, "-o", cache_path(p, d.name)};
    bake.args.insert(bake.args.end(), p.bake_options.begin(), p.bake_options.end());
    bake.outputs = {cache_path(p, d.name)};
    const bool synth = d.source.rfind("synth:", 0) == 0;
    const std::string input_hash =
        synth || !context.file_hash ? std::string("synth") : context.file_hash(d.source);
    std::vector<std::string> parts = bake.args;
    parts.push_back(input_hash);
    bake.key = key_of(parts);
    steps.push_back(bake);
    const std::string bake_key = bake.key;
    for (const std::string& tf : p.transfer_functions) {
      std::string reference_key, reference_skip;
      for (const PipelineTechnique& t : p.techniques) {
        const TechniqueInfo& info = find_technique(t.technique).info;
        PipelineStep render;
        render.id = "render/" + d.name + "/" + t.label + "/" + tf;
        render.kind = "render";
        render.depends = {bake.id};
        const std::string stem = render_stem(p, d.name, t.label, tf);
        render.args = {"render",
                       cache_path(p, d.name),
                       "--technique",
                       t.technique,
                       "--tf",
                       transfer_function_argument(p, tf),
                       "--flight",
                       p.flight,
                       "--frame-count",
                       std::to_string(p.frame_count),
                       "--size",
                       p.size,
                       "-o",
                       stem + ".png",
                       "--stats",
                       stem + ".json",
                       "--depth-complexity",
                       stem + "-dc.png"};
        if (several) render.args.insert(render.args.end(), {"--frames", "all"});
        if (p.warm_up > 0)
          render.args.insert(render.args.end(), {"--warm-up", std::to_string(p.warm_up)});
        render.args.insert(render.args.end(), t.options.begin(), t.options.end());
        render.outputs = {stem + ".json"};
        for (int f = 0; f < p.frame_count; ++f) {
          render.outputs.push_back(frame_png(stem, f));
          render.optional_outputs.push_back(frame_output(p, stem + "-dc", f, ".png"));
        }
        std::vector<std::string> rparts = render.args;
        rparts.push_back(bake_key);
        // An edited transfer-function or key-frame file renders again, as an edited input file
        // bakes again.
        if (p.transfer_function_files.count(tf) && context.file_hash)
          rparts.push_back(context.file_hash(transfer_function_argument(p, tf)));
        if (parse_flight_kind(p.flight) == FlightKind::Keyframes && context.file_hash)
          rparts.push_back(context.file_hash(p.flight));
        render.key = key_of(rparts);
        if (!listed(t.only_datasets, d.name))
          render.skip_reason = "left out of this pipeline on " + d.name + " (it runs on " +
                               name_list(t.only_datasets) + ")";
        else if (!listed(t.only_transfer_functions, tf))
          render.skip_reason = "left out of this pipeline for " + tf + " (it runs with " +
                               name_list(t.only_transfer_functions) + ")";
        else if (info.ray_tracing && !context.ray_tracing)
          render.skip_reason = "no Vulkan device with ray tracing";
        else if (!context.vulkan && (info.vulkan || (t.technique == "vrc" &&
                                                     std::find(t.options.begin(), t.options.end(),
                                                               "gpu") != t.options.end())))
          render.skip_reason = "no Vulkan device";
        steps.push_back(render);
        if (t.label == p.reference) {
          reference_key = render.key;
          reference_skip = render.skip_reason;
        }
      }
      // Every technique but the reference, frame by frame, against the reference.
      const std::string ref_stem = render_stem(p, d.name, p.reference, tf);
      for (const PipelineTechnique& t : p.techniques) {
        if (t.label == p.reference) continue;
        const std::string stem = render_stem(p, d.name, t.label, tf);
        const std::string render_id = "render/" + d.name + "/" + t.label + "/" + tf;
        // Copies: `steps` grows below.
        std::string render_key, render_skip;
        for (const PipelineStep& s : steps)
          if (s.id == render_id) {
            render_key = s.key;
            render_skip = s.skip_reason;
          }
        for (int f = 0; f < p.frame_count; ++f) {
          PipelineStep c;
          c.id = "compare/" + d.name + "/" + t.label + "/" + tf + "/" + std::to_string(f);
          c.kind = "compare";
          c.depends = {render_id, "render/" + d.name + "/" + p.reference + "/" + tf};
          const std::string err = frame_output(p, stem + "-error", f, ".png");
          const std::string json = frame_output(p, stem + "-compare", f, ".json");
          c.args = {"compare",       frame_png(stem, f),   frame_png(ref_stem, f),
                    "--json",        "--error-image",      err,
                    "--error-scale", error_gain_argument()};
          c.stdout_file = json;
          c.outputs = {json, err};
          std::vector<std::string> cparts = c.args;
          cparts.insert(cparts.end(), {render_key, reference_key});
          c.key = key_of(cparts);
          c.skip_reason = !render_skip.empty()     ? render_skip
                          : reference_skip.empty() ? std::string()
                                                   : "its reference, " + p.reference +
                                                         ", does not run here: " + reference_skip;
          steps.push_back(c);
        }
      }
    }
  }
  return steps;
}

}  // namespace linebake
