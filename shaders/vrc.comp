#version 460
// Voxel ray casting (VRC, techniques.md section 8) with Vulkan compute, one invocation per pixel:
// the same traversal as lib/render/voxel_ray_caster.cpp in float32. The ray walks the grid with a
// 3D DDA, jumping over cells that are empty at any occupancy mip level; in each voxel the chords
// of its 3x3x3 neighbourhood are decoded (as unpack_chord() in lib/voxels/voxel_grid.cpp) and
// intersected as capsules; hits inside the voxel are sorted, a repeated line id (mod 32) is
// skipped, and the rest are composited front to back.
// The capsule tests run in grid units about the voxel walked (the eye's place in the grid comes
// from the host in double), so the result does not depend on the data's scale or its distance
// from the origin: in world units a voxel of 1e-6 squared its terms to nothing in float32.
// lavapipe ends an invocation's loops once they have run 65535 times together (gallivm's
// limiter), dropping work silently: a walk there can be cut into slices of at most
// slicing.x steps, one dispatch each, the pixel's state kept in between; a loop that must run
// slicing.z times at the end tells the host when the limit cut one short (VoxelCaster).

layout(local_size_x = 8, local_size_y = 8) in;

const int kMaxTfPoints = 32;
const int kMaxLevels = 16;
const int kMaxVoxelHits = 16;  // hits kept per voxel (nearest first)

layout(set = 0, binding = 0, std140) uniform VrcUniforms {
  vec4 eye;          // xyz
  vec4 forward;      // xyz, unit
  vec4 right;        // xyz, scaled by tan(fov/2) x aspect
  vec4 up;           // xyz, scaled by tan(fov/2)
  vec4 shading;      // ambient, diffuse, specular, shininess
  vec4 background;   // linear rgb
  vec4 ranges;       // chord attribute decode lo, hi; transfer-function range lo, hi
  uvec4 size;        // width, height, early termination, skip empty space
  uvec4 tf_counts;   // colour points, opacity points, 0, 0
  vec4 params;       // termination alpha, radius, voxel size, 0
  vec4 origin;       // grid origin xyz
  uvec4 grid;        // resolution xyz, quantization
  uvec4 levels;      // occupancy levels; log2 offsets and chords per page (split grids), 0
  vec4 eye_grid;     // (eye - origin) / voxel size, computed in double
  uvec4 slicing;     // steps a dispatch (0: the whole walk), first slice, sentinel, first row
  uvec4 band;        // rows of this dispatch (from slicing.w), 0, 0, 0
  uvec4 level_resolution[kMaxLevels];  // xyz, first word
  vec4 colours[kMaxTfPoints];          // x, sRGB r, g, b
  vec4 opacities[kMaxTfPoints];        // x, opacity
} frame;

#include "shading.glsl"

layout(set = 0, binding = 1, std430) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 2, std430) readonly buffer Chords { uint chords[]; };
layout(set = 0, binding = 3, std430) readonly buffer Occupancy { uint occupancy[]; };
layout(set = 0, binding = 4, std430) writeonly buffer Output { vec4 pixels[]; };
layout(set = 0, binding = 5, std430) writeonly buffer Hits { uint hit_counts[]; };
// A sliced walk's pixels between dispatches, three words each of the band's pixels: colour and
// alpha; t and the voxel; hits and whether the walk is done. Counters first.
layout(set = 0, binding = 6, std430) buffer Slices {
  uint cut_short;   // invocations the loop limit cut short
  uint unfinished;  // walks paused at the end of their slice
  uint spare[2];
  uvec4 state[];
} slices;

// Offsets and chords past one storage buffer (specialisation constant 0): pages of
// 2^levels.y offsets and 2^levels.z chords at bindings 7 and 8, reached by constant index.
layout(constant_id = 0) const bool kPaged = false;
const uint kGridPages = 8u;
layout(set = 0, binding = 7, std430) readonly buffer OffsetPages { uint v[]; } offset_pages[kGridPages];
layout(set = 0, binding = 8, std430) readonly buffer ChordPages { uvec2 v[]; } chord_pages[kGridPages];

#define OFFSET(n) case n: return offset_pages[n].v[j];
uint offset_at(uint i) {
  if (!kPaged) return offsets[i];
  const uint j = i & ((1u << frame.levels.y) - 1u);
  switch (i >> frame.levels.y) {
    OFFSET(0) OFFSET(1) OFFSET(2) OFFSET(3) OFFSET(4) OFFSET(5) OFFSET(6)
    default: return offset_pages[7].v[j];
  }
}
#undef OFFSET

