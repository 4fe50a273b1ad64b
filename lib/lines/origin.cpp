#include "lines/origin.hpp"

#include <charconv>
#include <cmath>

#include "core/error.hpp"

namespace linebake {

std::string origin_text(const Origin& origin) {
  std::string text;
  for (int k = 0; k < 3; ++k) {
    // Plain digits where they are short (500000, not 5e+05), else the shortest form.
    const double v = origin[k];
    const bool plain = v == 0 || (std::fabs(v) < 1e15 && std::fabs(v) >= 1e-4);
    char digits[64];
    const auto r = std::to_chars(digits, digits + sizeof digits, v,
                                 plain ? std::chars_format::fixed : std::chars_format::general);
    text += (k ? " " : "") + std::string(digits, r.ptr);
  }
  return text;
}

std::optional<Origin> parse_origin(std::string_view text) {
  Origin origin{};
  size_t at = 0;
  const auto skip_blanks = [&] {
    while (at < text.size() && text[at] == ' ') ++at;
  };
  skip_blanks();
  for (int k = 0; k < 3; ++k) {
    if (k > 0) {  // blanks, or one comma with blanks around it
      const size_t before = at;
      skip_blanks();
      if (at < text.size() && text[at] == ',') ++at;
      skip_blanks();
      if (at == before) return std::nullopt;
    }
    // One sign at most: from_chars takes a '-' but not a '+'.
    if (at + 1 < text.size() && text[at] == '+' && text[at + 1] != '-') ++at;
    const auto r = std::from_chars(text.data() + at, text.data() + text.size(), origin[k]);
    if (r.ec != std::errc() || !std::isfinite(origin[k])) return std::nullopt;
    origin[k] += 0.0;  // -0 is 0: one text, one /lines key
    at = size_t(r.ptr - text.data());
  }
  skip_blanks();
  if (at != text.size()) return std::nullopt;
  return origin;
}

Origin origin_of(const LineSet& lines, const std::string& where) {
  return origin_of(lines.metadata, where);
}

Origin origin_of(const std::map<std::string, std::string>& metadata, const std::string& where) {
  const auto it = metadata.find(kOriginKey);
  if (it == metadata.end()) return {0, 0, 0};
  const std::optional<Origin> origin = parse_origin(it->second);
  if (!origin)
    throw InputError(where, "metadata \"origin\"",
                     "'" + it->second + "' is not three finite numbers (x y z)");
  return *origin;
}

bool has_origin(const LineSet& lines) {
  return lines.metadata.contains(kOriginKey);
}

std::optional<Origin> optional_origin(const LineSet& lines, const std::string& where) {
  if (!has_origin(lines)) return std::nullopt;
  return origin_of(lines, where);
}

std::map<std::string, std::string> metadata_without_origin(const LineSet& lines) {
  std::map<std::string, std::string> metadata = lines.metadata;
  metadata.erase(kOriginKey);
  return metadata;
}

void set_origin(LineSet& lines, const Origin& origin) {
  lines.metadata[kOriginKey] = origin_text(origin);
}

void keep_as_source_origin(std::map<std::string, std::string>& metadata) {
  const auto it = metadata.find(kOriginKey);
  if (it == metadata.end()) return;
  metadata.try_emplace(kSourceOriginKey, std::move(it->second));
  metadata.erase(it);
}

void shift_positions(std::span<float> xyz, const Origin& by) {
  if (by == Origin{0, 0, 0}) return;
  for (size_t i = 0; i < xyz.size(); ++i) xyz[i] = to_local(xyz[i], by[i % 3]);
}

Origin rounded_origin(const Origin& point) {
  // + 0.0 turns the -0 that rounding a small negative number gives into 0.
  return {std::round(point[0]) + 0.0, std::round(point[1]) + 0.0, std::round(point[2]) + 0.0};
}

}  // namespace linebake
