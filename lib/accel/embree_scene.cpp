#include "accel/embree_scene.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <limits>

#include "accel/capsule_chain.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"

namespace linebake {
namespace {

// Embree reads the last element of vertex and index buffers with 16-byte loads. A buffer can
// be shared as is when it sits in page-granular memory (linebake's large allocations and cache
// mappings) and its end leaves room in the page; otherwise it is copied with padding.
bool shareable(const void* data, size_t bytes) {
  constexpr size_t kPage = 4096;
  const auto end = reinterpret_cast<uintptr_t>(data) + bytes;
  return bytes >= (size_t{2} << 20) && (end % kPage) != 0 && kPage - end % kPage >= 16;
}

template <class T>
Array<T> padded_copy(const Array<T>& source) {
  const size_t pad = (16 + sizeof(T) - 1) / sizeof(T);
  Array<T> copy(source.size() + pad);
  std::copy(source.begin(), source.end(), copy.begin());
  std::fill(copy.begin() + source.size(), copy.end(), T{});
  return copy;
}

struct Part {
  uint64_t primitives = 0;
  // Curves: the part covers lines [first_line, end_line), points from first_point.
  uint64_t first_point = 0;
  Array<float> vertices;          // FLOAT4 (x, y, z, r), padded
  Array<float> scene_vertices;    // the same in the scene's frame, where it is not the identity
  Array<uint32_t> indices;        // first vertex of each segment
  Array<uint8_t> flags;           // neighbour flags (linear curves)
  Array<uint32_t> segment_point;  // part-local first point of each segment
  CapsuleChain chain;             // capsules: views the three buffers above
  // Triangles: the chunk, and the buffers Embree reads (the chunk's own, or padded copies).
  size_t chunk = 0;
  Array<float> positions;
  Array<uint32_t> triangle_indices;
};

// Embree's out of memory where no budget caught it first (the monitor refuses past the budget,
// and says so): the process's own limits, as for any allocation that fails.
std::string out_of_memory_cause() {
  const uint64_t left = address_space_left();
  return left == UINT64_MAX
             ? std::string("the machine's memory or the cgroup's limit")
             : "ulimit -v, which leaves this process " + format_bytes(left) + " of address space";
}

void throw_on_device_error(RTCDevice device, const char* what) {
  const RTCError e = rtcGetDeviceError(device);
  if (e == RTC_ERROR_OUT_OF_MEMORY)
    throw BudgetExceeded(std::string("Embree: ") + what +
                         " ran out of memory (RTC_ERROR_OUT_OF_MEMORY): " + out_of_memory_cause());
  if (e != RTC_ERROR_NONE)
    throw Error(std::string("Embree: ") + what + " failed (error " + std::to_string(int(e)) + ")");
}

}  // namespace

struct EmbreeScene::State {
  RTCDevice device = nullptr;
  RTCScene top = nullptr;
  std::vector<RTCScene> sub_scenes;
  std::atomic<int64_t> current{0}, peak{0};
  // What Embree may allocate (0: no limit), and whether the monitor cancelled an allocation
  // past it.
  int64_t limit = 0;
  std::atomic<bool> over_limit{false};
  StopLatch stop;  // the signal that cancelled a build (new_scene)
  std::atomic<int64_t> refused_bytes{0}, held_when_refused{0};  // the first allocation refused
  BvhStats stats;
  EmbreeGeometry geometry = EmbreeGeometry::LinearCurve;
  std::vector<Part> parts;
  Array<float> attribute;  // curves: per point (empty without attribute)
  TubeMesh mesh;           // triangles: shares the caller's arrays
  std::array<double, 2> range{0, 0};
  SceneFrame frame;

  ~State() {
    for (RTCScene s : sub_scenes) rtcReleaseScene(s);
    if (top) rtcReleaseScene(top);
    if (device) rtcReleaseDevice(device);
  }

  void set_attribute(const LineSet& lines, const std::string& name) {
    if (name.empty()) return;
    const Attribute* a = lines.find_attribute(name);
    if (!a) throw_unknown_attribute(lines, "--attribute", name, true);
    attribute = Array<float>(a->values.size());
    std::copy(a->values.begin(), a->values.end(), attribute.begin());
    const ValueRange r = compute_range(a->values);
    range = {r.min, r.max};
  }

