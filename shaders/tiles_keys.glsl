// Binning's last step, shared by the primitives' binning passes: the keys of primitive `s`, whose
// screen bounds are [lo, hi] pixels (covering the pixels of covered_pixels, tiles.glsl) and whose
// nearest view depth is z_near, one per covered tile of this pass's band of tile rows: the tile
// in the high bits, the quantised depth in the low.
// Every invocation of the workgroup calls it (`visible` false: no keys), because the workgroup
// adds its counts up in shared memory and makes one atomic of each kind on the global counters:
// one per primitive had every invocation of the GPU queue on one address (on the H100, 55 ms of
// binning clouds' 39.6 million segments).

shared uint group_keys, group_binned, group_base;
shared bool group_room;
// Keys per tile row of the workgroup's primitives, for images of up to kGroupRows tile rows
// (above that, each primitive adds its own to the global counts).
const uint kGroupRows = 1024;
shared uint group_rows[kGroupRows];

// Binning's pixel tests: primitives whose bounds hold at most this many pixel centres are binned
// only where one of those pixels may hit them (tiles_bin.comp, tiles_bin_triangles.comp). The
// host sets how many at most (frame.binning.x; 0: none tested).
const int kTestedPixels = 4;

// The pixel centres inside bounds [lo, hi] on the screen, from p0 over extent, and how many:
// -1 where the bounds hold more than binning tests (the primitive is binned untested).
int tested_pixels(vec2 lo, vec2 hi, out ivec2 p0, out ivec2 extent) {
  ivec2 p1;
  covered_pixels(lo, hi, p0, p1);
  p0 = max(p0, ivec2(0));
  p1 = min(p1, ivec2(view.size.xy) - 1);
  extent = max(p1 - p0 + 1, ivec2(0));
  const int pixels = extent.x * extent.y;
  return pixels > min(int(frame_tests.binning.x), kTestedPixels) ? -1 : pixels;
}

// Pixel k of bounds of at most 4 pixels from p0 (a column, a row, or 2 x 2; no integer division,
// which lavapipe's SIMD units do a lane at a time).
uvec2 tested_pixel(ivec2 p0, ivec2 extent, int k) {
  const ivec2 step = extent.x == 1   ? ivec2(0, k)
                     : extent.x == 2 ? ivec2(k & 1, k >> 1)
                                     : ivec2(k, 0);
  return uvec2(p0 + step);
}

void emit_keys(uint s, bool visible, vec2 lo, vec2 hi, float z_near) {
  const uint lane = gl_LocalInvocationIndex, lanes = gl_WorkGroupSize.x;
  const bool rows_shared = frame_tests.tiles.y <= kGroupRows;
  if (lane == 0u) group_keys = 0u, group_binned = 0u;
  for (uint r = lane; r < kGroupRows; r += lanes) group_rows[r] = 0u;
  barrier();
  const ivec2 tiles = ivec2(view.tiles.xy);
  ivec2 p0, p1;
  covered_pixels(lo, hi, p0, p1);
  const bool on_screen =
      visible && all(lessThanEqual(max(p0, ivec2(0)), min(p1, ivec2(view.size.xy) - 1)));
  ivec2 t0 = ivec2(0), t1 = ivec2(-1);
  if (on_screen) {
    t0 = clamp(p0 / int(kTile), ivec2(0), tiles - 1);
    t1 = clamp(p1 / int(kTile), ivec2(0), tiles - 1);
  }
  // This pass's band of tile rows only; the keys of every row are counted.
  const int row0 = max(t0.y, int(view.band.x)), row1 = min(t1.y, int(view.band.y) - 1);
  const uint n = on_screen && row0 <= row1 ? uint((t1.x - t0.x + 1) * (row1 - row0 + 1)) : 0u;
  uint local = 0u;
  if (n > 0u) {
    for (int ty = row0; ty <= row1; ++ty) {
      if (rows_shared) atomicAdd(group_rows[ty], uint(t1.x - t0.x + 1));
      else atomicAdd(row_keys[ty], uint(t1.x - t0.x + 1));
    }
    local = atomicAdd(group_keys, n);
    atomicAdd(group_binned, 1u);
  }
  barrier();
  if (lane == 0u) {
    const uint total = group_keys;
    // The count saturates instead of wrapping past 2^32 - 1 (the host refuses such a frame).
    const uint base = total > 0u ? atomicAdd(counters.key_count, total) : 0u;
    if (base > 0xFFFFFFFFu - total) atomicMax(counters.key_count, 0xFFFFFFFFu);
    if (group_binned > 0u) atomicAdd(counters.binned, group_binned);
    group_base = base;
    group_room = base <= view.tiles.w && total <= view.tiles.w - base;
  }
  if (rows_shared)
    for (uint r = lane; r < kGroupRows && r < frame_tests.tiles.y; r += lanes)
      if (group_rows[r] != 0u) atomicAdd(row_keys[r], group_rows[r]);
  barrier();
  // No room for the workgroup's keys: binned again with more.
  if (n == 0u || !group_room) return;
  const float span = view.params.w - view.params.z;
  const uint bits = view.tiles.z;
  const float level =
      clamp((max(z_near, view.params.z) - view.params.z) / span, 0.0, 1.0) *
      float((1u << bits) - 1u);
  const uint depth = min(uint(floor(level)), (1u << bits) - 1u);
  uint at = group_base + local;
  for (int ty = row0; ty <= row1; ++ty)
    for (int tx = t0.x; tx <= t1.x; ++tx) {
      const uint tile = uint(ty) * view.tiles.x + uint(tx);
      keys[at] = (tile << bits) | depth;
      values[at] = s;
      ++at;
    }
}
