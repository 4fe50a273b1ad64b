#pragma once
// The box a flight frames over one cache: the same for every technique, so that each frame of
// a comparison (`run`, `bench render`, `view`) is seen from the same camera as the reference's.
// Before, each technique framed its own geometry (the tube mesh, or the lines grown by the
// curves' radius), and the cameras of `embree` and `tiles` sat 0.2 % farther out than the
// reference's: up to 1.5 dB of their PSNR was the camera, not the technique.

#include "cache/cache.hpp"
#include "lines/line_set.hpp"

namespace linebake {

// The lines' bounds (kept in the /lines provenance; read from /lines/points for caches without
// them) grown by the tubes' radius (their provenance's radius_world; without tubes, the Embree
// curves', else the radius a bake would give them: 0.001 x the diagonal). That is the capsules'
// exact box, and the tube mesh, whose rings lie within the radius, lies inside it.
Bounds flight_bounds(const CacheReader& cache);
// The lines' bounds grown by `radius` where it passes the radius flight_bounds grows them by:
// what a technique draws with render --radius (the camera stays framed on flight_bounds).
Bounds drawn_bounds(const CacheReader& cache, float radius);

}  // namespace linebake