  // Embree calls this from its build threads, concurrently, before or after (post) each large
  // allocation and free. Returning false cancels the operation with RTC_ERROR_OUT_OF_MEMORY: an
  // allocation refused before it happened is not counted, one reported after it is (Embree
  // frees it). An allocation is granted only if it fits with what is held (a compare-exchange,
  // so that no thread sees another's refused bytes), and none after the first refusal.
  static bool monitor(void* user, ssize_t bytes, bool post) {
    auto* self = static_cast<State*>(user);
    int64_t held = self->current.load();
    if (bytes > 0 && self->limit > 0) {
      do {
        if (self->over_limit || held + bytes > self->limit) {
          if (!self->over_limit.exchange(true)) {
            self->refused_bytes = bytes;
            self->held_when_refused = held;
          }
          if (post) self->note_peak(self->current.fetch_add(bytes) + bytes);
          return false;
        }
      } while (!self->current.compare_exchange_weak(held, held + bytes));
    } else {
      held = self->current.fetch_add(bytes);
    }
    self->note_peak(held + bytes);
    return true;
  }

  void note_peak(int64_t now) {
    int64_t high = peak.load();
    while (now > high && !peak.compare_exchange_weak(high, now)) {
    }
  }

  // What linebake holds for the scene besides the mesh or lines it views: the prepared input
  // buffers (their copies in the scene's frame too), each segment's first point, and the
  // attribute's copy.
  uint64_t held_bytes() const {
    uint64_t bytes = stats.buffer_bytes + attribute.bytes();
    for (const Part& part : parts) bytes += part.segment_point.bytes();
    return bytes;
  }

  // Short curves into a frame of their own (SceneFrame): the parts' mean segment length (a
  // segment's ends: Bezier's first and last control points) and their vertices' box centre;
  // the vertices copied into the frame, radii scaled too.
  void choose_frame() {
    if (geometry != EmbreeGeometry::LinearCurve && geometry != EmbreeGeometry::BezierCurve) return;
    const uint32_t last = geometry == EmbreeGeometry::BezierCurve ? 3 : 1;
    double length = 0;
    uint64_t segments = 0;
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
    for (const Part& part : parts) {
      const float* v = part.vertices.data();
      for (const uint32_t i : part.indices) {
        const glm::dvec3 a(v[4 * i], v[4 * i + 1], v[4 * i + 2]);
        const glm::dvec3 b(v[4 * (i + last)], v[4 * (i + last) + 1], v[4 * (i + last) + 2]);
        length += glm::length(b - a);
        ++segments;
        lo = glm::min(lo, glm::min(a, b));
        hi = glm::max(hi, glm::max(a, b));
      }
    }
    if (segments == 0 || !(length > 0) || !(length / double(segments) < kShortCurveSegment)) return;
    frame.scale = double(segments) / length;
    frame.centre = (lo + hi) * 0.5;
    for (Part& part : parts) {
      part.scene_vertices = Array<float>(part.vertices.size());
      const float* from = part.vertices.data();
      float* to = part.scene_vertices.data();
      for (size_t i = 0; i + 3 < part.vertices.size(); i += 4) {
        const glm::dvec3 p = frame.to_scene(glm::dvec3(from[i], from[i + 1], from[i + 2]));
        to[i] = float(p.x), to[i + 1] = float(p.y), to[i + 2] = float(p.z);
        to[i + 3] = float(double(from[i + 3]) * frame.scale);
      }
      stats.buffer_bytes += part.scene_vertices.bytes();
    }
  }

  void create_device() {
    device = rtcNewDevice(nullptr);
    if (!device) {
      const RTCError e = rtcGetDeviceError(nullptr);
      if (e == RTC_ERROR_OUT_OF_MEMORY)
        throw BudgetExceeded(
            "Embree: cannot create a device: out of memory (RTC_ERROR_OUT_OF_MEMORY; its "
            "threads' stacks and allocators take memory): " +
            out_of_memory_cause());
      // Anything else is Embree's own reason; a limit is named, not blamed.
      const uint64_t left = address_space_left();
      throw Error("Embree: cannot create a device (error " + std::to_string(int(e)) + ")" +
                  (left == UINT64_MAX ? std::string()
                                      : " (ulimit -v leaves this process " + format_bytes(left) +
                                            " of address space)"));
    }
    rtcSetDeviceMemoryMonitorFunction(device, &State::monitor, this);
  }

