// tiles, pass 3, shared by the primitives' composite passes (tiles_composite.comp for capsules,
// tiles_composite_triangles.comp): one workgroup per 16x16 tile (or four, one per strip of 16x4
// pixels: TILES_STRIPS below) walks the tile's primitives in key order, a batch of 256 at a time
// through shared memory. Each pixel intersects its ray with
// the primitives whose screen bounds cover its block of 4x2 pixels and keeps its hits in a small
// window sorted by (t, primitive). A hit is composited once no later primitive can come nearer:
// every later key's depth bound is past it. When the window is full the farther of its last hit
// and the new one is left for another walk: from then on the pixel keeps only hits before it
// (the floor), so what it composites stays exact, and after the tile's last key the tile is
// walked again (binding 14) for the hits from there on, past those composited (k-buffer
// peeling, as rtx's windows do; counted in window_overflows).
//
// A dispatch takes one slice of the keys of the tiles that have keys in it (the first slice: of
// every tile); the pixels' state (colour, window) carries over between slices through a buffer,
// and a tile's pixels are written out by its last slice. Devices that cap the loop iterations
// of an invocation (lavapipe: 65535) render in slices; others in one.
//
// Per batch a pixel first finds the entries its ray may hit (may_cross, cheap), and the
// workgroup then computes those (pixel, entry) pairs' exact hits with every invocation on a pair
// of any pixel, up to kSlots pairs a round (no more than it has invocations): each SIMD unit
// computes the hits of full rows of pairs, where the pixels' own walks left most of its lanes
// idle (on lavapipe, whose 8-lane units run every statement for all lanes, 35 % of the lanes of
// an aneurysm frame's tests had a pair). Each pixel then takes its hits, in key order, into its
// window.
//
// The including shader defines, before this file: kBatch and kSlots (at most 256);
// load_primitive(lane, primitive, bound, far), which puts the primitive, its key's depth bound
// and its farthest view depth in its shared batch arrays; screen_bounds (as for binning);
// kNearWords and near_words(i, words), the words of batch entry i that may_cross reads, the
// depth bound in word 0's w and the farthest depth in word 1's, and depth_bound(i) alone (what
// a block reads per entry it walks is then two or three vec4 loads: on lavapipe each shared
// load whose index differs between invocations is a loop over the 8 lanes of a SIMD unit, and
// the near test's five loads were 35 % of the aneurysm's composite instructions;
// docs/tiles.md, "Per-lane shared loads on lavapipe"); may_cross(words, direction), a test
// that keeps every batch entry the ray from the eye along `direction` may hit; first_hit(i,
// direction, t, colour), the nearest front hit and its shaded colour (false: none; no colour
// with TILES_LATE_SHADING); seam_of(i, direction), how near two hits of neighbouring primitives
// are one seam's (seam_twins below; 0: never); and hit_colour(primitive, t, direction, colour),
// the shaded colour of the hit at t that first_hit finds, from the primitive buffers (for
// TILES_LATE_SHADING; false: its test missed it there).

// Compiled with TILES_PIXEL_HITS (TileOptions::pixel_hits), each pixel computes its own pairs'
// hits instead, as the composite did before the rounds (3120a50): lavapipe's composite is
// faster with the rounds, and on NVIDIA's H200 the capsules' frames took 42 to 49 % longer on
// the aneurysm and convection than the H100's of 3120a50 (docs/tiles.md, "Measured on an NVIDIA
// H200"): bench render's tiles-pixel-hits is the A/B a GPU decides. The same bytes.
//
// Compiled with TILES_LATE_SHADING (TileOptions::late_shading), the window holds each pending
// hit's t and primitive only, not its colour: first_hit computes no colour, and a hit is shaded
// when it is composited, its primitive read again from the primitive buffers and tested again
// (hit_colour). A composited hit costs two tests instead of one, and its shading moves from the
// rounds to the pixel's own lane; the window holds 2 words a hit instead of 6 (the state between
// walks keeps its colour slots, unread), and the batch keeps no attributes or normals in shared
// memory. For GPUs, where the window in registers bounds how many workgroups run at once
// (docs/tiles.md, "Shading late"): bench render's tiles-late-shading is the A/B. The same bytes:
// the same test on the same floats gives the same hit (a test that misses it the second time is
// counted in late_misses: the stats of the late builds hold it to 0).
//
// Compiled with TILES_STRIPS (a choice of the host's, TileOptions::strips), a tile's pixels
// are composited by four workgroups, each of a strip of 16x4 pixels, walking all of the tile's
// keys: a crowded tile is shared by four workgroups, and a workgroup waiting at a barrier holds
// a quarter of the invocations. Where a pixel takes 240 registers (docs/tiles.md, "Registers:
// what the GPU compilers make of the composite"), a GPU core (an AMD CU; an H100 SM, if NVIDIA's
// compiler needs as many) runs one 256-invocation workgroup, which a barrier leaves idle; it
// runs four of 64. Each key's screen bounds are computed four times instead of once. The same
// pixels, the same hits in the same order: the same bytes.
#ifdef TILES_STRIPS
const uint kStrips = 4;
#else
const uint kStrips = 1;
#endif
const uint kLanes = kTile * kTile / kStrips;  // a workgroup's invocations, one per pixel
layout(local_size_x = kLanes) in;

