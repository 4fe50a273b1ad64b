// The members of the tiles passes' frame values (tiles.glsl declares them twice: a uniform
// buffer and a storage-buffer view of the same buffer). TileUniforms in
// lib/render/vulkan/tile_renderer.cpp.
vec4 eye;         // xyz
vec4 forward;     // xyz, unit
vec4 right;       // xyz, scaled by tan(fov/2) x aspect
vec4 up;          // xyz, scaled by tan(fov/2)
vec4 shading;     // ambient, diffuse, specular, shininess
vec4 background;  // linear rgb
vec4 ranges;      // 0, 0; transfer-function range lo, hi
uvec4 size;       // width, height, early termination, primitives
uvec4 tf_counts;  // colour points, opacity points, 0, 0
vec4 params;      // termination alpha, capsule radius, key depth near, key depth far
uvec4 tiles;      // tiles across, tiles down, depth bits of a key, key capacity
uvec4 band;       // the tile rows of this pass: first, one past the last
uvec4 binning;    // pixels a primitive's bounds hold at most to be tested (tiles_keys.glsl), 0, ...
vec4 colours[kMaxTfPoints];    // x, sRGB r, g, b
vec4 opacities[kMaxTfPoints];  // x, opacity