  RTCScene new_scene(const EmbreeOptions& o) {
    RTCScene scene = rtcNewScene(device);
    int flags = RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION;
    if (o.compact) flags |= RTC_SCENE_FLAG_COMPACT;
    if (o.robust) flags |= RTC_SCENE_FLAG_ROBUST;
    rtcSetSceneFlags(scene, RTCSceneFlags(flags));
    rtcSetSceneBuildQuality(scene, o.quality == BuildQuality::Low    ? RTC_BUILD_QUALITY_LOW
                                   : o.quality == BuildQuality::High ? RTC_BUILD_QUALITY_HIGH
                                                                     : RTC_BUILD_QUALITY_MEDIUM);
    // A large build takes seconds (a Renderer made in Python, a render's first frame): Embree
    // cancels it when its progress monitor says no, so Ctrl-C stops it there, said as such (not
    // as an Embree error).
    rtcSetSceneProgressMonitorFunction(
        scene, [](void* state, double) { return !static_cast<State*>(state)->stop.stopped(); },
        this);
    return scene;
  }

  RTCGeometry new_geometry(const Part& part) {
    RTCGeometry g = nullptr;
    if (geometry == EmbreeGeometry::Triangles) {
      g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                 part.positions.data(), 0, 12,
                                 mesh.chunks[part.chunk].vertex_count());
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                 part.triangle_indices.data(), 0, 12, part.primitives);
    } else if (geometry == EmbreeGeometry::Capsules) {
      g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
      set_capsule_geometry(g, &part.chain, uint32_t(part.primitives));
    } else {
      const bool linear = geometry == EmbreeGeometry::LinearCurve;
      g = rtcNewGeometry(device, linear ? RTC_GEOMETRY_TYPE_ROUND_LINEAR_CURVE
                                        : RTC_GEOMETRY_TYPE_ROUND_BEZIER_CURVE);
      const uint64_t vertices = (part.vertices.size() - 4) / 4;  // less the padding
      const Array<float>& seen = part.scene_vertices.empty() ? part.vertices : part.scene_vertices;
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, seen.data(), 0,
                                 16, vertices);
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT, part.indices.data(),
                                 0, 4, part.primitives);
      if (linear)
        rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_FLAGS, 0, RTC_FORMAT_UCHAR, part.flags.data(),
                                   0, 1, part.primitives);
    }
    throw_on_device_error(device, "setting up a geometry");
    rtcCommitGeometry(g);
    return g;
  }

  [[noreturn]] void throw_over_limit(uint64_t max_bytes) const {
    const std::string what = "Embree's BVH over " + std::to_string(stats.primitives) + " " +
                             (geometry == EmbreeGeometry::Triangles ? "triangles" : "segments") +
                             " needs more than the " + format_bytes(max_bytes) +
                             " the memory budget leaves for the scene (linebake's buffers " +
                             format_bytes(held_bytes());
    const std::string build =
        over_limit ? "; the build asked for " + format_bytes(uint64_t(refused_bytes.load())) +
                         " more while holding " +
                         format_bytes(uint64_t(std::max<int64_t>(held_when_refused.load(), 0)))
                   : "";
    throw BudgetExceeded(what + build + "); raise --memory-budget");
  }

  // Parts into scenes: one scene when everything fits, else consecutive parts grouped into
  // sub-scenes of at most max_primitives_per_scene, instanced with the identity transform.
  void commit(const EmbreeOptions& o) {
    const auto start = std::chrono::steady_clock::now();
    choose_frame();
    if (o.max_memory_bytes > 0) {
      if (held_bytes() >= o.max_memory_bytes) throw_over_limit(o.max_memory_bytes);
      limit = int64_t(o.max_memory_bytes - held_bytes());
    }
    top = new_scene(o);
    const bool instanced = stats.primitives > o.max_primitives_per_scene && parts.size() > 1;
    RTCScene current_scene = instanced ? nullptr : top;
    uint64_t in_scene = 0;
    for (size_t i = 0; i < parts.size(); ++i) {
      if (instanced &&
          (!current_scene || in_scene + parts[i].primitives > o.max_primitives_per_scene)) {
        current_scene = new_scene(o);
        sub_scenes.push_back(current_scene);
        in_scene = 0;
      }
      RTCGeometry g = new_geometry(parts[i]);
      rtcAttachGeometryByID(current_scene, g,
                            unsigned(i));  // geomID = part index, also in sub-scenes
      rtcReleaseGeometry(g);
      in_scene += parts[i].primitives;
    }
    for (size_t s = 0; s < sub_scenes.size(); ++s) {
      rtcCommitScene(sub_scenes[s]);
      stop.throw_if_stopped();
      if (over_limit) throw_over_limit(o.max_memory_bytes);
      RTCGeometry inst = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
      rtcSetGeometryInstancedScene(inst, sub_scenes[s]);
      const float identity[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
      rtcSetGeometryTransform(inst, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, identity);
      rtcCommitGeometry(inst);
      rtcAttachGeometryByID(top, inst, unsigned(s));
      rtcReleaseGeometry(inst);
    }
    rtcCommitScene(top);
    stop.throw_if_stopped();
    if (over_limit) throw_over_limit(o.max_memory_bytes);
    throw_on_device_error(device, "the BVH build");
    stats.commit_s = seconds_since(start);
    stats.instanced = instanced;
    stats.parts = parts.size();
    stats.bvh_bytes = uint64_t(std::max<int64_t>(current.load(), 0));
    stats.bvh_peak_bytes = uint64_t(std::max<int64_t>(peak.load(), 0));
  }
};

