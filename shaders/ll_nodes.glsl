// ll's node pool (shaders/ll_gather.frag, ll_resolve.comp) in the pages of pages.glsl, each of
// 2^frame.size.w nodes. A node is kNodeWords words: 6 (straight r, g, b, a as float bits,
// depth, next) or 3 (r, g, b, a as unorm8, depth, next: LineVis's 12-byte node). Needs frame.glsl.

#include "pages.glsl"

// Specialisation constant 3: words per node.
layout(constant_id = 3) const uint kNodeWords = 6;

uint node_load(uint node, uint k) {
  return page_load(page_of(node), index_in_page(node) * kNodeWords + k);
}

void node_store(uint node, uint k, uint word) {
  page_store(page_of(node), index_in_page(node) * kNodeWords + k, word);
}

bool wide_nodes() {
  return kNodeWords == 6u;
}

void write_node(uint node, vec4 colour, float depth, uint next) {
  if (wide_nodes()) {
    for (uint k = 0u; k < 4u; ++k) node_store(node, k, floatBitsToUint(colour[k]));
    node_store(node, 4u, floatBitsToUint(depth));
    node_store(node, 5u, next);
  } else {
    node_store(node, 0u, packUnorm4x8(colour));
    node_store(node, 1u, floatBitsToUint(depth));
    node_store(node, 2u, next);
  }
}

vec4 node_colour(uint node) {
  if (!wide_nodes()) return unpackUnorm4x8(node_load(node, 0u));
  return vec4(uintBitsToFloat(node_load(node, 0u)), uintBitsToFloat(node_load(node, 1u)),
              uintBitsToFloat(node_load(node, 2u)), uintBitsToFloat(node_load(node, 3u)));
}

float node_depth(uint node) {
  return uintBitsToFloat(node_load(node, wide_nodes() ? 4u : 1u));
}

uint node_next(uint node) {
  return node_load(node, wide_nodes() ? 5u : 2u);
}
