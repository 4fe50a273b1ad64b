#include "cache/line_store.hpp"

#include "core/error.hpp"
#include "core/hash.hpp"

namespace linebake {

std::string content_hash(const LineSet& lines) {
  Hasher h;
  h.update(uint64_t{lines.positions.size()});
  h.update(lines.positions.data(), lines.positions.size() * sizeof(float));
  h.update(uint64_t{lines.line_offsets.size()});
  h.update(lines.line_offsets.data(), lines.line_offsets.size() * sizeof(uint64_t));
  for (const auto* group : {&lines.attributes, &lines.line_attributes}) {
    h.update(uint64_t{group->size()});
    for (const Attribute& a : *group) {
      h.update(a.name);
      h.update(uint64_t{a.values.size()});
      h.update(a.values.data(), a.values.size() * sizeof(float));
    }
  }
  return h.hex();
}

uint64_t line_set_bytes(const LineSet& lines) {
  return compute_stats(lines).total_bytes();
}

void store_lines(CacheWriter& cache, const LineSet& lines, Provenance provenance) {
  cache.create_group("/lines");
  uint64_t disk = cache.write("/lines/points", lines.positions.data(), lines.point_count(), 3);
  disk += cache.write("/lines/line_offsets", lines.line_offsets.data(), lines.line_offsets.size());
  for (const Attribute& a : lines.attributes)
    disk += cache.write("/lines/attributes/" + encode_link_name(a.name), a.values.data(),
                        a.values.size());
  for (const Attribute& a : lines.line_attributes)
    disk += cache.write("/lines/line_attributes/" + encode_link_name(a.name), a.values.data(),
                        a.values.size());
  nlohmann::json metadata = lines.metadata;
  cache.write_attribute("/lines", "metadata", metadata.dump());
  provenance.disk_bytes = disk;
  provenance.memory_bytes = line_set_bytes(lines);
  cache.write_provenance("/lines", provenance);
}

template <class T>
static std::vector<T> to_vector(const Array<T>& a) {
  return std::vector<T>(a.begin(), a.end());
}

LineSet load_lines(const CacheReader& cache) {
  if (!cache.exists("/lines")) throw InputError(cache.path(), "group /lines", "missing");
  LineSet lines;
  lines.line_offsets = to_vector(cache.read<uint64_t>("/lines/line_offsets"));
  if (lines.line_offsets.empty() || lines.line_offsets.front() != 0)
    throw InputError(cache.path(), "dataset /lines/line_offsets", "must start with 0");
  for (size_t i = 1; i < lines.line_offsets.size(); ++i)
    if (lines.line_offsets[i] < lines.line_offsets[i - 1])
      throw InputError(cache.path(), "dataset /lines/line_offsets",
                       "decreasing at index " + std::to_string(i));
  const uint64_t points = lines.line_offsets.back();
  lines.positions = to_vector(cache.read<float>("/lines/points", 3 * points));
  for (const std::string& name : cache.members("/lines/attributes"))
    lines.attributes.push_back({decode_link_name(name),
                                to_vector(cache.read<float>("/lines/attributes/" + name, points))});
  for (const std::string& name : cache.members("/lines/line_attributes"))
    lines.line_attributes.push_back(
        {decode_link_name(name),
         to_vector(cache.read<float>("/lines/line_attributes/" + name, lines.line_count()))});
  if (const auto text = cache.attribute("/lines", "metadata")) {
    try {
      lines.metadata = nlohmann::json::parse(*text).get<std::map<std::string, std::string>>();
    } catch (const std::exception& e) {
      throw InputError(cache.path(), "group /lines", std::string("bad metadata: ") + e.what());
    }
  }
  return lines;
}

}  // namespace linebake
