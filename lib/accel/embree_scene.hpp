#pragma once
// Embree 3 scenes over a line set: the paper's OSP column. The builders prepare Embree's input
// buffers (kept by the cache; Embree BVHs cannot be serialised), commit the scene, and measure
// both steps: preparation and commit time, and the BVH memory Embree reports through its memory
// monitor. The scene views the data it was built from: keep the LineSet / TubeMesh alive.

#include <embree3/rtcore.h>

#include <glm/glm.hpp>
#include <memory>
#include <string>
#include <vector>

#include "core/array.hpp"
#include "lines/line_set.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake {

enum class EmbreeGeometry {
  LinearCurve,  // RTC_GEOMETRY_TYPE_ROUND_LINEAR_CURVE with neighbour flags (joints merged)
  BezierCurve,  // RTC_GEOMETRY_TYPE_ROUND_BEZIER_CURVE, Catmull-Rom through the points
  Triangles,    // the cached tube mesh, its buffers shared with Embree
  Capsules      // user geometry: capsule chains intersected analytically (accel/capsule_chain)
};
// linear | bezier | triangles | capsules
EmbreeGeometry parse_embree_geometry(const std::string& name);
const char* to_string(EmbreeGeometry geometry);

enum class BuildQuality { Low, Medium, High };
BuildQuality parse_build_quality(const std::string& name);
const char* to_string(BuildQuality quality);

struct EmbreeOptions {
  EmbreeGeometry geometry = EmbreeGeometry::LinearCurve;
  BuildQuality quality = BuildQuality::Medium;
  bool compact = false;  // RTC_SCENE_FLAG_COMPACT: less memory, slower traversal
  bool robust = false;   // RTC_SCENE_FLAG_ROBUST: watertight, slower traversal
  // Primitives per Embree scene. Past it the geometry is split at line (chunk) boundaries into
  // sub-scenes, instanced into one top-level scene: Embree's primitive ids are 32-bit.
  uint64_t max_primitives_per_scene = 0xFFFFFFFFull;
  // The most memory the scene may take (0: no limit): the input buffers it prepares and what
  // Embree allocates for the BVH. Embree's memory monitor cancels the build at the allocation
  // that would pass it, and the builder throws BudgetExceeded with the figures: a BVH that does
  // not fit the memory budget is refused, not left to the kernel.
  uint64_t max_memory_bytes = 0;
};

struct BvhStats {
  EmbreeGeometry geometry = EmbreeGeometry::LinearCurve;
  uint64_t primitives = 0;      // curve segments or triangles
  uint64_t parts = 0;           // Embree geometries
  bool instanced = false;       // parts live in instanced sub-scenes
  double prepare_s = 0;         // building Embree's input buffers from the data
  double commit_s = 0;          // rtcCommitScene (the BVH build) over all scenes
  uint64_t buffer_bytes = 0;    // prepared input buffers owned by linebake (0 when shared)
  uint64_t bvh_bytes = 0;       // Embree's memory after the build (memory monitor)
  uint64_t bvh_peak_bytes = 0;  // Embree's high-water mark during the build
};

// What a ray hit, for shading: the unit outward surface normal (interpolated vertex normals on
// triangles, the exact normal on curves) and the data attribute there (0 without one).
struct SurfacePoint {
  glm::dvec3 normal{0, 0, 1};
  double attribute = 0;
};

// Embree's input buffers for one curve geometry, as prepared: what the cache keeps, ready for
// rtcSetSharedGeometryBuffer (vertices are FLOAT4 x, y, z, r with one zero padding vertex).
struct PreparedCurves {
  Array<float> vertices;
  Array<uint32_t> indices;  // first vertex of each segment (Bezier: 4 x segment)
  Array<uint8_t> flags;     // RTC_CURVE_FLAG_NEIGHBOR_LEFT / _RIGHT (linear curves, capsules)
};