EmbreeGeometry parse_embree_geometry(const std::string& name) {
  if (name == "linear") return EmbreeGeometry::LinearCurve;
  if (name == "bezier") return EmbreeGeometry::BezierCurve;
  if (name == "triangles") return EmbreeGeometry::Triangles;
  if (name == "capsules") return EmbreeGeometry::Capsules;
  throw Error("unknown Embree geometry '" + name + "' (linear, bezier, triangles, capsules)");
}

const char* to_string(EmbreeGeometry g) {
  switch (g) {
    case EmbreeGeometry::LinearCurve:
      return "linear";
    case EmbreeGeometry::BezierCurve:
      return "bezier";
    case EmbreeGeometry::Triangles:
      return "triangles";
    case EmbreeGeometry::Capsules:
      return "capsules";
  }
  return "?";
}

BuildQuality parse_build_quality(const std::string& name) {
  if (name == "low") return BuildQuality::Low;
  if (name == "medium") return BuildQuality::Medium;
  if (name == "high") return BuildQuality::High;
  throw Error("unknown build quality '" + name + "' (low, medium, high)");
}

const char* to_string(BuildQuality q) {
  switch (q) {
    case BuildQuality::Low:
      return "low";
    case BuildQuality::Medium:
      return "medium";
    case BuildQuality::High:
      return "high";
  }
  return "?";
}

uint64_t curve_part_limit(const EmbreeOptions& options) {
  return std::min<uint64_t>(options.max_primitives_per_scene, 0xFFFFFFFFull / 4);
}

void CurvePartPlanner::add(uint64_t line_points) {
  const uint64_t segments = line_points > 1 ? line_points - 1 : 0;
  if (segments > limit_)
    throw Error("Embree: line " + std::to_string(line_) + " has more segments than fit a scene");
  if (open_.segments + segments > limit_) {
    if (open_.segments > 0) parts_.push_back(open_);
    open_ = {line_, line_, point_, 0, 0};
  }
  open_.end_line = ++line_;
  open_.points += line_points;
  open_.segments += segments;
  point_ += line_points;
}

std::vector<CurvePart> CurvePartPlanner::finish() {
  if (open_.segments > 0) parts_.push_back(open_);
  open_ = {line_, line_, point_, 0, 0};
  return std::move(parts_);
}

uint64_t curve_vertices(const CurvePart& part, EmbreeGeometry geometry) {
  return geometry == EmbreeGeometry::BezierCurve ? 4 * part.segments : part.points;
}

