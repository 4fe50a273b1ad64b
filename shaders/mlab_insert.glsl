// One fragment into its pixel's MLAB nodes: plain MLAB (kBuckets = 0) inserts into all k nodes;
// MLABDB (kBuckets = 1) discards fragments behind the first opaque one, merges those in front of
// the first fairly opaque one into the front bucket (node 0) and inserts the rest into nodes
// 1..k-1. Depth is gl_FragCoord.z for MLAB, the normalised log depth for MLABDB.
#include "mlab.glsl"

layout(constant_id = 1) const uint kBuckets = 0;

void mlab_fragment(uint pixel, vec4 c) {
  const vec3 rgb = c.a * c.rgb;
  const float t = 1.0 - c.a;
  if (kBuckets == 0u) {
    load_nodes(pixel);
    insert_fragment(0u, gl_FragCoord.z, rgb, t);
    store_nodes(pixel);
    return;
  }
  const uint count = frame.size.x * frame.size.y;
  const float d = log_depth();
  const float min_depth = uintBitsToFloat(pixel_state[count + pixel]);
  const float min_opaque_depth = uintBitsToFloat(pixel_state[2u * count + pixel]);
  if (d > min_opaque_depth + 1e-4) return;
  load_nodes(pixel);
  if (d < min_depth) {
    if (isinf(node_depth[0])) {
      node_depth[0] = d;
      node_rgb[0] = rgb;
      node_t[0] = t;
    } else {
      merge_nodes(0u, d, rgb, t);
    }
  } else {
    insert_fragment(1u, d, rgb, t);
  }
  store_nodes(pixel);
}
