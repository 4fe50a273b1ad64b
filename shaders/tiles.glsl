// Shared by the passes of the `tiles` technique (lib/render/vulkan/tile_renderer.hpp): an exact
// transparency renderer built only from compute shaders, after the tile rasterisers of 3D
// Gaussian splatting (bin primitives into 16x16 tiles, sort (tile, depth) keys, one workgroup per
// tile blending front to back) with StopThePop's per-pixel sorted window, so the order is exact
// per pixel even where the depth keys misorder long, overlapping capsules.

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
  const uint bits = frame.tiles.z;
  const float q = float(key & ((1u << bits) - 1u));
  return frame.params.z + q / float((1u << bits) - 1u) * (frame.params.w - frame.params.z);
}

// Pixel position and view depth of a point (binning).
vec3 project(vec3 p) {
  const vec3 q = p - frame.eye.xyz;
  const float z = dot(q, frame.forward.xyz);
  const float x = dot(q, frame.right.xyz) / dot(frame.right.xyz, frame.right.xyz) / z;
  const float y = -dot(q, frame.up.xyz) / dot(frame.up.xyz, frame.up.xyz) / z;
  return vec3((x + 1.0) * 0.5 * float(frame.size.x), (y + 1.0) * 0.5 * float(frame.size.y), z);
}

// The pixels whose ray may hit a primitive with screen bounds [lo, hi]: those whose centre
// (x + 0.5, y + 0.5), through which the ray passes, lies inside them, [p0, p1] (empty where p0 >
// p1 on an axis), clamped to one pixel outside the image. Binning's tiles and the composite's
// blocks both come from here. A small primitive between pixel centres covers none. With the
// capsules' exact bounds this took 27 % of paper-small's keys (40 to 65 % with triangles; see
// the README). Bounds that are not numbers cover the whole image.
void covered_pixels(vec2 lo, vec2 hi, out ivec2 p0, out ivec2 p1) {
  const vec2 size = vec2(frame.size.xy);
  if (any(isnan(lo)) || any(isnan(hi))) lo = vec2(0.0), hi = size;
  p0 = ivec2(clamp(ceil(lo - 0.5), vec2(-1.0), size));
  p1 = ivec2(clamp(floor(hi - 0.5), vec2(-1.0), size));
}

// The unit ray from the eye through the centre of `pixel`: one function for the composite's
// pixels, the invocations that compute their pairs' hits and binning's probes of small
// primitives, so all see the same ray.
vec3 ray_direction(uvec2 pixel) {
  const vec2 ndc = (vec2(pixel) + 0.5) / vec2(frame.size.xy) * 2.0 - 1.0;
  return normalize(frame.forward.xyz + ndc.x * frame.right.xyz - ndc.y * frame.up.xyz);
}

// The nearest distance at which binning clips: in front of the eye, scaled to the data.
float near_clip() {
  return max(1e-6 * (frame.params.w - frame.params.z), frame.params.y * 1e-3);
}
