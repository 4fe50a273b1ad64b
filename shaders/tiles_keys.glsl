// Binning's last step, shared by the primitives' binning passes: the keys of primitive `s`, whose
// screen bounds are [lo, hi] pixels and whose nearest view depth is z_near, one per covered tile
// of this pass's band of tile rows: the tile in the high bits, the quantised depth in the low.
void emit_keys(uint s, vec2 lo, vec2 hi, float z_near) {
  if (hi.x < 0.0 || hi.y < 0.0 || lo.x >= float(frame.size.x) || lo.y >= float(frame.size.y))
    return;
  const ivec2 tiles = ivec2(frame.tiles.xy);
  const ivec2 t0 = clamp(ivec2(floor(lo / float(kTile))), ivec2(0), tiles - 1);
  const ivec2 t1 = clamp(ivec2(floor(hi / float(kTile))), ivec2(0), tiles - 1);
  const uint bits = frame.tiles.z;
  const float span = frame.params.w - frame.params.z;
  const float level =
      clamp((max(z_near, frame.params.z) - frame.params.z) / span, 0.0, 1.0) *
      float((1u << bits) - 1u);
  const uint depth = min(uint(floor(level)), (1u << bits) - 1u);
  // This pass's band of tile rows only; the keys of every row are counted.
  const int row0 = max(t0.y, int(frame.band.x)), row1 = min(t1.y, int(frame.band.y) - 1);
  if (row0 > row1) return;
  for (int ty = row0; ty <= row1; ++ty) atomicAdd(row_keys[ty], uint(t1.x - t0.x + 1));
  const uint n = uint((t1.x - t0.x + 1) * (row1 - row0 + 1));
  // The count saturates instead of wrapping past 2^32 - 1 (the host refuses such a frame).
  const uint base = atomicAdd(counters.key_count, n);
  if (base > 0xFFFFFFFFu - n) atomicMax(counters.key_count, 0xFFFFFFFFu);
  atomicAdd(counters.binned, 1u);
  if (base > frame.tiles.w || n > frame.tiles.w - base) return;  // no room: binned again
  uint at = base;
  for (int ty = row0; ty <= row1; ++ty)
    for (int tx = t0.x; tx <= t1.x; ++tx) {
      const uint tile = uint(ty) * frame.tiles.x + uint(tx);
      keys[at] = (tile << bits) | depth;
      values[at] = s;
      ++at;
    }
}