// Curves are cut into parts of consecutive lines, each at most `limit` segments (Embree's
// primitive ids are 32-bit); lines without segments join the open part, parts without segments
// are left out. The plan needs only the lines' point counts, so it can be made batch by batch.
struct CurvePart {
  uint64_t first_line = 0, end_line = 0;  // lines [first_line, end_line)
  uint64_t first_point = 0, points = 0;   // the lines' points
  uint64_t segments = 0;
};
// The segment limit per part for these options (max_primitives_per_scene, at most 2^30 - 1).
uint64_t curve_part_limit(const EmbreeOptions& options);
class CurvePartPlanner {
 public:
  explicit CurvePartPlanner(uint64_t limit) : limit_(limit) {}
  void add(uint64_t line_points);  // the next line; throws Error when it alone exceeds the limit
  std::vector<CurvePart> finish();

 private:
  uint64_t limit_, line_ = 0, point_ = 0;
  CurvePart open_;
  std::vector<CurvePart> parts_;
};
// Vertices of a part as prepared (without the padding vertex): a point each for linear curves
// and capsules, four per segment for Bezier curves.
uint64_t curve_vertices(const CurvePart& part, EmbreeGeometry geometry);

// Where prepare_curves writes: the first vertex (FLOAT4), index and flag of its lines.
struct CurveOutput {
  float* vertices = nullptr;
  uint32_t* indices = nullptr;
  uint8_t* flags = nullptr;  // linear curves and capsules only
};
// Embree's input buffers for lines [first, end) of `lines`, which start at point `point_base`
// and segment `segment_base` of their part (the values the indices take).
void prepare_curves(const LineSet& lines, size_t first, size_t end, uint64_t point_base,
                    uint64_t segment_base, float radius, EmbreeGeometry geometry,
                    const CurveOutput& out);

// Where Embree sees a scene's geometry: world = scene / scale + centre. The identity but for
// curves (linear, Bezier) whose segments are short (a mean under kShortCurveSegment): Embree 3's
// round curve intersectors compare lengths squared with absolute float epsilons (its ulp,
// 1.2e-7, against (p - p0).(p1 - p0) at the clipping planes), so segments of 2.6e-4 took hits
// through their caps (22.5 dB against the tube mesh where capsules kept 26.4). Such curves go
// to Embree about the scene's centre, scaled so that a mean segment is one unit long, and rays
// are traced in that frame (trace_frame and trace_hits convert).
struct SceneFrame {
  glm::dvec3 centre{0};
  double scale = 1;
  glm::dvec3 to_scene(const glm::dvec3& world) const { return (world - centre) * scale; }
};
constexpr double kShortCurveSegment = 1.0 / 128;

class EmbreeScene {
 public:
  // Curves over the line set with one world-space radius; `attribute` names the vertex
  // attribute hits report ("" for none).
  static EmbreeScene from_lines(const LineSet& lines, float radius, const std::string& attribute,
                                const EmbreeOptions& options);
  // Curves from buffers prepared earlier for these lines (the cache's /assets/embree: the same
  // geometry and line order), skipping preparation; options.geometry must match the buffers.
  // Throws when the buffers do not cover the lines' segments.
  static EmbreeScene from_prepared(const LineSet& lines, std::vector<PreparedCurves> buffers,
                                   const std::string& attribute, const EmbreeOptions& options);
  // Triangles over the tube mesh (options.geometry is ignored).
  static EmbreeScene from_tubes(const TubeMesh& mesh, const EmbreeOptions& options);

  EmbreeScene(EmbreeScene&&) noexcept;
  EmbreeScene& operator=(EmbreeScene&&) noexcept;
  ~EmbreeScene();

  RTCScene handle() const;
  const BvhStats& stats() const;
  // The attribute range the data reports in (the tube mesh's, or the line set's).
  std::array<double, 2> attribute_range() const;
  SurfacePoint surface(const RTCHit& hit) const;
  // Whether two primitives of one geometry meet (consecutive segments of a line; triangles
  // sharing a vertex). A ray through the seam reports both at the same distance, where
  // rasterisation makes one fragment: the tracer counts such a pair once.
  bool adjacent(unsigned geometry, unsigned a, unsigned b) const;
  // The prepared curve buffers per geometry (empty for triangles: those are the tube mesh's).
  std::vector<PreparedCurves> prepared_curves() const;
  // Scene bounds (for cameras), in world units.
  Bounds bounds() const;
  // The frame rays are traced in (identity but for short curves).
  const SceneFrame& frame() const;

  struct State;  // Embree handles and prepared buffers

 private:
  explicit EmbreeScene(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace linebake
