#include "techniques/framing.hpp"

#include <algorithm>
#include <span>
#include <vector>

#include "cache/line_store.hpp"
#include "core/error.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake {
namespace {

// The points' bounds, a million rows at a time (caches baked before the provenance kept them).
Bounds read_line_bounds(const CacheReader& cache) {
  const std::string d = "/lines/points";
  const std::vector<uint64_t> shape = cache.shape(d);
  if (shape.size() != 2 || shape[1] != 3)
    throw InputError(cache.path(), "dataset " + d, "not 3 floats per point");
  constexpr uint64_t kRows = uint64_t{1} << 20;
  Bounds bounds;
  std::vector<float> piece;
  for (uint64_t first = 0; first < shape[0]; first += kRows) {
    const uint64_t rows = std::min(kRows, shape[0] - first);
    piece.resize(3 * rows);
    cache.read_rows(d, first, rows, piece.data());
    include_points(bounds, std::span<const float>(piece.data(), piece.size()));
  }
  return bounds;
}

}  // namespace

Bounds flight_bounds(const CacheReader& cache) {
  const auto lines = cache.provenance("/lines");
  Bounds bounds = lines && lines->stats.contains("bounds")
                      ? line_stats_from_json(lines->stats, cache.path()).bounds
                      : read_line_bounds(cache);
  if (bounds.empty) return bounds;
  // The tubes' radius, else Embree's curves' (built with the same options), else a bake's
  // default. In float, as the capsules' radius is (radius_world is a float's value).
  float radius = TubeOptions{}.radius * bounds.diagonal();
  for (const char* asset : {"/assets/embree", "/assets/tubes"})
    if (cache.exists(asset))
      if (const auto p = cache.provenance(asset); p && p->stats.contains("radius_world"))
        radius = p->stats["radius_world"].get<float>();
  for (size_t k = 0; k < 3; ++k) bounds.min[k] -= radius, bounds.max[k] += radius;
  return bounds;
}

}  // namespace linebake