void prepare_curves(const LineSet& lines, size_t first, size_t end, uint64_t point_base,
                    uint64_t segment_base, float radius, EmbreeGeometry geometry,
                    const CurveOutput& out) {
  const bool linear = geometry != EmbreeGeometry::BezierCurve;
  const auto point = [&](uint64_t p) {
    return glm::vec3(lines.positions[3 * p], lines.positions[3 * p + 1],
                     lines.positions[3 * p + 2]);
  };
  const auto put = [&](uint64_t v, glm::vec3 x) {
    float* o = out.vertices + 4 * v;
    o[0] = x.x, o[1] = x.y, o[2] = x.z, o[3] = radius;
  };
  const uint64_t first_point = lines.line_offsets[first];
  if (linear)
    for (uint64_t p = first_point; p < lines.line_offsets[end]; ++p) put(p - first_point, point(p));
  uint64_t s = 0;
  for (size_t l = first; l < end; ++l) {
    const uint64_t begin = lines.line_offsets[l], stop = lines.line_offsets[l + 1];
    for (uint64_t p = begin; p + 1 < stop; ++p, ++s) {
      if (linear) {
        out.indices[s] = uint32_t(point_base + (p - first_point));
        out.flags[s] = uint8_t((p > begin ? RTC_CURVE_FLAG_NEIGHBOR_LEFT : 0) |
                               (p + 2 < stop ? RTC_CURVE_FLAG_NEIGHBOR_RIGHT : 0));
      } else {
        // Catmull-Rom through p0 p1 p2 p3 as the Bezier b0 b1 b2 b3 of the span p1 -> p2;
        // at a line's ends the missing neighbour is the end point itself.
        const glm::vec3 p1 = point(p), p2 = point(p + 1);
        const glm::vec3 p0 = p > begin ? point(p - 1) : p1;
        const glm::vec3 p3 = p + 2 < stop ? point(p + 2) : p2;
        out.indices[s] = uint32_t(4 * (segment_base + s));
        put(4 * s, p1);
        put(4 * s + 1, p1 + (p2 - p0) / 6.0f);
        put(4 * s + 2, p2 - (p3 - p1) / 6.0f);
        put(4 * s + 3, p2);
      }
    }
  }
}

EmbreeScene EmbreeScene::from_lines(const LineSet& lines, float radius,
                                    const std::string& attribute, const EmbreeOptions& options) {
  if (options.geometry == EmbreeGeometry::Triangles)
    throw Error("Embree: triangles are built from a tube mesh, not from lines");
  if (!(radius > 0)) throw Error("Embree: the curve radius must be positive");
  if (options.max_primitives_per_scene == 0) throw Error("Embree: max primitives per scene is 0");
  auto state = std::make_unique<State>();
  state->geometry = options.geometry;
  state->stats.geometry = options.geometry;
  const auto start = std::chrono::steady_clock::now();
  state->set_attribute(lines, attribute);
  const bool linear = options.geometry != EmbreeGeometry::BezierCurve;
  CurvePartPlanner planner(curve_part_limit(options));
  for (size_t l = 0; l < lines.line_count(); ++l) planner.add(lines.line_size(l));
  const std::vector<CurvePart> plans = planner.finish();
  // The buffers below, refused before they are made where they alone pass the limit.
  if (options.max_memory_bytes > 0) {
    uint64_t planned = state->attribute.bytes(), segments = 0;
    for (const CurvePart& plan : plans) {
      planned += 16 * (curve_vertices(plan, options.geometry) + 1) +
                 plan.segments * (4 + 4 + (linear ? 1 : 0));
      segments += plan.segments;
    }
    if (planned >= options.max_memory_bytes)
      throw BudgetExceeded("Embree's input buffers for " + std::to_string(segments) +
                           " segments take " + format_bytes(planned) + ", more than the " +
                           format_bytes(options.max_memory_bytes) +
                           " the memory budget leaves for the scene; raise --memory-budget");
  }
  for (const CurvePart& plan : plans) {
    Part part;
    part.primitives = plan.segments;
    part.first_point = plan.first_point;
    const uint64_t vertex_count = curve_vertices(plan, options.geometry);
    part.vertices = Array<float>(4 * (vertex_count + 1));  // + one padding vertex
    part.indices = Array<uint32_t>(part.primitives);
    part.segment_point = Array<uint32_t>(part.primitives);
    if (linear) part.flags = Array<uint8_t>(part.primitives);
    prepare_curves(lines, plan.first_line, plan.end_line, 0, 0, radius, options.geometry,
                   {part.vertices.data(), part.indices.data(), part.flags.data()});
    uint64_t s = 0;
    for (size_t l = plan.first_line; l < plan.end_line; ++l)
      for (uint64_t p = lines.line_offsets[l]; p + 1 < lines.line_offsets[l + 1]; ++p, ++s)
        part.segment_point[s] = uint32_t(p - part.first_point);
    std::memset(part.vertices.data() + 4 * vertex_count, 0, 16);
    part.chain = {part.vertices.data(), part.indices.data(), part.flags.data()};
    state->stats.primitives += part.primitives;
    state->stats.buffer_bytes += part.vertices.bytes() + part.indices.bytes() + part.flags.bytes();
    state->parts.push_back(std::move(part));
  }
  state->stats.prepare_s = seconds_since(start);
  state->create_device();
  state->commit(options);
  return EmbreeScene(std::move(state));
}

