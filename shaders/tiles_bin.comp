#version 460
// tiles, pass 1: each segment's capsule is projected to the screen, culled, and one key per tile
// its bounds cover is emitted: the tile in the high bits, the quantised nearest view depth in
// the low bits, the segment as the value.
#include "tiles.glsl"

layout(local_size_x = 256) in;

// Pixel position and view depth of a point.
vec3 project(vec3 p) {
  const vec3 q = p - frame.eye.xyz;
  const float z = dot(q, frame.forward.xyz);
  const float x = dot(q, frame.right.xyz) / dot(frame.right.xyz, frame.right.xyz) / z;
  const float y = -dot(q, frame.up.xyz) / dot(frame.up.xyz, frame.up.xyz) / z;
  return vec3((x + 1.0) * 0.5 * float(frame.size.x), (y + 1.0) * 0.5 * float(frame.size.y), z);
}

void main() {
  const uint s = gl_GlobalInvocationID.x;
  if (s >= frame.size.w) return;
  const uint first = segments[s] >> 2u;
  vec3 a = points[first].xyz, b = points[first + 1u].xyz;
  const float r = frame.params.y;
  const vec3 f = frame.forward.xyz;
  float za = dot(a - frame.eye.xyz, f), zb = dot(b - frame.eye.xyz, f);
  // Behind the eye: culled; crossing the plane just in front of it: clipped there (pushed back
  // by the radius, so the end spheres stay in front too).
  const float near = max(1e-6 * (frame.params.w - frame.params.z), r * 1e-3);
  if (max(za, zb) + r <= near) return;
  const float clip = near + r;
  if (za < clip || zb < clip) {
    if (max(za, zb) < clip) {
      // Wholly within a radius of the eye: it may cover the whole screen.
      a = frame.eye.xyz + clip * f + (a - frame.eye.xyz - za * f);
      b = frame.eye.xyz + clip * f + (b - frame.eye.xyz - zb * f);
      za = zb = clip;
    } else {
      const vec3 from = za < clip ? b : a, to = za < clip ? a : b;
      const float zf = za < clip ? zb : za, zt = za < clip ? za : zb;
      const vec3 cut = from + (to - from) * ((zf - clip) / (zf - zt));
      if (za < clip) a = cut, za = clip;
      else b = cut, zb = clip;
    }
  }
  const vec3 pa = project(a), pb = project(b);
  // A sphere of radius r at depth z lies within r / (z - r) of its centre's direction in the
  // image plane at distance 1 (conservative also off axis with the factor for the corner).
  const float focal = 0.5 * float(frame.size.y) / length(frame.up.xyz);
  const float corner = sqrt(1.0 + dot(frame.right.xyz, frame.right.xyz) + dot(frame.up.xyz, frame.up.xyz));
  const float ra = r / max(za - r, near) * focal * corner + 1.0;
  const float rb = r / max(zb - r, near) * focal * corner + 1.0;
  const vec2 lo = min(pa.xy - ra, pb.xy - rb), hi = max(pa.xy + ra, pb.xy + rb);
  const ivec2 tiles = ivec2(frame.tiles.xy);
  const ivec2 t0 = clamp(ivec2(floor(lo / float(kTile))), ivec2(0), tiles - 1);
  const ivec2 t1 = clamp(ivec2(floor(hi / float(kTile))), ivec2(0), tiles - 1);
  if (hi.x < 0.0 || hi.y < 0.0 || lo.x >= float(frame.size.x) || lo.y >= float(frame.size.y))
    return;
  const float z_near = max(min(za, zb) - r, frame.params.z);
  const uint bits = frame.tiles.z;
  const float span = frame.params.w - frame.params.z;
  const float level = clamp((z_near - frame.params.z) / span, 0.0, 1.0) * float((1u << bits) - 1u);
  const uint depth = min(uint(floor(level)), (1u << bits) - 1u);
  const uint n = uint((t1.x - t0.x + 1) * (t1.y - t0.y + 1));
  // The count saturates instead of wrapping past 2^32 - 1 (the host refuses such a frame).
  const uint base = atomicAdd(counters.key_count, n);
  if (base > 0xFFFFFFFFu - n) atomicMax(counters.key_count, 0xFFFFFFFFu);
  atomicAdd(counters.binned, 1u);
  if (base > frame.tiles.w || n > frame.tiles.w - base) return;  // no room: binned again
  uint at = base;
  for (int ty = t0.y; ty <= t1.y; ++ty)
    for (int tx = t0.x; tx <= t1.x; ++tx) {
      const uint tile = uint(ty) * frame.tiles.x + uint(tx);
      keys[at] = (tile << bits) | depth;
      values[at] = s;
      ++at;
    }
}