// The pixels' states between slices and walks hold kStateWindow pending hits: 16 where the
// window's loops exit past the pending hits (GPUs), 8 where they run every trip (lavapipe, where
// a hit costs the whole window; with walks again cheap there, paper-small's composite at
// 640x360 took 5 to 27 % less time with 8 than with 16 on the four sets, and 4 was slower again
// on the aneurysm, whose walks went up to 25 a tile). A walk again runs the build with
// TILES_DEEP_WINDOW (GPUs, one slice per tile: a walk then ends with no hit pending), whose
// window holds 64: the pixels that fill 16 are those behind hundreds of primitives, and each walk
// again costs a pass over their tile's keys (on the H100 a third of the 1080p aneurysm's
// composite, 7 walks, with 16 in every walk).
#ifdef TILES_WINDOW_EXITS
const int kStateWindow = 16;
#else
const int kStateWindow = 8;
#endif
#ifdef TILES_DEEP_WINDOW
const int kWindow = 64;
#else
const int kWindow = kStateWindow;
#endif

shared uint batch_primitive[kBatch];  // its primitive

// Pixels go to invocations in blocks of 4x2, eight consecutive invocations per block, so the
// invocations one SIMD unit runs together (lavapipe: 8 along x) share a block. Per block, a bit
// per batch entry whose screen bounds cover it: a block walks only those, in key order, so a
// small capsule costs the pixels near it instead of the whole tile's 256 (on lavapipe, where a
// SIMD unit runs both sides of a branch, a skip inside the loop would save nothing).
const uint kBlocks = kLanes / 8u;  // a workgroup's
shared uint block_entries[kBlocks][kBatch / 32u];

// Batch entries as bits, entry 32 w + b in bit b of word w, in key order.
const uint kWords = kBatch / 32u;

// The first entry of `words` (kBatch: none). The words are indexed by constants only, so that
// they stay in registers; a loop over the entries with this runs once per entry, where a loop
// per word with one inside over its bits ran at least once per word: lavapipe runs the body of
// every loop it enters at least once, with its lanes masked off when none has work (the near
// test's two shared loads cost that much for each of a batch's 8 words, empty or not).
uint first_entry(uint words[kWords]) {
  uint w = kWords, word = 0u;
  for (int k = int(kWords) - 1; k >= 0; --k)
    if (words[k] != 0u) w = uint(k), word = words[k];
  return w < kWords ? w * 32u + uint(findLSB(word)) : kBatch;
}

// Sets (on) or clears entry `entry`'s bit in `words`.
void set_entry(inout uint words[kWords], uint entry, bool on) {
  const uint bit = 1u << (entry % 32u);
  for (uint k = 0u; k < kWords; ++k)
    if (k == entry / 32u) words[k] = on ? words[k] | bit : words[k] & ~bit;
}