#define CHORD(n) case n: return chord_pages[n].v[j];
uvec2 chord_at(uint c) {
  if (!kPaged) return uvec2(chords[2u * c], chords[2u * c + 1u]);
  const uint j = c & ((1u << frame.levels.z) - 1u);
  switch (c >> frame.levels.z) {
    CHORD(0) CHORD(1) CHORD(2) CHORD(3) CHORD(4) CHORD(5) CHORD(6)
    default: return chord_pages[7].v[j];
  }
}
#undef CHORD

uint voxel_index(ivec3 v) {
  return (uint(v.z) * frame.grid.y + uint(v.y)) * frame.grid.x + uint(v.x);
}

bool occupied(int level, ivec3 v) {
  const uvec4 r = frame.level_resolution[level];
  const ivec3 c = v >> level;
  const uint bit = (uint(c.z) * r.y + uint(c.y)) * r.x + uint(c.x);
  return ((occupancy[r.w + bit / 32u] >> (bit % 32u)) & 1u) != 0u;
}

// One chord end in voxel-local coordinates, decoded at cell centres.
vec3 decode_end(uint face, uint u, uint v, uint w) {
  const float inv_q = 1.0 / float(frame.grid.w);
  if (face == 6u)
    return vec3((float(u) + 0.5) * inv_q, (float(v) + 0.5) * inv_q,
                (float(w) + 0.5) / float(min(frame.grid.w, 32u)));
  const uint axis = face / 2u;
  vec3 p;
  p[axis] = float(face & 1u);
  p[axis == 0u ? 1u : 0u] = (float(u) + 0.5) * inv_q;
  p[axis == 2u ? 1u : 2u] = (float(v) + 0.5) * inv_q;
  return p;
}

// The capsule's entering distance along the unit ray, or -1.
float intersect_capsule(vec3 ro, vec3 rd, vec3 a, vec3 b, float r) {
  const vec3 ba = b - a, oa = ro - a;
  const float baba = dot(ba, ba);
  if (baba > 1e-24) {
    const float bard = dot(ba, rd), baoa = dot(ba, oa);
    const float k2 = baba - bard * bard;
    const float k1 = baba * dot(oa, rd) - baoa * bard;
    const float k0 = baba * dot(oa, oa) - baoa * baoa - r * r * baba;
    if (k2 > 0.0) {
      const float h = k1 * k1 - k2 * k0;
      if (h < 0.0) return -1.0;
      const float t = (-k1 - sqrt(h)) / k2;
      const float y = baoa + t * bard;
      if (y > 0.0 && y < baba) return t;
      const vec3 oc = y <= 0.0 ? oa : ro - b;
      const float sb = dot(rd, oc), sc = dot(oc, oc) - r * r;
      const float sh = sb * sb - sc;
      return sh > 0.0 ? -sb - sqrt(sh) : -1.0;
    }
  }
  const vec3 oc = dot(rd, ba) > 0.0 ? oa : ro - b;
  const float sb = dot(rd, oc), sc = dot(oc, oc) - r * r;
  const float sh = sb * sb - sc;
  return sh > 0.0 ? -sb - sqrt(sh) : -1.0;
}

float hit_t[kMaxVoxelHits];
uint hit_line[kMaxVoxelHits];
vec3 hit_normal[kMaxVoxelHits];
float hit_value[kMaxVoxelHits];
int hit_count;

// Keeps the nearest kMaxVoxelHits hits, sorted by (t, line id).
void add_hit(float t, uint line, vec3 normal, float value) {
  int i = hit_count < kMaxVoxelHits ? hit_count : kMaxVoxelHits - 1;
  if (hit_count == kMaxVoxelHits && !(t < hit_t[i])) return;
  while (i > 0 && (hit_t[i - 1] > t || (hit_t[i - 1] == t && hit_line[i - 1] > line))) {
    hit_t[i] = hit_t[i - 1];
    hit_line[i] = hit_line[i - 1];
    hit_normal[i] = hit_normal[i - 1];
    hit_value[i] = hit_value[i - 1];
    --i;
  }
  hit_t[i] = t;
  hit_line[i] = line;
  hit_normal[i] = normal;
  hit_value[i] = value;
  if (hit_count < kMaxVoxelHits) ++hit_count;
}

