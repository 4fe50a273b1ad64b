// Shared by the passes of the `tiles` technique (lib/render/vulkan/tile_renderer.hpp): an exact
// transparency renderer built only from compute shaders, after the tile rasterisers of 3D
// Gaussian splatting (bin primitives into 16x16 tiles, sort (tile, depth) keys, one workgroup per
// tile blending front to back) with StopThePop's per-pixel sorted window, so the order is exact
// per pixel even where the depth keys misorder long, overlapping capsules.

#include "dispatch.glsl"

const int kMaxTfPoints = 32;
const uint kTile = 16;

layout(set = 0, binding = 0, std140) uniform TileUniforms {
#include "tiles_frame.glsl"
} frame;
// The same buffer as a storage buffer, for the values that a branch or a loop bound tests on
// their own (the transfer function's point counts, early termination, the tile rows). Mesa
// 22.3's lavapipe specialises a shader on the uniform-buffer values that its branches and loops
// test alone, and compiles it again with LLVM for every command buffer that binds it: 14 to 21
// ms a submission of the composite, which a frame makes once per walk (the paper-small aneurysm
// at 640x360: 3 to 7 walks a frame). It leaves storage buffers alone. The other values stay in
// the uniform buffer, whose loads lavapipe vectorises where a storage buffer's are a loop over
// the lanes (with every value in a storage buffer, the composite of paper-small's convection,
// turbulence and clouds ran 10 to 20 % slower).
layout(set = 0, binding = 18, std430) restrict readonly buffer TileTests {
#include "tiles_frame.glsl"
} frame_tests;
#define TF_COUNTS frame_tests.tf_counts

// The frame's view values as the passes read them: a private copy that each pass's main loads
// first (load_frame_view), where all lanes run together. lavapipe (gallivm) appears to load a
// uniform-buffer value lane by lane inside branches and loops whose lanes part: reading binning's
// values at the top of main took 1.2 of 15.6 billion JIT instructions off a paper-small clouds
// frame at 320x180 under callgrind, the copy in every pass another 0.2 (docs/tiles.md, "Keys only
// where a pixel may hit"). Values that a branch or loop tests alone stay in frame_tests.
struct FrameView {
  vec3 eye, forward, right, up;
  vec4 params;
  uvec4 size, tiles, band;
};
FrameView view;

void load_frame_view() {
  view.eye = frame.eye.xyz, view.forward = frame.forward.xyz;
  view.right = frame.right.xyz, view.up = frame.up.xyz;
  view.params = frame.params, view.size = frame.size, view.tiles = frame.tiles;
  view.band = frame.band;
}

// Bindings 1 and 2 hold the primitives: tiles_capsules.glsl or tiles_triangles.glsl.
layout(set = 0, binding = 3, std430) buffer Keys { uint keys[]; };
layout(set = 0, binding = 4, std430) buffer Values { uint values[]; };
// keys emitted (may exceed the capacity: then the frame is binned again), segments binned.
layout(set = 0, binding = 5, std430) buffer Counters { uint key_count; uint binned; } counters;
// Per tile: first and one past the last sorted key.
layout(set = 0, binding = 6, std430) buffer Ranges { uvec2 ranges[]; };
layout(set = 0, binding = 7, std430) writeonly buffer Pixels { vec4 pixels[]; };
layout(set = 0, binding = 8, std430) writeonly buffer Hits { uint hit_counts[]; };
// Keys per tile row (binning counts them, so the host can cut the frame into bands).
layout(set = 0, binding = 12, std430) buffer RowKeys { uint row_keys[]; };

// The lower bound of a key's view depth: keys hold floor((z - near) / (far - near) * (2^bits - 1))
// of the primitive's nearest view depth z (the composite turns it into a bound on t along each
// pixel's ray).
float key_depth(uint key) {
  const uint bits = view.tiles.z;
  const float q = float(key & ((1u << bits) - 1u));
  return view.params.z + q / float((1u << bits) - 1u) * (view.params.w - view.params.z);
}

// Pixel position and view depth of the point at offset q from the eye (binning).
vec3 project_offset(vec3 q) {
  const float z = dot(q, view.forward);
  const float x = dot(q, view.right) / dot(view.right, view.right) / z;
  const float y = -dot(q, view.up) / dot(view.up, view.up) / z;
  return vec3((x + 1.0) * 0.5 * float(view.size.x), (y + 1.0) * 0.5 * float(view.size.y), z);
}

// ... and of a point.
vec3 project(vec3 p) {
  return project_offset(p - view.eye);
}

// The signed distances of the view-relative point q from the four side planes of the view's
// pyramid (right, left, up, down; positive outside). Every pixel's ray lies inside all four, so
// a primitive wholly outside one of them by more than its reach has no hit: that tells the
// primitives near the plane of the eye, whose projection is unbounded, from those that may
// cover the screen.
vec4 pyramid_distances(vec3 q) {
  const float tx = length(view.right), ty = length(view.up);
  const float x = dot(q, view.right) / tx, y = dot(q, view.up) / ty, z = dot(q, view.forward);
  return vec4(x - tx * z, -x - tx * z, y - ty * z, -y - ty * z) /
         vec4(sqrt(1.0 + tx * tx), sqrt(1.0 + tx * tx), sqrt(1.0 + ty * ty), sqrt(1.0 + ty * ty));
}

// The pixels whose ray may hit a primitive with screen bounds [lo, hi]: those whose centre
// (x + 0.5, y + 0.5), through which the ray passes, lies inside them, [p0, p1] (empty where p0 >
// p1 on an axis), clamped to one pixel outside the image. Binning's tiles and the composite's
// blocks both come from here. A small primitive between pixel centres covers none. With the
// capsules' exact bounds this took 27 % of paper-small's keys (40 to 65 % with triangles; see
// docs/tiles.md). Bounds that are not numbers cover the whole image.
void covered_pixels(vec2 lo, vec2 hi, out ivec2 p0, out ivec2 p1) {
  const vec2 size = vec2(view.size.xy);
  if (any(isnan(lo)) || any(isnan(hi))) lo = vec2(0.0), hi = size;
  p0 = ivec2(clamp(ceil(lo - 0.5), vec2(-1.0), size));
  p1 = ivec2(clamp(floor(hi - 0.5), vec2(-1.0), size));
}

// The unit ray from the eye through the centre of `pixel`: one function for the composite's
// pixels, the invocations that compute their pairs' hits and binning's probes of small
// primitives, so all see the same ray.
vec3 ray_direction(uvec2 pixel) {
  const vec2 ndc = (vec2(pixel) + 0.5) / vec2(view.size.xy) * 2.0 - 1.0;
  return normalize(view.forward + ndc.x * view.right - ndc.y * view.up);
}

// The nearest distance at which binning clips: in front of the eye, scaled to the data.
float near_clip() {
  return max(1e-6 * (view.params.w - view.params.z), view.params.y * 1e-3);
}
