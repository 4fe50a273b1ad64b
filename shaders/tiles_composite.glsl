// tiles, pass 3, shared by the primitives' composite passes (tiles_composite.comp for capsules,
// tiles_composite_triangles.comp): one workgroup per 16x16 tile walks the tile's primitives in
// key order, a batch of 256 at a time through shared memory. Each pixel intersects its ray with
// each primitive and keeps its hits in a small window sorted by t. A hit is composited once no
// later primitive can come nearer: every later key's depth bound is past it. Only when the window
// is full is its nearest hit composited early, and that is counted (window_overflows).
//
// A dispatch takes one slice of each tile's keys; the pixels' state (colour, window) carries over
// between slices through a buffer. Devices that cap the loop iterations of an invocation
// (lavapipe: 65535) render in slices; others in one.
//
// The including shader defines, before this file: kBatch, load_primitive(lane, primitive), which puts
// the primitive in its shared batch arrays, and intersect_primitive(i, primitive, direction),
// which calls insert(t, colour, primitive, seam) for each front hit of batch entry i along the pixel's ray from the eye.

layout(local_size_x = 16, local_size_y = 16) in;

const int kWindow = 16;

shared float batch_bound[kBatch];     // the key's depth bound
shared uint batch_primitive[kBatch];  // its primitive
layout(set = 0, binding = 9, std430) buffer Stats { uint window_overflows; } stats;
// This dispatch's slice: keys [slice * slice_keys, (slice + 1) * slice_keys) of each tile's range;
// first: the pixels start empty; last: they are written out.
layout(set = 0, binding = 10, std430) readonly buffer Slice {
  uint slice, slice_keys, first, last;
} slicing;
struct PixelState {
  vec4 colour_alpha;
  uint hits, pending, done, last_primitive;
  float last_t, pad0, pad1, pad2;
  float t[kWindow];
  uint primitive[kWindow];
  vec4 colour[kWindow];
};
layout(set = 0, binding = 11, std430) buffer States { PixelState states[]; };

float window_t[kWindow];
uint window_primitive[kWindow];
vec4 window_colour[kWindow];
// The hit composited last, for seams whose second report comes after it.
float last_t = -1.0;
uint last_primitive = 0xFFFFFFFFu;
int pending = 0;
vec3 colour = vec3(0.0);
float alpha = 0.0;
uint hit_count = 0u;
bool done = false;

void composite(float t, uint primitive, vec4 c) {
  last_t = t;
  last_primitive = primitive;
  colour += (1.0 - alpha) * c.a * c.rgb;
  alpha += (1.0 - alpha) * c.a;
  ++hit_count;
  if (frame.size.z != 0u && alpha >= frame.params.x) done = true;
}

// Composites the pending hits nearer than `bound`, nearest first.
void flush(float bound) {
  int k = 0;
  while (k < pending && window_t[k] < bound && !done) {
    composite(window_t[k], window_primitive[k], window_colour[k]);
    ++k;
  }
  if (done) k = pending;
  for (int j = k; j < pending; ++j) {
    window_t[j - k] = window_t[j];
    window_primitive[j - k] = window_primitive[j];
    window_colour[j - k] = window_colour[j];
  }
  pending -= k;
}

// Whether a hit of `primitive` at t is the second report of a seam: a hit of the primitive
// before or after it (the neighbour in its line) within `seam` of t. Float error lets both sides
// of a joint keep a crossing there (capsule.glsl keeps a doubtful one rather than lose it); the
// CPU tracer removes such doubles the same way (lib/render/ray_tracer.cpp, resolve()).
bool seam_double(float t, uint primitive, float seam) {
  const bool last = abs(last_t - t) <= seam &&
                    (last_primitive + 1u == primitive || primitive + 1u == last_primitive);
  if (seam <= 0.0 || last) return last && seam > 0.0;
  for (int j = 0; j < pending; ++j)
    if (abs(window_t[j] - t) <= seam &&
        (window_primitive[j] + 1u == primitive || primitive + 1u == window_primitive[j]))
      return true;
  return false;
}

// Adds a hit to the window, nearest first; `seam` > 0 drops a neighbour's double (above).
void insert(float t, vec4 c, uint primitive, float seam) {
  if (seam_double(t, primitive, seam)) return;
  if (pending == kWindow) {
    // Full: the nearest goes now (exact unless a later segment comes nearer still).
    atomicAdd(stats.window_overflows, 1u);
    composite(window_t[0], window_primitive[0], window_colour[0]);
    for (int j = 1; j < pending; ++j) {
      window_t[j - 1] = window_t[j];
      window_primitive[j - 1] = window_primitive[j];
      window_colour[j - 1] = window_colour[j];
    }
    --pending;
  }
  int at = pending;
  while (at > 0 && window_t[at - 1] > t) {
    window_t[at] = window_t[at - 1];
    window_primitive[at] = window_primitive[at - 1];
    window_colour[at] = window_colour[at - 1];
    --at;
  }
  window_t[at] = t;
  window_primitive[at] = primitive;
  window_colour[at] = c;
  ++pending;
}

void main() {
  // The dispatch covers the band's tile rows.
  const uvec2 pixel = gl_GlobalInvocationID.xy + uvec2(0u, frame.band.x * kTile);
  const uint tile = (gl_WorkGroupID.y + frame.band.x) * frame.tiles.x + gl_WorkGroupID.x;
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
    last_t = s.last_t;
    last_primitive = s.last_primitive;
    for (int k = 0; k < kWindow; ++k)
      window_t[k] = s.t[k], window_primitive[k] = s.primitive[k], window_colour[k] = s.colour[k];
  }
  const uvec2 whole = ranges[tile];
  const uint begin = min(whole.x + slicing.slice * slicing.slice_keys, whole.y);
  const uint end = min(begin + slicing.slice_keys, whole.y);
  for (uint first = begin; first < end; first += kBatch) {
    const uint count = min(kBatch, end - first);
    if (lane < count) {
      batch_primitive[lane] = values[first + lane];
      load_primitive(lane, batch_primitive[lane]);
      batch_bound[lane] = key_depth(keys[first + lane]);
    }
    barrier();
    if (inside && !done) {
      const vec2 ndc = (vec2(pixel) + 0.5) / vec2(frame.size.xy) * 2.0 - 1.0;
      const vec3 direction =
          normalize(frame.forward.xyz + ndc.x * frame.right.xyz - ndc.y * frame.up.xyz);
      for (uint i = 0u; i < count && !done; ++i) {
        flush(batch_bound[i]);
        if (done) break;
        intersect_primitive(i, batch_primitive[i], direction);
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
    s.last_primitive = last_primitive;
    s.last_t = last_t;
    s.pad0 = s.pad1 = s.pad2 = 0.0;
    for (int k = 0; k < kWindow; ++k)
      s.t[k] = window_t[k], s.primitive[k] = window_primitive[k], s.colour[k] = window_colour[k];
    states[index] = s;
    return;
  }
  flush(3.0e38);
  colour += (1.0 - alpha) * frame.background.rgb;
  pixels[index] = vec4(colour, alpha);
  hit_counts[index] = hit_count;
}
