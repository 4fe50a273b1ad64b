#include "core/json_file.hpp"

#include <filesystem>
#include <fstream>
#include <set>
#include <vector>

namespace linebake {

namespace {

// nlohmann's `byte` counts the characters read up to the one that failed, the end of the input
// counted as one: the failing character's offset from 0 is one less.
std::string parse_error_place(const std::string& path, const nlohmann::json::parse_error& e) {
  const uint64_t offset = e.byte > 0 ? e.byte - 1 : 0;
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (!ec && offset >= size)
    return "the end of the file (byte offset " + std::to_string(size) + ")";
  return at_byte(offset);
}

// What nlohmann's message says after its place: "[json.exception.parse_error.101] parse error at
// line 1, column 7: syntax error while parsing value - unexpected end of input; ...".
std::string parse_error_reason(const nlohmann::json::parse_error& e) {
  const std::string what = e.what();
  const size_t column = what.find("column ");
  const size_t colon = what.find(": ", column == std::string::npos ? 0 : column);
  return colon == std::string::npos ? what : what.substr(colon + 2);
}

}  // namespace

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
    throw InputError(path, parse_error_place(path, e), "not valid JSON: " + parse_error_reason(e));
  } catch (const nlohmann::json::exception& e) {
    // A number past double's range (out_of_range 406) carries no offset.
    throw InputError(path, "", std::string("not valid JSON: ") + e.what());
  }
}

std::string json_text(const nlohmann::json& value, int indent) {
  return value.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace linebake
