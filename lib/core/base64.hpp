#pragma once
// RFC 4648 base64 (standard alphabet, '=' padding), for data: URIs in self-contained reports.

#include <string>
#include <string_view>

namespace linebake {

std::string base64_encode(std::string_view bytes);

}  // namespace linebake