// Whether a pixel of the workgroup may still take a hit after a batch, by the batch's parity (a
// flag every such pixel stores): none, and the walk stops early (every pixel opaque enough, written
// out, or past its floor).
shared uint busy[2];
// The depth bound of the first key after the batch (+inf: none in this slice), read once.
shared float next_bound;
// The batch's farthest view depth (float bits, at least 0), for chunk_far.
shared uint batch_far;
// A round's pairs: slot_pair holds the pixel's lane | the entry << 8 | the pair's place among
// the pixel's pairs of the round << 16; a hit's colour, and in slot_hit the bits of its t, of
// its entry's depth bound along the pixel's ray and of its seam distance, and its primitive:
// what the pixel takes it into its window with, in two loads (see kNearWords). round_hits: per
// pixel, a bit per pair of the round with a hit. Claimed slots, and whether a pixel has pairs
// left, by the round's parity.
// A round computes a pair an invocation at most.
const uint kRoundSlots = min(kSlots, kLanes);
shared uint slot_pair[kRoundSlots];
shared uvec4 slot_hit[kRoundSlots];
#ifndef TILES_LATE_SHADING
shared vec4 slot_colour[kRoundSlots];
#endif
shared uint round_hits[kLanes];
shared uint round_claimed[2], round_more[2];
// A pixel's pairs in one round: one bit each in round_hits.
const uint kPairsPerRound = 32;

// The pixel of the tile's `lane`th (in the tile's blocks of 4x2, four blocks a row; a strip is
// eight consecutive blocks).
uvec2 pixel_in_tile(uint lane) {
  const uint block = lane / 8u, k = lane % 8u;
  return uvec2((block % 4u) * 4u + k % 4u, (block / 4u) * 2u + k / 4u);
}

// Marks batch entry `entry` in the blocks whose pixels its screen bounds [lo, hi] cover
// (covered_pixels, as binning's tiles) in the workgroup's pixels, kTile wide, whose first pixel
// is `origin`. Bounds it cannot use cover them all. Whether it marked any.
bool mark_blocks(uint entry, bool bounded, vec2 lo, vec2 hi, ivec2 origin) {
  ivec2 p0 = ivec2(0), p1 = ivec2(int(kTile) - 1, int(kLanes / kTile) - 1);
  if (bounded) {
    ivec2 q0, q1;
    covered_pixels(lo, hi, q0, q1);
    p0 = max(q0 - origin, p0);
    p1 = min(q1 - origin, p1);
    if (p0.x > p1.x || p0.y > p1.y) return false;
  }
  for (int by = p0.y / 2; by <= p1.y / 2; ++by)
    for (int bx = p0.x / 4; bx <= p1.x / 4; ++bx)
      atomicOr(block_entries[by * 4 + bx][entry / 32u], 1u << (entry % 32u));
  return true;
}

layout(set = 0, binding = 9, std430) buffer Stats {
  uint window_overflows, cut_short, late_misses;
} stats;
// This dispatch's slice: keys [slice * slice_keys, (slice + 1) * slice_keys) of each tile's range,
// for the tiles slice_tiles[tile_offset, tile_offset + tile_count). `walk` > 0: a walk again
// over tiles whose pixels left hits for it (their state carries over). The first `strip_tiles`
// of them are the strips build's, four workgroups each; the others, the build of whole tiles',
// one workgroup each (two dispatches of one slice, which may run at once).
layout(set = 0, binding = 10, std430) readonly buffer Slice {
  uint slice, slice_keys, tile_offset, tile_count, sentinel, walk, strip_tiles;
} slicing;
layout(set = 0, binding = 13, std430) readonly buffer SliceTiles { uint slice_tiles[]; };
const uint kDone = 1u, kWritten = 2u;  // PixelState.flags: opaque enough; pixel written out
// The hits passed last that a pixel remembers (below).
const int kPassed = 4;
struct PixelState {
  vec4 colour_alpha;
  uint hits, pending, flags, last_primitive;
  float last_t, floor_t, after_t;
  uint floor_primitive;
  uint after_primitive;
  float passed_t[kPassed - 1];
  uint passed_primitive[kPassed - 1], pad0;
  float t[kStateWindow];
  uint primitive[kStateWindow];
#ifndef TILES_LATE_SHADING
  vec4 colour[kStateWindow];  // the builds that shade late keep none (the host sizes both)
#endif
};
// The pixels' states, kTile * kTile per tile slot: as many tiles as one storage buffer holds
// are composited at a time (the host's groups), each group's tiles in slots 0, 1, ...
layout(set = 0, binding = 11, std430) buffer States { PixelState states[]; };
layout(set = 0, binding = 15, std430) readonly buffer TileSlots { uint tile_slots[]; };
// Per tile, where a pixel left hits for another walk: the least view depth its hits may lie at
// (float bits, the minimum over such pixels; 0: any), else all ones (the host's).
layout(set = 0, binding = 14, std430) buffer WalkAgain { uint walk_again[]; };
// Per tile, the farthest view depth of each kBatch keys from its first (+inf: not walked, or a
// primitive with no bounds), in chunk ranges[tile].x / kBatch + tile on: the walks write them,
// and the host starts a walk again at the first chunk that may reach past the tile's depth in
// walk_again, so that it does not pass again the keys its pixels are done with (the host's
// walk_first, the tile's first key in a walk again; slices count from there).
layout(set = 0, binding = 16, std430) buffer ChunkFar { float chunk_far[]; };
layout(set = 0, binding = 17, std430) readonly buffer WalkFirst { uint walk_first[]; };

