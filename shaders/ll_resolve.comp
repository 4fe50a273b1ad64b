#version 460
// Per-pixel linked lists, resolve pass: copy the pixel's list (up to kMaxFragments nodes) into
// local arrays, sort by depth and blend front to back over the background. Longer lists are
// reported through `longest` and the host re-runs the resolve with room for them, for those
// pixels only (kResolvedUpTo).
//
// Fragments of equal depth (coincident tubes: repeated lines are common in real data) are
// ordered by a key of their colour. A list holds its fragments in the order they arrived, which
// a GPU does not fix from run to run; without the tie-break, equal depths blended in that order
// and the same input could give different images. The key is read once per fragment, as the
// list is copied: read in the comparisons, lavapipe (which runs both sides of every branch) took
// 244 ms for the aneurysm's resolve instead of 27 (docs/tiles.md).
#include "frame.glsl"
#include "ll_nodes.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(constant_id = 0) const uint kMaxFragments = 256;
// 0 insertion, 1 shell (24, 9, 4, 1), 2 heap, 3 quicksort with insertion sort below 16
layout(constant_id = 1) const uint kSort = 2;
// The resolve again after one whose arrays held this many fragments: the pixels whose lists it
// held whole (their depth complexity, which it wrote) are done. 0: every pixel.
layout(constant_id = 4) const uint kResolvedUpTo = 0;

layout(set = 0, binding = 1, std430) readonly buffer Heads { uint heads[]; };
layout(set = 0, binding = 4, std430) writeonly buffer Output { vec4 pixels[]; };
layout(set = 0, binding = 5, std430) buffer Stats { uint longest; uint depth_complexity[]; };

// Per fragment its sort key, (depth's ordered bits, colour key). One array of both: on lavapipe
// each access of a private array by a varying index is a gather, and comparisons read both.
uvec2 order_of[kMaxFragments];
uint node_of[kMaxFragments];

// The tie-break key of a node's colour: the 12-byte node's packed colour itself (a total order of
// its colours), or a mix of the 24-byte node's four words (equal keys for different colours at
// equal depth, which would blend in arrival order, are a 2^-32 chance).
uint colour_key(uint node) {
  if (!wide_nodes()) return node_load(node, 0u);
  uint h = 0x811C9DC5u;
  for (uint k = 0u; k < 4u; ++k) {
    h = (h ^ node_load(node, k)) * 0x01000193u;
    h ^= h >> 15;
  }
  return h;
}

// A float's bits as a uint that orders as the floats do, negative ones (a fragment a rounding
// step before the near plane, -0.0) included.
uint ordered_bits(float x) {
  const uint b = floatBitsToUint(x);
  return (b & 0x80000000u) != 0u ? ~b : b | 0x80000000u;
}

// Whether the fragment of sort key a blends before that of b.
bool before(uvec2 a, uvec2 b) {
  return a.x < b.x || (a.x == b.x && a.y < b.y);
}

bool entry_before(uint i, uint j) {
  return before(order_of[i], order_of[j]);
}

void swap_entries(uint i, uint j) {
  const uvec2 o = order_of[i];
  order_of[i] = order_of[j];
  order_of[j] = o;
  const uint n = node_of[i];
  node_of[i] = node_of[j];
  node_of[j] = n;
}

void insertion_sort(uint count, uint gap) {
  for (uint i = gap; i < count; ++i) {
    const uvec2 o = order_of[i];
    const uint n = node_of[i];
    uint j = i;
    while (j >= gap && before(o, order_of[j - gap])) {
      order_of[j] = order_of[j - gap];
      node_of[j] = node_of[j - gap];
      j -= gap;
    }
    order_of[j] = o;
    node_of[j] = n;
  }
}

// Insertion sort of [lo, hi).
void insertion_sort_range(uint lo, uint hi) {
  for (uint i = lo + 1u; i < hi; ++i) {
    const uvec2 o = order_of[i];
    const uint n = node_of[i];
    uint j = i;
    while (j > lo && before(o, order_of[j - 1u])) {
      order_of[j] = order_of[j - 1u];
      node_of[j] = node_of[j - 1u];
      --j;
    }
    order_of[j] = o;
    node_of[j] = n;
  }
}

