#include "cache/rtx_store.hpp"

#include <algorithm>
#include <cstdio>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/json_file.hpp"

namespace linebake {

static std::string blas_dataset(size_t i) {
  char name[32];
  std::snprintf(name, sizeof name, "/blas_%06zu", i);
  return std::string(kRtxGroup) + name;
}

void store_rtx(CacheWriter& cache, const StoredRtx& rtx, Provenance provenance) {
  cache.create_group(kRtxGroup);
  uint64_t disk = 0;
  for (size_t i = 0; i < rtx.blobs.size(); ++i)
    disk += cache.write(blas_dataset(i), rtx.blobs[i].data(), rtx.blobs[i].size());
  const nlohmann::json description = {{"geometry", rtx.geometry}, {"compaction", rtx.compaction},
                                      {"source", rtx.source},     {"device", rtx.device},
                                      {"driver", rtx.driver},     {"driver_uuid", rtx.driver_uuid},
                                      {"blas", rtx.blobs.size()}};
  cache.write_attribute(kRtxGroup, "acceleration_structures", json_text(description));
  provenance.disk_bytes = disk;
  cache.write_provenance(kRtxGroup, provenance);
}

StoredRtx load_rtx(const CacheReader& cache) {
  StoredRtx r = load_rtx_description(cache);
  load_rtx_blobs(cache, r);
  return r;
}

StoredRtx load_rtx_description(const CacheReader& cache) {
  const std::string where = std::string("group ") + kRtxGroup;
  const auto text = cache.attribute(kRtxGroup, "acceleration_structures");
  if (!text)
    throw InputError(cache.path(), where,
                     "missing: no serialised acceleration structures in this cache; add them with: "
                     "linebake bake " +
                         cache.path() + " --assets rtx");
  StoredRtx r;
  size_t count = 0;
  try {
    const auto j = nlohmann::json::parse(*text);
    r.geometry = j.at("geometry").get<std::string>();
    r.compaction = j.at("compaction").get<bool>();
    r.source = j.at("source").get<std::string>();
    r.device = j.at("device").get<std::string>();
    r.driver = j.at("driver").get<std::string>();
    r.driver_uuid = j.at("driver_uuid").get<std::string>();
    count = j.at("blas").get<size_t>();
  } catch (const std::exception& e) {
    throw InputError(cache.path(), where,
                     std::string("bad acceleration structure description: ") + e.what());
  }
  if (r.geometry != "triangles" && r.geometry != "capsules")
    throw InputError(cache.path(), where, "unknown geometry '" + r.geometry + "'");
  r.blas = count;
  for (size_t i = 0; i < count; ++i) {
    const std::vector<uint64_t> shape = cache.shape(blas_dataset(i));
    if (shape.size() != 1)
      throw InputError(
          cache.path(), "dataset " + blas_dataset(i),
          "a serialised BLAS is one dimension of bytes, not " + std::to_string(shape.size()));
    r.blob_bytes += shape[0];
    r.largest_blob_bytes = std::max(r.largest_blob_bytes, shape[0]);
  }
  return r;
}

void load_rtx_blobs(const CacheReader& cache, StoredRtx& rtx) {
  rtx.blobs.clear();
  rtx.blobs.reserve(rtx.blas);
  for (size_t i = 0; i < rtx.blas; ++i) {
    const Array<uint8_t> blob = cache.read<uint8_t>(blas_dataset(i));
    rtx.blobs.emplace_back(blob.data(), blob.data() + blob.size());
  }
}

std::string rtx_capsules_source(const std::string& lines_hash, float radius,
                                const std::string& attribute) {
  const std::string radius_text = std::to_string(radius);  // outlives the views below
  Hasher h;
  for (std::string_view part : {std::string_view("capsules"), std::string_view(lines_hash),
                                std::string_view(radius_text), std::string_view(attribute)})
    h.update(part);
  return h.hex();
}

}  // namespace linebake