// Hits in voxel v's neighbourhood between t_enter and t_exit (world distances along the unit
// ray), found in grid units about v: the ray from its entry point `local` (grid units from v's
// corner), chord ends at their cells' offsets from v, the radius in voxels; a distance found in
// voxels is size times as long in the world.
void voxel_hits(ivec3 v, vec3 local, vec3 dir, float t_enter, float t_exit) {
  hit_count = 0;
  const ivec3 res = ivec3(frame.grid.xyz);
  const uint q = frame.grid.w;
  const uint bits = uint(findLSB(q)), mask = q - 1u;
  const float size = frame.params.z, radius = frame.params.y / frame.params.z;
  const float lo = frame.ranges.x, span = frame.ranges.y - frame.ranges.x;
  for (int z = max(v.z - 1, 0); z <= min(v.z + 1, res.z - 1); ++z)
    for (int y = max(v.y - 1, 0); y <= min(v.y + 1, res.y - 1); ++y)
      for (int x = max(v.x - 1, 0); x <= min(v.x + 1, res.x - 1); ++x) {
        const uint i = voxel_index(ivec3(x, y, z));
        const vec3 corner = vec3(ivec3(x, y, z) - v);
        const uint end = offset_at(i + 1u);
        for (uint c = offset_at(i); c < end; ++c) {
          const uvec2 chord = chord_at(c);
          const uint w0 = chord.x, w1 = chord.y;
          const vec3 a = corner + decode_end(w0 & 7u, (w0 >> 6u) & mask,
                                             (w0 >> (6u + bits)) & mask, (w1 >> 21u) & 31u);
          const vec3 b = corner + decode_end((w0 >> 3u) & 7u, (w0 >> (6u + 2u * bits)) & mask,
                                             (w0 >> (6u + 3u * bits)) & mask, (w1 >> 26u) & 31u);
          const float entering = intersect_capsule(local, dir, a, b, radius);
          const float t = t_enter + entering * size;
          if (!(entering >= 0.0 && t < t_exit)) continue;
          const vec3 p = local + entering * dir, ab = b - a;
          const float len2 = dot(ab, ab);
          const float s = len2 > 0.0 ? clamp(dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
          const vec3 n = p - (a + s * ab);
          const float va = lo + float((w1 >> 5u) & 255u) / 255.0 * span;
          const float vb = lo + float((w1 >> 13u) & 255u) / 255.0 * span;
          add_hit(t, w1 & 31u, length(n) > 0.0 ? normalize(n) : -dir, va + s * (vb - va));
        }
      }
}

// Distance at which the ray leaves the cell [lo, lo + size) and the axis it leaves through.
float cell_exit(vec3 g0, vec3 gd, ivec3 lo, int size, out int axis) {
  float t = 3.0e38;
  axis = 0;
  for (int k = 0; k < 3; ++k) {
    if (gd[k] == 0.0) continue;
    const float face = float(gd[k] > 0.0 ? lo[k] + size : lo[k]);
    const float tk = (face - g0[k]) / gd[k];
    if (tk < t) {
      t = tk;
      axis = k;
    }
  }
  return t;
}

void main() {
  const uvec2 pixel = uvec2(gl_GlobalInvocationID.x, gl_GlobalInvocationID.y + frame.slicing.w);
  // The last workgroup row of a band reaches past it: those rows are the next band's.
  if (pixel.x >= frame.size.x || pixel.y >= frame.size.y || gl_GlobalInvocationID.y >= frame.band.x)
    return;
  const uint index = pixel.y * frame.size.x + pixel.x;
  const uint slot = 3u * (gl_GlobalInvocationID.y * frame.size.x + pixel.x);
  const uint slice_steps = frame.slicing.x;
  const bool sliced = slice_steps != 0u, resumed = sliced && frame.slicing.y == 0u;
  uvec4 kept[3];
  if (resumed) {
    for (uint k = 0u; k < 3u; ++k) kept[k] = slices.state[slot + k];
    if (kept[2].y != 0u) return;  // its walk ended in an earlier slice
  }
  const float sx = 2.0 * (float(pixel.x) + 0.5) / float(frame.size.x) - 1.0;
  const float sy = 1.0 - 2.0 * (float(pixel.y) + 0.5) / float(frame.size.y);
  const vec3 dir = normalize(frame.forward.xyz + sx * frame.right.xyz + sy * frame.up.xyz);
  const ivec3 res = ivec3(frame.grid.xyz);
  const bool early = frame.size.z != 0u, skip = frame.size.w != 0u;
  const float termination = frame.params.x;
  vec3 colour = vec3(0.0);
  float alpha = 0.0;
  uint hits = 0u;
  const vec3 g0 = frame.eye_grid.xyz, gd = dir / frame.params.z;
  float t0 = 0.0, t1 = 3.0e38;
  bool inside = true;
  for (int k = 0; k < 3; ++k) {
    if (gd[k] == 0.0) {
      inside = inside && g0[k] >= 0.0 && g0[k] <= float(res[k]);
      continue;
    }
    float ta = -g0[k] / gd[k], tb = (float(res[k]) - g0[k]) / gd[k];
    if (ta > tb) {
      const float swap = ta;
      ta = tb;
      tb = swap;
    }
    t0 = max(t0, ta);
    t1 = min(t1, tb);
  }
  bool paused = false;
  if (inside && t0 < t1) {
    ivec3 v = clamp(ivec3(floor(g0 + t0 * gd)), ivec3(0), res - 1);
    const ivec3 step = ivec3(gd.x > 0.0 ? 1 : -1, gd.y > 0.0 ? 1 : -1, gd.z > 0.0 ? 1 : -1);
    float t_enter = t0;
    if (resumed) {
      colour = uintBitsToFloat(kept[0].xyz);
      alpha = uintBitsToFloat(kept[0].w);
      t_enter = uintBitsToFloat(kept[1].x);
      v = ivec3(kept[1].yzw);
      hits = kept[2].x;
    }
    uint steps = 0u;
    while (t_enter < t1) {
      if (sliced && steps == slice_steps) {
        paused = true;
        slices.state[slot] = uvec4(floatBitsToUint(colour), floatBitsToUint(alpha));
        slices.state[slot + 1u] = uvec4(floatBitsToUint(t_enter), uvec3(v));
        slices.state[slot + 2u] = uvec4(hits, 0u, 0u, 0u);
        break;
      }
      ++steps;
      int empty = -1;
      if (skip)
        for (int k = int(frame.levels.x) - 1; k >= 0; --k)
          if (!occupied(k, v)) {
            empty = k;
            break;
          }
      if (empty >= 0) {
        const int size = 1 << empty;
        const ivec3 lo = (v >> empty) << empty;
        int axis;
        // A ray along a cell's face can leave it where it entered: it still steps out of the
        // cell (it had ended there, dropping every hit behind).
        const float t_exit = max(cell_exit(g0, gd, lo, size, axis), t_enter);
        t_enter = t_exit;
        for (int k = 0; k < 3; ++k)
          v[k] = k == axis ? (step[k] > 0 ? lo[k] + size : lo[k] - 1)
                           : clamp(int(floor(g0[k] + t_exit * gd[k])), lo[k], lo[k] + size - 1);
        if (v[axis] < 0 || v[axis] >= res[axis]) break;
        continue;
      }
      int axis;
      const float t_exit = min(cell_exit(g0, gd, v, 1, axis), t1);
      voxel_hits(v, g0 + t_enter * gd - vec3(v), dir, t_enter, t_exit);
      for (int h = 0; h < hit_count; ++h) {
        bool repeated = false;
        for (int k = 0; k < h; ++k) repeated = repeated || hit_line[k] == hit_line[h];
        if (repeated) continue;
        if (early && alpha >= termination) break;
        const vec4 c = transfer_function(hit_value[h]);
        colour += (1.0 - alpha) * c.a * shade_towards(-dir, hit_normal[h], c.rgb);
        alpha += (1.0 - alpha) * c.a;
        ++hits;
      }
      if (early && alpha >= termination) break;
      t_enter = t_exit;
      v[axis] += step[axis];
      if (v[axis] < 0 || v[axis] >= res[axis]) break;
    }
  }
  // gallivm's limiter, where it cut this invocation short, leaves this loop short too. It holds
  // while the compiler keeps the loop a loop (Mesa 22.3 does: the trip count is a uniform, not a
  // constant); one that folds it into trips = slicing.z would hide a cut.
  uint trips = 0u;
  for (uint k = 0u; k < frame.slicing.z; ++k) ++trips;
  if (trips != frame.slicing.z) atomicAdd(slices.cut_short, 1u);
  if (paused) {
    atomicAdd(slices.unfinished, 1u);
    return;
  }
  if (sliced) slices.state[slot + 2u] = uvec4(hits, 1u, 0u, 0u);
  pixels[index] = vec4(colour + (1.0 - alpha) * frame.background.rgb, alpha);
  hit_counts[index] = hits;
}
