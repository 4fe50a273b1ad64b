#include "core/json_file.hpp"

#include <fstream>

namespace linebake {

nlohmann::json read_json_file(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "", "cannot open the " + what);
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(path, "byte offset " + std::to_string(e.byte), "not valid JSON");
  } catch (const nlohmann::json::exception& e) {
    // A number past double's range (out_of_range 406) carries no offset.
    throw InputError(path, "", std::string("not valid JSON: ") + e.what());
  }
}

}  // namespace linebake
