// The any-hit side of `--hits filter` for rtx (shaders/rtx.rgen): every hit of a trace is
// offered to a window of the kWindowHits nearest hits after the previous window's last, in
// (t, chunk, primitive) order, then ignored so that traversal goes on. A hit beyond a full
// window is accepted instead, which shrinks the ray's t_max so traversal culls what lies farther.
// The CPU tracer collects hits the same way with Embree's filter (lib/render/ray_tracer.cpp),
// there without a window. Needs `payload` (rayPayloadInEXT Payload) declared before it.

const int kIgnore = 0, kInsert = 1, kAccept = 2;

bool key_less(float ta, uint ca, uint pa, float tb, uint cb, uint pb) {
  if (ta != tb) return ta < tb;
  if (ca != cb) return ca < cb;
  return pa < pb;
}

// What to do with a hit: kIgnore (already in an earlier window, or reported twice), kInsert
// (shade it and call window_insert) or kAccept (beyond the full window).
int window_admit(float t, uint chunk, uint primitive) {
  if (!key_less(payload.after_t, payload.after_chunk, payload.after_primitive, t, chunk,
                primitive))
    return kIgnore;
  const uint n = payload.count;
  if (n == kWindowHits) {
    const uint last = kWindowHits - 1u;
    if (!key_less(t, chunk, primitive, payload.t[last], payload.chunk[last] & ~kBackHit,
                  payload.primitive[last])) {
      payload.overflow = 1u;
      // Equal distances stay reportable: only a strictly farther hit may cut t_max.
      return t > payload.t[last] ? kAccept : kIgnore;
    }
  }
  // Traversal may report one hit more than once (no NO_DUPLICATE_ANY_HIT flag on the BLAS).
  for (uint k = 0u; k < n; ++k)
    if (payload.primitive[k] == primitive && (payload.chunk[k] & ~kBackHit) == chunk &&
        abs(payload.t[k] - t) <= 1e-6 * max(1.0, t))
      return kIgnore;
  return kInsert;
}

// Inserts in order; a full window drops its last hit and records the overflow.
void window_insert(float t, uint chunk_flags, uint primitive, vec4 colour) {
  uint k = payload.count;
  if (k == kWindowHits) {
    payload.overflow = 1u;
    --k;
  } else {
    payload.count = k + 1u;
  }
  const uint chunk = chunk_flags & ~kBackHit;
  while (k > 0u && key_less(t, chunk, primitive, payload.t[k - 1u],
                            payload.chunk[k - 1u] & ~kBackHit, payload.primitive[k - 1u])) {
    payload.t[k] = payload.t[k - 1u];
    payload.chunk[k] = payload.chunk[k - 1u];
    payload.primitive[k] = payload.primitive[k - 1u];
    payload.colour[k] = payload.colour[k - 1u];
    --k;
  }
  payload.t[k] = t;
  payload.chunk[k] = chunk_flags;
  payload.primitive[k] = primitive;
  payload.colour[k] = colour;
}