float window_t[kWindow];
uint window_primitive[kWindow];
#ifndef TILES_LATE_SHADING
vec4 window_colour[kWindow];
#endif
vec3 pixel_direction;  // the pixel's ray, for hit_colour
// The hits passed last (composited, or seam doubles), nearest last, for seams whose second report
// comes after them: last_t and the kPassed - 1 before it. A chain of short segments crossed at
// one point can bring a twin after others of the chain were passed: clouds' frame 5 of 8 at
// 640x360 has a ray through 21 consecutive segments within 1.2e-4, where a twin came after its
// twin and one more hit had been passed.
float last_t = -1.0;
uint last_primitive = 0xFFFFFFFFu;
float passed_t[kPassed - 1];
uint passed_primitive[kPassed - 1];
int pending = 0;
vec3 colour = vec3(0.0);
float alpha = 0.0;
uint hit_count = 0u;
bool done = false;
// Hits at or before `after` were passed by an earlier walk; hits at or past `floor` are left
// for the next (a full window dropped one there). No floor: t = +inf.
float after_t = -1.0, floor_t = 1.0 / 0.0;
uint after_primitive = 0u, floor_primitive = 0xFFFFFFFFu;

// The order of hits: by t, ties by primitive, so that every walk sees the same order.
bool hit_before(float t, uint primitive, float other_t, uint other_primitive) {
  return t < other_t || (t == other_t && primitive < other_primitive);
}

void pass_hit(float t, uint primitive) {
  for (int k = kPassed - 2; k > 0; --k)
    passed_t[k] = passed_t[k - 1], passed_primitive[k] = passed_primitive[k - 1];
  passed_t[0] = last_t, passed_primitive[0] = last_primitive;
  last_t = t, last_primitive = primitive;
}

void composite(float t, uint primitive, vec4 c) {
  pass_hit(t, primitive);
  colour += (1.0 - alpha) * c.a * c.rgb;
  alpha += (1.0 - alpha) * c.a;
  ++hit_count;
  if (frame_tests.size.z != 0u && alpha >= view.params.x) done = true;
}

// The window is indexed by constants only (loops of kWindow trips, which the compiler unrolls).
// With variable indices the composite on lavapipe ran 22-30 % slower, and a 4-hit window about a
// third faster than a 16-hit one: an access cost about the whole window there (many of Mesa's
// back ends lower a variable index into a private array to an if-else ladder over it).
// Compiled with TILES_WINDOW_EXITS (the pipeline of devices other than lavapipe), the loops
// leave once past the pending hits, so a hit costs the few pending, not the whole window; on
// lavapipe that made the composite 46 % slower (the 1080p aneurysm, 22.1 against 15.1 s), so
// there every loop runs its kWindow trips.
#ifdef TILES_WINDOW_EXITS
const bool kWindowExits = true;
#else
const bool kWindowExits = false;
#endif

// A pending hit's primitive carries kDropped when it is a seam double (insert below): it stays
// in the window, in order, so that the hits after it are judged against it, and is not
// composited. Primitive numbers stay below 2^31: a storage buffer holds fewer segment words or
// triangles.
const uint kDropped = 0x80000000u;

// Drops the nearest pending hit.
void pop_front() {
  for (int j = 0; j + 1 < kWindow; ++j) {
    if (kWindowExits && j + 1 >= pending) break;
    window_t[j] = window_t[j + 1];
    window_primitive[j] = window_primitive[j + 1];
#ifndef TILES_LATE_SHADING
    window_colour[j] = window_colour[j + 1];
#endif
  }
  --pending;
}

