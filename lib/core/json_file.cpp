#include "core/json_file.hpp"

#include <fstream>
#include <set>
#include <vector>

namespace linebake {

nlohmann::json read_json_file(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open the " + what);
  // A key given twice in one object: nlohmann::json keeps the last silently, which hides a
  // mistake (two "frames" in a pipeline). The keys of each open object, innermost last.
  std::vector<std::set<std::string>> open_objects;
  std::string twice;
  const auto each = [&](int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using Event = nlohmann::json::parse_event_t;
    if (event == Event::object_start) {
      open_objects.emplace_back();
    } else if (event == Event::object_end) {
      open_objects.pop_back();
    } else if (event == Event::key && twice.empty() && !open_objects.empty() &&
               !open_objects.back().insert(parsed.get<std::string>()).second) {
      twice = parsed.get<std::string>();
    }
    return true;
  };
  try {
    nlohmann::json j = nlohmann::json::parse(in, each);
    if (!twice.empty())
      throw InputError(path, "key '" + twice + "'",
                       "given twice in one object (JSON readers keep either); give it once");
    return j;
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(path, "byte offset " + std::to_string(e.byte), "not valid JSON");
  } catch (const nlohmann::json::exception& e) {
    // A number past double's range (out_of_range 406) carries no offset.
    throw InputError(path, "", std::string("not valid JSON: ") + e.what());
  }
}

std::string json_text(const nlohmann::json& value, int indent) {
  return value.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace linebake
