// Multi-layer alpha blending (Salvi & Vaidyanathan 2014; techniques.md sections 4 and 5): k nodes
// per pixel {depth, premultiplied rgb, transmittance T}, kept sorted by depth; when a fragment
// pushes a node past the last slot, the two farthest merge. Nodes live in the pages of binding 6
// (pages.glsl: storage past one buffer) as three planes of words (depths, rgb, T) so each can be
// cleared with fills: depth +inf, rgb 0, T 1.
// The insert reads and rewrites the whole array, so it runs inside a per-pixel critical section:
// fragment shader interlock where the device has it, a spin lock on binding 1 otherwise.
#include "fragment.glsl"

layout(constant_id = 0) const uint kLayers = 8;

layout(set = 0, binding = 1, std430) coherent buffer PixelState { uint pixel_state[]; };
#define PAGES_QUALIFIER coherent
#include "pages.glsl"

float node_word(uint w) {
  return uintBitsToFloat(word_load(w));
}

void set_node_word(uint w, float v) {
  word_store(w, floatBitsToUint(v));
}

float node_depth[kLayers + 1];
vec3 node_rgb[kLayers + 1];
float node_t[kLayers + 1];

uint plane_size() {
  return frame.size.x * frame.size.y * kLayers;
}

void load_nodes(uint pixel) {
  const uint n = plane_size();
  for (uint i = 0u; i < kLayers; ++i) {
    const uint at = pixel * kLayers + i;
    node_depth[i] = node_word(at);
    node_rgb[i] =
        vec3(node_word(n + 3u * at), node_word(n + 3u * at + 1u), node_word(n + 3u * at + 2u));
    node_t[i] = node_word(4u * n + at);
  }
}

void store_nodes(uint pixel) {
  const uint n = plane_size();
  for (uint i = 0u; i < kLayers; ++i) {
    const uint at = pixel * kLayers + i;
    set_node_word(at, node_depth[i]);
    set_node_word(n + 3u * at, node_rgb[i].r);
    set_node_word(n + 3u * at + 1u, node_rgb[i].g);
    set_node_word(n + 3u * at + 2u, node_rgb[i].b);
    set_node_word(4u * n + at, node_t[i]);
  }
}

// Slot `into` becomes the nearer of (into, other) blended over the farther.
void merge_nodes(uint into, float depth, vec3 rgb, float t) {
  const bool node_nearer = node_depth[into] <= depth;
  const vec3 src_rgb = node_nearer ? node_rgb[into] : rgb;
  const float src_t = node_nearer ? node_t[into] : t;
  const vec3 dst_rgb = node_nearer ? rgb : node_rgb[into];
  const float dst_t = node_nearer ? t : node_t[into];
  node_rgb[into] = src_rgb + src_t * dst_rgb;
  node_t[into] = src_t * dst_t;
  node_depth[into] = min(node_depth[into], depth);
}

// Sorted insert into slots [first, kLayers) with slot kLayers as the +inf sentinel; an occupied
// sentinel merges into the last slot.
void insert_fragment(uint first, float depth, vec3 rgb, float t) {
  node_depth[kLayers] = uintBitsToFloat(0x7F800000u);
  node_rgb[kLayers] = vec3(0.0);
  node_t[kLayers] = 1.0;
  for (uint i = first; i <= kLayers; ++i) {
    if (node_depth[i] >= depth) {
      const float d = node_depth[i];
      const vec3 c = node_rgb[i];
      const float tt = node_t[i];
      node_depth[i] = depth;
      node_rgb[i] = rgb;
      node_t[i] = t;
      depth = d;
      rgb = c;
      t = tt;
    }
  }
  if (!isinf(node_depth[kLayers]))
    merge_nodes(kLayers - 1u, node_depth[kLayers], node_rgb[kLayers], node_t[kLayers]);
}
