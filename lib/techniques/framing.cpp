#include "techniques/framing.hpp"

#include <algorithm>

#include "cache/line_store.hpp"
#include "tubes/tube_builder.hpp"

namespace linebake {

namespace {

// The lines' bounds, and the radius flight_bounds grows them by.
Bounds line_bounds(const CacheReader& cache, float& radius) {
  const auto lines = cache.provenance("/lines");
  Bounds bounds;
  if (lines && lines->stats.contains("bounds"))
    bounds = line_stats_from_json(lines->stats, cache.path()).bounds;
  else  // caches baked before the provenance kept them
    include_dataset_points(bounds, cache, "/lines/points");
  if (bounds.empty) return bounds;
  // The tubes' radius, else Embree's curves' (built with the same options), else a bake's
  // default. In float, as the capsules' radius is (radius_world is a float's value).
  radius = TubeOptions{}.radius * bounds.diagonal();
  for (const char* asset : {"/assets/embree", "/assets/tubes"})
    if (cache.exists(asset))
      if (const auto p = cache.provenance(asset); p && p->stats.contains("radius_world"))
        radius = p->stats["radius_world"].get<float>();
  return bounds;
}

Bounds grown(Bounds bounds, float radius) {
  if (!bounds.empty)
    for (size_t k = 0; k < 3; ++k) bounds.min[k] -= radius, bounds.max[k] += radius;
  return bounds;
}

}  // namespace

Bounds flight_bounds(const CacheReader& cache) {
  float radius = 0;
  const Bounds bounds = line_bounds(cache, radius);
  return grown(bounds, radius);
}

Bounds drawn_bounds(const CacheReader& cache, float radius) {
  float framed = 0;
  const Bounds bounds = line_bounds(cache, framed);
  return grown(bounds, std::max(radius, framed));
}

}  // namespace linebake
