// Shared by the passes of the `tiles` technique (lib/render/vulkan/tile_renderer.hpp): an exact
// transparency renderer built only from compute shaders, after the tile rasterisers of 3D
// Gaussian splatting (bin primitives into 16x16 tiles, sort (tile, depth) keys, one workgroup per
// tile blending front to back) with StopThePop's per-pixel sorted window, so the order is exact
// per pixel even where the depth keys misorder long, overlapping capsules.

const int kMaxTfPoints = 32;
const uint kTile = 16;

layout(set = 0, binding = 0, std140) uniform TileUniforms {
  vec4 eye;         // xyz
  vec4 forward;     // xyz, unit
  vec4 right;       // xyz, scaled by tan(fov/2) x aspect
  vec4 up;          // xyz, scaled by tan(fov/2)
  vec4 shading;     // ambient, diffuse, specular, shininess
  vec4 background;  // linear rgb
  vec4 ranges;      // 0, 0; transfer-function range lo, hi
  uvec4 size;       // width, height, early termination, primitives
  uvec4 tf_counts;  // colour points, opacity points, 0, 0
  vec4 params;      // termination alpha, capsule radius, key depth near, key depth far
  uvec4 tiles;      // tiles across, tiles down, depth bits of a key, key capacity
  uvec4 band;       // the tile rows of this pass: first, one past the last
  vec4 colours[kMaxTfPoints];    // x, sRGB r, g, b
  vec4 opacities[kMaxTfPoints];  // x, opacity
} frame;

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

// The nearest distance at which binning clips: in front of the eye, scaled to the data.
float near_clip() {
  return max(1e-6 * (frame.params.w - frame.params.z), frame.params.y * 1e-3);
}