// Composites the pending hits nearer than `bound`, nearest first; a seam double only becomes
// the hit passed last.
void flush(float bound) {
  while (pending > 0 && window_t[0] < bound && !done) {
    if ((window_primitive[0] & kDropped) != 0u) {
      pass_hit(window_t[0], window_primitive[0] & ~kDropped);
    } else {
#ifdef TILES_LATE_SHADING
      vec4 c;
      if (!hit_colour(window_primitive[0], window_t[0], pixel_direction, c))
        atomicAdd(stats.late_misses, 1u);
      composite(window_t[0], window_primitive[0], c);
#else
      composite(window_t[0], window_primitive[0], window_colour[0]);
#endif
    }
    pop_front();
  }
  if (done) pending = 0;
}

// Whether two hits are the two reports of one seam: hits of neighbouring primitives (in one
// line) within `seam` of each other. Float error lets both sides of a joint keep a crossing
// there (capsule.glsl keeps a doubtful one rather than lose it). No seam (0): never.
bool seam_twins(float t, uint primitive, float other_t, uint other_primitive, float seam) {
  return seam > 0.0 && abs(other_t - t) <= seam &&
         (other_primitive + 1u == primitive || primitive + 1u == other_primitive);
}

// Adds a hit to the window in (t, primitive) order. A hit with a seam twin (above) before it,
// composited or itself a double, is a seam double: the rule of the CPU tracer
// (lib/render/ray_tracer.cpp, resolve_from()) and rtx, which decide in order. It depends only
// on the hits, not on the order they come in: keys of equal (tile, depth) come in the order
// binning emitted them, which varies between runs on a GPU, and the keys' depth bits change
// which hits are pending together. A twin after the hit, pending, becomes a double; one that
// comes later finds the hit pending or passed last. (Clouds' frame 5 of 8 at 640x360 has a ray
// through four consecutive segments shorter than a hundredth of the radius, all crossed
// within 4e-5; keeping only the nearer of two twins, with the other dropped from the window,
// composited one or two of the four by the order they came in.) Hits an earlier walk passed,
// and hits at or past the floor, are not this walk's.
void insert(float t, vec4 c, uint primitive, float seam) {
  if (!hit_before(after_t, after_primitive, t, primitive) ||
      !hit_before(t, primitive, floor_t, floor_primitive))
    return;
  bool dropped = seam_twins(t, primitive, last_t, last_primitive, seam);
  for (int k = 0; k < kPassed - 1; ++k)
    dropped = dropped || seam_twins(t, primitive, passed_t[k], passed_primitive[k], seam);
  // Its place, after every pending hit before it (the window is sorted), and its twins, in one
  // pass over the window.
  int at = 0;
  for (int j = 0; j < kWindow; ++j) {
    if (j >= pending) {
      if (kWindowExits) break;
      continue;
    }
    const uint other = window_primitive[j] & ~kDropped;
    const bool before = hit_before(window_t[j], other, t, primitive);
    if (before) at = j + 1;
    if (seam_twins(t, primitive, window_t[j], other, seam)) {
      if (before) dropped = true;
      else window_primitive[j] |= kDropped;
    }
  }
  if (pending == kWindow) {
    // Full: the farther of the window's last and this hit becomes the floor and waits for the
    // next walk; every hit before it is still composited in order.
    const int last = kWindow - 1;
    if (at == kWindow) {
      floor_t = t, floor_primitive = primitive;
      return;
    }
    floor_t = window_t[last], floor_primitive = window_primitive[last] & ~kDropped;
    --pending;
  }
  // From `at` on, each slot takes the hit carried from the one before, up to the first free one.
  primitive |= dropped ? kDropped : 0u;
  for (int j = 0; j < kWindow; ++j) {
    if (j > pending) {
      if (kWindowExits) break;
      continue;
    }
    if (j < at) continue;
    const float next_t = window_t[j];
    const uint next_primitive = window_primitive[j];
    window_t[j] = t;
    window_primitive[j] = primitive;
    t = next_t, primitive = next_primitive;
#ifndef TILES_LATE_SHADING
    const vec4 next_colour = window_colour[j];
    window_colour[j] = c;
    c = next_colour;
#endif
  }
  ++pending;
}

// A key's depth bound (a view depth) in the units of t along a pixel's ray (below).
float bound_t(float bound, float t_per_z) { return bound > 0.0 ? bound * t_per_z : bound; }

// A point at view depth z lies at t = z / dot(direction, forward) along the unit ray: the factor,
// a few float steps nearer (the bounds of keys) or farther (of primitives' far ends).
float t_per_z_of(vec3 direction, float steps) {
  return (1.0 + steps * 4.0e-6) / dot(direction, view.forward);
}