EmbreeScene EmbreeScene::from_prepared(const LineSet& lines, std::vector<PreparedCurves> buffers,
                                       const std::string& attribute, const EmbreeOptions& options) {
  if (options.geometry == EmbreeGeometry::Triangles)
    throw Error("Embree: prepared buffers hold curves, not triangles");
  auto state = std::make_unique<State>();
  state->geometry = options.geometry;
  state->stats.geometry = options.geometry;
  const auto start = std::chrono::steady_clock::now();
  state->set_attribute(lines, attribute);
  // Parts hold whole lines in order: walk the lines to find each segment's first point.
  const bool point_layout = options.geometry != EmbreeGeometry::BezierCurve;
  size_t line = 0;
  for (PreparedCurves& b : buffers) {
    Part part;
    part.primitives = b.indices.size();
    part.first_point = line < lines.line_count() ? lines.line_offsets[line] : 0;
    part.segment_point = Array<uint32_t>(part.primitives);
    // from_lines closes a part at the first line that does not fit, so lines without segments
    // after its last segment still belong to it.
    uint64_t s = 0;
    bool fits = true;
    while (line < lines.line_count() && (s < part.primitives || lines.line_size(line) < 2)) {
      const uint64_t begin = lines.line_offsets[line], end = lines.line_offsets[line + 1];
      if (end - begin > 1 && s + (end - begin - 1) > part.primitives) {
        fits = false;
        break;
      }
      for (uint64_t p = begin; p + 1 < end; ++p, ++s)
        part.segment_point[s] = uint32_t(p - part.first_point);
      ++line;
    }
    const uint64_t vertices = b.vertices.size() / 4;
    if (!fits || s != part.primitives || vertices < 1 || (point_layout && b.flags.size() != s) ||
        (point_layout ? lines.line_offsets[line] - part.first_point + 1 != vertices
                      : 4 * s + 1 != vertices))
      throw Error("Embree: the prepared buffers do not match the lines");
    part.vertices = std::move(b.vertices);
    part.indices = std::move(b.indices);
    part.flags = std::move(b.flags);
    part.chain = {part.vertices.data(), part.indices.data(), part.flags.data()};
    state->stats.primitives += part.primitives;
    state->stats.buffer_bytes += part.vertices.bytes() + part.indices.bytes() + part.flags.bytes();
    state->parts.push_back(std::move(part));
  }
  while (buffers.empty() && line < lines.line_count() && lines.line_size(line) < 2) ++line;
  if (line != lines.line_count())
    throw Error("Embree: the prepared buffers do not match the lines");
  state->stats.prepare_s = seconds_since(start);
  state->create_device();
  state->commit(options);
  return EmbreeScene(std::move(state));
}

EmbreeScene EmbreeScene::from_tubes(const TubeMesh& mesh, const EmbreeOptions& options) {
  auto state = std::make_unique<State>();
  state->geometry = EmbreeGeometry::Triangles;
  state->stats.geometry = EmbreeGeometry::Triangles;
  state->mesh = mesh;
  state->range = {mesh.attribute_range[0], mesh.attribute_range[1]};
  const auto start = std::chrono::steady_clock::now();
  for (size_t c = 0; c < mesh.chunks.size(); ++c) {
    const TubeChunk& chunk = mesh.chunks[c];
    if (chunk.triangle_count() == 0) continue;
    Part part;
    part.chunk = c;
    part.primitives = chunk.triangle_count();
    part.positions = shareable(chunk.positions.data(), chunk.positions.bytes())
                         ? chunk.positions
                         : padded_copy(chunk.positions);
    part.triangle_indices = shareable(chunk.indices.data(), chunk.indices.bytes())
                                ? chunk.indices
                                : padded_copy(chunk.indices);
    if (part.positions.data() != chunk.positions.data())
      state->stats.buffer_bytes += part.positions.bytes();
    if (part.triangle_indices.data() != chunk.indices.data())
      state->stats.buffer_bytes += part.triangle_indices.bytes();
    state->stats.primitives += part.primitives;
    state->parts.push_back(std::move(part));
  }
  state->stats.prepare_s = seconds_since(start);
  state->create_device();
  state->commit(options);
  return EmbreeScene(std::move(state));
}

