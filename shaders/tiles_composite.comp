#version 460
// tiles, pass 3: one workgroup per 16x16 tile walks the tile's segments in key order, a batch of
// 256 at a time through shared memory. Each pixel intersects its ray with each capsule
// (capsule.glsl: the chain's union surface, front crossings only, as Embree's capsules and rtx
// capsules) and keeps its hits in a small window sorted by t. A hit is composited once no later
// segment can come nearer: every later key's depth bound is past it. Only when the window is full
// is its nearest hit composited early, and that is counted (window_overflows).
//
// A dispatch takes one slice of each tile's keys; the pixels' state (colour, window) carries over
// between slices through a buffer. Devices that cap the loop iterations of an invocation
// (lavapipe: 65535) render in slices; others in one.
#include "tiles.glsl"
#include "shading.glsl"
#include "capsule.glsl"

layout(local_size_x = 16, local_size_y = 16) in;

const uint kBatch = 256;
const int kWindow = 16;

shared vec4 batch_p0[kBatch];  // xyz, attribute
shared vec4 batch_p1[kBatch];
shared vec4 batch_before[kBatch];  // xyz, flags
shared vec4 batch_after[kBatch];   // xyz, key depth bound
layout(set = 0, binding = 9, std430) buffer Stats { uint window_overflows; } stats;
// This dispatch's slice: keys [slice * slice_keys, (slice + 1) * slice_keys) of each tile's range;
// first: the pixels start empty; last: they are written out.
layout(set = 0, binding = 10, std430) readonly buffer Slice {
  uint slice, slice_keys, first, last;
} slicing;
struct PixelState {
  vec4 colour_alpha;
  uint hits, pending, done, pad;
  float t[kWindow];
  vec4 colour[kWindow];
};
layout(set = 0, binding = 11, std430) buffer States { PixelState states[]; };

float window_t[kWindow];
vec4 window_colour[kWindow];
int pending = 0;
vec3 colour = vec3(0.0);
float alpha = 0.0;
uint hit_count = 0u;
bool done = false;

void composite(vec4 c) {
  colour += (1.0 - alpha) * c.a * c.rgb;
  alpha += (1.0 - alpha) * c.a;
  ++hit_count;
  if (frame.size.z != 0u && alpha >= frame.params.x) done = true;
}

// Composites the pending hits nearer than `bound`, nearest first.
void flush(float bound) {
  int k = 0;
  while (k < pending && window_t[k] < bound && !done) composite(window_colour[k++]);
  if (done) k = pending;
  for (int j = k; j < pending; ++j) {
    window_t[j - k] = window_t[j];
    window_colour[j - k] = window_colour[j];
  }
  pending -= k;
}

void insert(float t, vec4 c) {
  if (pending == kWindow) {
    // Full: the nearest goes now (exact unless a later segment comes nearer still).
    atomicAdd(stats.window_overflows, 1u);
    composite(window_colour[0]);
    for (int j = 1; j < pending; ++j) {
      window_t[j - 1] = window_t[j];
      window_colour[j - 1] = window_colour[j];
    }
    --pending;
  }
  int at = pending;
  while (at > 0 && window_t[at - 1] > t) {
    window_t[at] = window_t[at - 1];
    window_colour[at] = window_colour[at - 1];
    --at;
  }
  window_t[at] = t;
  window_colour[at] = c;
  ++pending;
}

void main() {
  const uvec2 pixel = gl_GlobalInvocationID.xy;
  const uint tile = gl_WorkGroupID.y * frame.tiles.x + gl_WorkGroupID.x;
  const uint lane = gl_LocalInvocationIndex;
  const bool inside = pixel.x < frame.size.x && pixel.y < frame.size.y;
  const uint index = pixel.y * frame.size.x + pixel.x;
  if (inside && slicing.first == 0u) {
    const PixelState s = states[index];
    colour = s.colour_alpha.rgb;
    alpha = s.colour_alpha.a;
    hit_count = s.hits;
    pending = int(s.pending);
    done = s.done != 0u;
    for (int k = 0; k < kWindow; ++k) window_t[k] = s.t[k], window_colour[k] = s.colour[k];
  }
  const uvec2 whole = ranges[tile];
  const uint begin = min(whole.x + slicing.slice * slicing.slice_keys, whole.y);
  const uint end = min(begin + slicing.slice_keys, whole.y);
  for (uint first = begin; first < end; first += kBatch) {
    const uint count = min(kBatch, end - first);
    if (lane < count) {
      const uint s = values[first + lane];
      const uint word = segments[s];
      const uint p = word >> 2u, flags = word & 3u;
      batch_p0[lane] = points[p];
      batch_p1[lane] = points[p + 1u];
      batch_before[lane] =
          vec4((flags & 1u) != 0u ? points[p - 1u].xyz : points[p].xyz, float(flags));
      batch_after[lane] = vec4((flags & 2u) != 0u ? points[p + 2u].xyz : points[p + 1u].xyz,
                               key_depth(keys[first + lane]));
    }
    barrier();
    if (inside && !done) {
      const vec2 ndc = (vec2(pixel) + 0.5) / vec2(frame.size.xy) * 2.0 - 1.0;
      const vec3 direction =
          normalize(frame.forward.xyz + ndc.x * frame.right.xyz - ndc.y * frame.up.xyz);
      for (uint i = 0u; i < count && !done; ++i) {
        flush(batch_after[i].w);
        if (done) break;
        CapsuleSegment c;
        c.p0 = batch_p0[i].xyz;
        c.p1 = batch_p1[i].xyz;
        c.before = batch_before[i].xyz;
        c.after = batch_after[i].xyz;
        c.flags = uint(batch_before[i].w);
        c.radius = frame.params.y;
        float t[4], u[4];
        vec3 n[4];
        // From the ray's point nearest the segment's start: in float32 the quadratics lose the
        // radius against the squared distance from a far eye.
        const float t0 = dot(c.p0 - frame.eye.xyz, direction);
        const int crossings =
            capsule_crossings(c, frame.eye.xyz + t0 * direction, direction, t, n, u);
        for (int k = 0; k < crossings; ++k) {
          t[k] += t0;
          if (t[k] <= 0.0 || dot(n[k], direction) >= 0.0) continue;  // front crossings ahead
          const float value = batch_p0[i].w + u[k] * (batch_p1[i].w - batch_p0[i].w);
          const vec4 base = transfer_function(value);
          const vec3 x = frame.eye.xyz + t[k] * direction;
          insert(t[k], vec4(shade(x, n[k], base.rgb), base.a));
        }
      }
    }
    barrier();
  }
  if (!inside) return;
  if (slicing.last == 0u) {
    PixelState s;
    s.colour_alpha = vec4(colour, alpha);
    s.hits = hit_count;
    s.pending = uint(pending);
    s.done = done ? 1u : 0u;
    s.pad = 0u;
    for (int k = 0; k < kWindow; ++k) s.t[k] = window_t[k], s.colour[k] = window_colour[k];
    states[index] = s;
    return;
  }
  flush(3.0e38);
  colour += (1.0 - alpha) * frame.background.rgb;
  pixels[index] = vec4(colour, alpha);
  hit_counts[index] = hit_count;
}