void main() {
  load_frame_view();
  const uint group = flat_workgroup();
#ifdef TILES_STRIPS
  const uint entry = group / kStrips, strip = group % kStrips;
  if (entry >= slicing.strip_tiles) return;
#else
  const uint entry = slicing.strip_tiles + group, strip = 0u;
  if (entry >= slicing.tile_count) return;
#endif
  const uint tile = slice_tiles[slicing.tile_offset + entry];
  const uvec2 tile_xy = uvec2(tile % view.tiles.x, tile / view.tiles.x);
  const uint lane = gl_LocalInvocationIndex, tile_lane = strip * kLanes + lane;
  // The workgroup's pixels: the tile's, or a strip of them.
  const uvec2 origin = tile_xy * kTile + uvec2(0u, strip * (kLanes / kTile));
  const uvec2 pixel = tile_xy * kTile + pixel_in_tile(tile_lane);
  const uint block = lane / 8u;
  const bool inside = pixel.x < view.size.x && pixel.y < view.size.y;
  const uint index = pixel.y * view.size.x + pixel.x;
  // The pixel's state between slices and walks: its tile's slot, the pixel's lane in it.
  const uint state = tile_slots[tile] * (kTile * kTile) + tile_lane;
  const uvec2 whole = ranges[tile];
  const uint start = slicing.walk > 0u ? clamp(walk_first[tile], whole.x, whole.y) : whole.x;
  const uint begin = min(start + slicing.slice * slicing.slice_keys, whole.y);
  const uint end = min(begin + slicing.slice_keys, whole.y);
  // The first slice of the first walk starts the pixels empty; the tile's last slice writes
  // them out, or keeps them for another walk.
  const bool first_slice = slicing.slice == 0u && slicing.walk == 0u, last_slice = end == whole.y;
  for (int k = 0; k < kPassed - 1; ++k) passed_t[k] = -1.0, passed_primitive[k] = 0xFFFFFFFFu;
  bool written = false;  // by an earlier walk
  if (inside && !first_slice) {
    colour = states[state].colour_alpha.rgb;
    alpha = states[state].colour_alpha.a;
    hit_count = states[state].hits;
    pending = min(int(states[state].pending), kStateWindow);
    done = (states[state].flags & kDone) != 0u;
    written = (states[state].flags & kWritten) != 0u;
    last_t = states[state].last_t;
    last_primitive = states[state].last_primitive;
    for (int k = 0; k < kPassed - 1; ++k) {
      passed_t[k] = states[state].passed_t[k];
      passed_primitive[k] = states[state].passed_primitive[k];
    }
    floor_t = states[state].floor_t;
    floor_primitive = states[state].floor_primitive;
    after_t = states[state].after_t;
    after_primitive = states[state].after_primitive;
    for (int k = 0; k < kStateWindow; ++k) {
      if (k >= pending) continue;
      window_t[k] = states[state].t[k];
      window_primitive[k] = states[state].primitive[k];
#ifndef TILES_LATE_SHADING
      window_colour[k] = states[state].colour[k];
#endif
    }
  }
  const vec3 direction = ray_direction(pixel);
  pixel_direction = direction;
  // A key's depth bound is a view depth z; along this pixel's unit ray a point at view depth z
  // lies at t = z / dot(direction, forward), so the bound in the units of t is that much
  // farther. Comparing hits with the view depth itself left them pending up to 20 % longer off
  // the image's centre: on the H100's 1080p aneurysm a full window sent 483,349 pixel walks
  // round again, up to 9 walks a tile. The factor keeps a few float steps to spare.
  const float t_per_z = t_per_z_of(direction, -1.0), far_t_per_z = t_per_z_of(direction, 1.0);
  if (lane == 0u) round_claimed[0] = 0u, round_more[0] = 0u;
  uint round = 0u;  // the rounds of pairs so far, the same in every invocation
  for (uint first = begin; first < end; first += kBatch) {
    const uint count = min(kBatch, end - first), parity = ((first - begin) / kBatch) & 1u;
    for (uint k = lane; k < kBlocks * kWords; k += kLanes)
      block_entries[k / kWords][k % kWords] = 0u;
    // Last read two batches ago, before the barriers of the batch between.
    if (lane == 0u) busy[parity] = 0u, batch_far = 0u;
    barrier();
    if (lane == 0u) {
      const uint next = first + kBatch;
      next_bound = next < end ? key_depth(keys[next]) : 1.0 / 0.0;
    }
    for (uint e = lane; e < count; e += kLanes) {
      const uint primitive = values[first + e];
      batch_primitive[e] = primitive;
      vec2 lo, hi;
      float z_near, z_far;
      const bool bounded = screen_bounds(primitive, lo, hi, z_near, z_far);
      const float far = bounded ? z_far : 1.0 / 0.0;
      // Only the blocks that an entry marks read it (a strip's: a quarter of the tile's).
      if (mark_blocks(e, bounded, lo, hi, ivec2(origin)))
        load_primitive(e, primitive, key_depth(keys[first + e]), far);
      atomicMax(batch_far, floatBitsToUint(max(far, 0.0)));
    }
    barrier();
    // A batch that holds a whole chunk gives its far depth (slices and walks again start on
    // chunks; slices of fewer keys than a batch leave the chunks unknown, walked again).
    // (Every strip of a tile that walks a chunk writes the same value.)
    if (lane == 0u && (first - whole.x) % kBatch == 0u && (count == kBatch || end == whole.y))
      chunk_far[whole.x / kBatch + tile + (first - whole.x) / kBatch] = uintBitsToFloat(batch_far);
    // The entries this pixel's ray may hit, in key order: bit i of near[w] for entry 32 w + i.
    // An entry whose hits all lie at or before the hits an earlier walk composited, or past the
    // floor, has none for this walk: this makes the walks again cheap where they pass keys
    // their pixel is done with.
    uint near[kWords], entries[kWords];
    for (uint w = 0u; w < kWords; ++w) {
      near[w] = 0u;
      entries[w] = inside && !done && !written ? block_entries[block][w] : 0u;
    }
    uint left = 0u;  // pairs not yet in a round
    for (uint i = first_entry(entries); i < kBatch; i = first_entry(entries)) {
      set_entry(entries, i, false);
      vec4 words[kNearWords];
      near_words(i, words);
      if (bound_t(words[0].w, t_per_z) > floor_t || bound_t(words[1].w, far_t_per_z) < after_t)
        continue;
      if (may_cross(words, direction)) set_entry(near, i, true), ++left;
    }
#ifdef TILES_PIXEL_HITS
    // Each pixel computes its own entries' hits, in key order: the same hits, taken in the same
    // order, as the rounds below (the same bytes), without their shared-memory traffic and two
    // barriers a round, each pixel's work on its own lane.
    for (uint i = first_entry(near); i < kBatch && !done; i = first_entry(near)) {
      set_entry(near, i, false);
      float t;
      vec4 c;
      if (!first_hit(i, direction, t, c)) continue;
      flush(bound_t(depth_bound(i), t_per_z));
      if (done) break;
      insert(t, c, batch_primitive[i], seam_of(i, direction));
    }
#else
    // Rounds of pairs until every pixel has had its pairs' hits. The counters alternate by the
    // round's parity: those of the next round are cleared in this one, after their last reads.
    for (;; ++round) {
      const uint r = round & 1u;
      uint base = 0u, take = 0u;
      if (left > 0u) {
        const uint want = min(left, kPairsPerRound);
        base = atomicAdd(round_claimed[r], want);
        take = base < kRoundSlots ? min(want, kRoundSlots - base) : 0u;
      }
      round_hits[lane] = 0u;
      if (lane == 0u) round_claimed[r ^ 1u] = 0u, round_more[r ^ 1u] = 0u;
      for (uint taken = 0u; taken < take; ++taken) {
        const uint i = first_entry(near);
        set_entry(near, i, false);
        slot_pair[base + taken] = lane | (i << 8u) | (taken << 16u);
      }
      left -= take;
      if (left > 0u) round_more[r] = 1u;  // a flag: every writer writes the same value
      barrier();
      if (lane < min(round_claimed[r], kRoundSlots)) {
        const uint pair = slot_pair[lane];
        const uint p = pair & 0xFFu, i = (pair >> 8u) & 0xFFu;
        float t;
        vec4 c;
        const vec3 ray = ray_direction(tile_xy * kTile + pixel_in_tile(strip * kLanes + p));
        if (first_hit(i, ray, t, c)) {
          const float bound = bound_t(depth_bound(i), t_per_z_of(ray, -1.0));
          slot_hit[lane] = uvec4(floatBitsToUint(t), floatBitsToUint(bound),
                                 floatBitsToUint(seam_of(i, ray)), batch_primitive[i]);
#ifndef TILES_LATE_SHADING
          slot_colour[lane] = c;
#endif
          atomicOr(round_hits[p], 1u << (pair >> 16u));
        }
      }
      barrier();
      // Skipped entries (no hit) need no flush: the depth bounds grow in key order, so the
      // flush before the next hit's entry composites all that theirs would have.
      for (uint hits = round_hits[lane]; hits != 0u && !done; hits &= hits - 1u) {
        const uint s = base + uint(findLSB(hits));
        const uvec4 hit = slot_hit[s];
        flush(uintBitsToFloat(hit.y));
        if (done) break;
#ifdef TILES_LATE_SHADING
        const vec4 c = vec4(0.0);  // shaded when composited
#else
        const vec4 c = slot_colour[s];
#endif
        insert(uintBitsToFloat(hit.x), c, hit.w, uintBitsToFloat(hit.z));
      }
      if (done) left = 0u;
      const bool more = round_more[r] != 0u;
      barrier();
      if (!more) break;
    }
    ++round;
#endif
    // Hits of the later keys lie past their depth bounds, so once those pass the pixel's floor
    // it takes none of them in this walk.
    if (inside && !done && !written && floor_t > bound_t(next_bound, t_per_z))
      busy[parity] = 1u;
    barrier();
    if (busy[parity] == 0u) break;
  }
  // lavapipe ends every loop of an invocation once its loops together have run 65535 times
  // (gallivm's limiter), dropping work silently. A loop that must run `sentinel` times and runs
  // fewer tells it, and the host composites the band again in smaller slices.
  uint trips = 0u;
  for (uint k = 0u; k < slicing.sentinel; ++k) ++trips;
  if (trips != slicing.sentinel) atomicAdd(stats.cut_short, 1u);
  if (!inside || written) return;
  if (last_slice) flush(3.0e38);
  // Hits left for another walk: this walk composited every hit before the floor, and the next
  // starts after the last of them.
  const bool again = last_slice && !done && floor_t < 1.0 / 0.0;
  if (again) {
    atomicAdd(stats.window_overflows, 1u);
    // The next walk takes hits past last_t: from primitives whose far depth, in the units of t
    // along this ray (bound_t), is last_t or more, so whose far depth is at least this (a
    // millionth nearer for the float steps on the way; nothing behind the eye: 0, any).
    const float least_z = last_t > 0.0 ? last_t / far_t_per_z * (1.0 - 1e-6) : 0.0;
    atomicMin(walk_again[tile], floatBitsToUint(least_z));
    after_t = last_t, after_primitive = last_primitive;
    floor_t = 1.0 / 0.0, floor_primitive = 0xFFFFFFFFu;
  }
  // Without room for the state (one slice, no walk yet) the host makes room and composites
  // the band again.
  if ((!last_slice || again) && state < states.length()) {
    states[state].colour_alpha = vec4(colour, alpha);
    states[state].hits = hit_count;
    states[state].pending = uint(pending);
    states[state].flags = done ? kDone : 0u;
    states[state].last_primitive = last_primitive;
    states[state].last_t = last_t;
    for (int k = 0; k < kPassed - 1; ++k) {
      states[state].passed_t[k] = passed_t[k];
      states[state].passed_primitive[k] = passed_primitive[k];
    }
    states[state].floor_t = floor_t;
    states[state].floor_primitive = floor_primitive;
    states[state].after_t = after_t;
    states[state].after_primitive = after_primitive;
    // Only the pending hits: the rest of the window is never read.
    for (int k = 0; k < kStateWindow; ++k) {
      if (k >= pending) continue;
      states[state].t[k] = window_t[k];
      states[state].primitive[k] = window_primitive[k];
#ifndef TILES_LATE_SHADING
      states[state].colour[k] = window_colour[k];
#endif
    }
  }
  if (!last_slice || again) return;
  colour += (1.0 - alpha) * frame.background.rgb;
  pixels[index] = vec4(colour, alpha);
  hit_counts[index] = hit_count;
  // A walk again over this tile (another pixel's) leaves this one as it is.
  if (state < states.length()) states[state].flags = kWritten;
}