EmbreeScene::EmbreeScene(std::unique_ptr<State> state) : state_(std::move(state)) {}
EmbreeScene::EmbreeScene(EmbreeScene&&) noexcept = default;
EmbreeScene& EmbreeScene::operator=(EmbreeScene&&) noexcept = default;
EmbreeScene::~EmbreeScene() = default;

RTCScene EmbreeScene::handle() const {
  return state_->top;
}
const BvhStats& EmbreeScene::stats() const {
  return state_->stats;
}
std::array<double, 2> EmbreeScene::attribute_range() const {
  return state_->range;
}

Bounds EmbreeScene::bounds() const {
  RTCBounds b;
  rtcGetSceneBounds(state_->top, &b);
  Bounds out;
  out.empty = !(b.lower_x <= b.upper_x);
  const SceneFrame& f = state_->frame;
  const glm::dvec3 lo = glm::dvec3(b.lower_x, b.lower_y, b.lower_z) / f.scale + f.centre;
  const glm::dvec3 hi = glm::dvec3(b.upper_x, b.upper_y, b.upper_z) / f.scale + f.centre;
  out.min = {float(lo.x), float(lo.y), float(lo.z)};
  out.max = {float(hi.x), float(hi.y), float(hi.z)};
  return out;
}

const SceneFrame& EmbreeScene::frame() const {
  return state_->frame;
}

std::vector<PreparedCurves> EmbreeScene::prepared_curves() const {
  std::vector<PreparedCurves> out;
  if (state_->geometry == EmbreeGeometry::Triangles) return out;
  for (const Part& part : state_->parts) out.push_back({part.vertices, part.indices, part.flags});
  return out;
}

bool EmbreeScene::adjacent(unsigned geometry, unsigned a, unsigned b) const {
  const State& s = *state_;
  const Part& part = s.parts[geometry];
  if (a > b) std::swap(a, b);
  if (s.geometry == EmbreeGeometry::Triangles) {
    const uint32_t* ta = s.mesh.chunks[part.chunk].indices.data() + 3 * uint64_t(a);
    const uint32_t* tb = s.mesh.chunks[part.chunk].indices.data() + 3 * uint64_t(b);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (ta[i] == tb[j]) return true;
    return false;
  }
  // Consecutive segments of one line share a point.
  return b == a + 1 && part.segment_point[b] == part.segment_point[a] + 1;
}

SurfacePoint EmbreeScene::surface(const RTCHit& hit) const {
  const State& s = *state_;
  // Instanced: the instance id is the sub-scene, the geometry id is still the part index.
  const Part& part = s.parts[hit.geomID];
  SurfacePoint out;
  if (s.geometry == EmbreeGeometry::Triangles) {
    const TubeChunk& chunk = s.mesh.chunks[part.chunk];
    const uint32_t* tri = chunk.indices.data() + 3 * uint64_t(hit.primID);
    const double w[3] = {1.0 - hit.u - hit.v, hit.u, hit.v};
    glm::dvec3 n(0);
    double a = 0;
    for (int k = 0; k < 3; ++k) {
      const uint64_t v = tri[k];
      if (!chunk.normals.empty()) {
        n += w[k] *
             glm::dvec3(chunk.normals[3 * v], chunk.normals[3 * v + 1], chunk.normals[3 * v + 2]);
      } else if (!chunk.normals_oct.empty()) {
        const auto d = decode_octahedral(chunk.normals_oct[2 * v], chunk.normals_oct[2 * v + 1]);
        n += w[k] * glm::dvec3(d[0], d[1], d[2]);
      }
      if (!chunk.attribute.empty())
        a += w[k] * decode_unorm16(chunk.attribute[v], s.mesh.attribute_range);
    }
    const double len = glm::length(n);
    out.normal = len > 0 ? n / len : glm::normalize(glm::dvec3(hit.Ng_x, hit.Ng_y, hit.Ng_z));
    out.attribute = a;
    return out;
  }
  out.normal = glm::normalize(glm::dvec3(hit.Ng_x, hit.Ng_y, hit.Ng_z));
  if (!s.attribute.empty()) {
    const uint64_t p = part.first_point + part.segment_point[hit.primID];
    const double u = std::clamp(double(hit.u), 0.0, 1.0);
    out.attribute = s.attribute[p] + u * (double(s.attribute[p + 1]) - s.attribute[p]);
  }
  return out;
}

}  // namespace linebake
