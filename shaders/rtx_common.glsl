// Shared by the Vulkan ray tracing shaders (technique `rtx`): the frame's uniforms (named
// `frame`, as shading.glsl expects), the chunk table and the ray payload.

#extension GL_EXT_ray_tracing : require
#extension GL_EXT_buffer_reference2 : require

const int kMaxTfPoints = 32;

layout(set = 0, binding = 1, std140) uniform RtUniforms {
  vec4 eye;         // xyz
  vec4 forward;     // xyz, unit
  vec4 right;       // xyz, scaled by tan(fov/2) x aspect
  vec4 up;          // xyz, scaled by tan(fov/2)
  vec4 shading;     // ambient, diffuse, specular, shininess
  vec4 background;  // linear rgb
  vec4 ranges;      // stored attribute decode lo, hi; transfer-function range lo, hi
  uvec4 size;       // width, height, early termination, max iterations per pixel
  uvec4 tf_counts;  // colour points, opacity points, hit collection (0 filter, 1 stepping), 0
  vec4 params;      // termination alpha, capsule radius, capsules (1) or triangles (0), 0
  vec4 colours[kMaxTfPoints];    // x, sRGB r, g, b
  vec4 opacities[kMaxTfPoints];  // x, opacity
} frame;

layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer Floats {
  float v[];
};
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer Words {
  uint v[];
};

// One BLAS's geometry (gl_InstanceCustomIndexEXT selects it). Triangles: the tube chunk's
// positions, normals (float32 or octahedral snorm16 pairs), unorm16 attribute and indices.
// Capsules: points (x, y, z, attribute) in `positions` and segment words in `indices`.
struct Chunk {
  Floats positions;
  Floats normals;
  Words normals_oct;
  Words attributes;  // unorm16 pairs
  Words indices;
  uint normal_encoding;  // 0 float32, 1 octahedral
  uint has_attribute;
};
layout(set = 0, binding = 2, std430) readonly buffer Chunks { Chunk chunks[]; };

// What a trace returns to the ray generation loop: a window of hits in (t, chunk, primitive)
// order. With `--hits filter` (default) the any-hit shaders fill up to kWindowHits of the hits
// after `after_*` (the previous window's last) and set `overflow` when more lay beyond; with
// `--hits stepping` the closest-hit shaders return the one nearest hit (count 1) and the miss
// shader count 0.
const uint kWindowHits = 8u;
const uint kBackHit = 0x80000000u;  // flag in chunk[]: a back hit (counted, not composited)
struct Payload {
  vec4 colour[kWindowHits];  // shaded linear rgb, opacity (front hits)
  float t[kWindowHits];
  uint chunk[kWindowHits];  // gl_InstanceCustomIndexEXT, | kBackHit
  uint primitive[kWindowHits];
  uint count;
  uint overflow;
  float after_t;
  uint after_chunk, after_primitive;
};