// Quicksort (median-of-three pivot, explicit stack, the smaller side pushed last so the stack
// stays within log2 of the count) that leaves ranges below 16 to insertion sort.
void quick_hybrid_sort(uint count) {
  uint stack_lo[32], stack_hi[32];
  uint top = 0u;
  stack_lo[0] = 0u;
  stack_hi[0] = count;
  top = 1u;
  while (top > 0u) {
    --top;
    const uint lo = stack_lo[top], hi = stack_hi[top];
    if (hi - lo < 16u) {
      insertion_sort_range(lo, hi);
      continue;
    }
    const uint mid = lo + (hi - lo) / 2u;
    if (entry_before(mid, lo)) swap_entries(mid, lo);
    if (entry_before(hi - 1u, lo)) swap_entries(hi - 1u, lo);
    if (entry_before(hi - 1u, mid)) swap_entries(hi - 1u, mid);
    const uvec2 pivot = order_of[mid];
    uint i = lo, j = hi - 1u;
    for (;;) {  // Hoare partition: [lo, j] <= pivot <= [j + 1, hi)
      while (before(order_of[i], pivot)) ++i;
      while (before(pivot, order_of[j])) --j;
      if (i >= j) break;
      swap_entries(i, j);
      ++i;
      --j;
    }
    const uint split = j + 1u;
    // The larger side waits on the stack; the smaller is sorted next.
    const bool left_smaller = split - lo < hi - split;
    stack_lo[top] = left_smaller ? split : lo;
    stack_hi[top] = left_smaller ? hi : split;
    stack_lo[top + 1u] = left_smaller ? lo : split;
    stack_hi[top + 1u] = left_smaller ? split : hi;
    top += 2u;
  }
}

void sift_down(uint i, uint count) {
  for (;;) {
    const uint l = 2u * i + 1u, r = l + 1u;
    uint m = i;
    if (l < count && entry_before(l, m)) m = l;
    if (r < count && entry_before(r, m)) m = r;
    if (m == i) return;
    swap_entries(i, m);
    i = m;
  }
}

vec3 colour_acc = vec3(0.0);
float alpha_acc = 0.0;

bool blend(uint node) {  // false once compositing may stop
  const vec4 c = node_colour(node);
  const vec3 rgb = c.rgb;
  const float a = c.a;
  colour_acc += (1.0 - alpha_acc) * a * rgb;
  alpha_acc += (1.0 - alpha_acc) * a;
  return !(frame.tf_counts.z != 0u && alpha_acc >= frame.termination.x);
}

void main() {
  const uvec2 p = gl_GlobalInvocationID.xy;
  if (p.x >= frame.size.x || p.y >= frame.size.y) return;
  const uint pixel = p.y * frame.size.x + p.x;
  if (kResolvedUpTo > 0u && depth_complexity[pixel] <= kResolvedUpTo) return;
  uint count = 0u, total = 0u;
  for (uint n = heads[pixel]; n != 0xFFFFFFFFu; n = node_next(n)) {
    if (count < kMaxFragments) {
      order_of[count] = uvec2(ordered_bits(node_depth(n)), colour_key(n));
      node_of[count] = n;
      ++count;
    }
    ++total;
  }
  depth_complexity[pixel] = total;
  if (total > kMaxFragments) atomicMax(longest, total);
  if (kSort == 2u) {
    // Min-heap priority queue: pop the nearest fragment, blend, repeat.
    for (uint i = count / 2u; i-- > 0u;) sift_down(i, count);
    for (uint left = count; left > 0u; --left) {
      if (!blend(node_of[0])) break;
      swap_entries(0u, left - 1u);
      sift_down(0u, left - 1u);
    }
  } else {
    if (kSort == 3u) {
      quick_hybrid_sort(count);
    } else {
      if (kSort == 1u) {
        insertion_sort(count, 24u);
        insertion_sort(count, 9u);
        insertion_sort(count, 4u);
      }
      insertion_sort(count, 1u);
    }
    for (uint i = 0u; i < count; ++i)
      if (!blend(node_of[i])) break;
  }
  pixels[pixel] = vec4(colour_acc + (1.0 - alpha_acc) * frame.background.rgb, alpha_acc);
}
