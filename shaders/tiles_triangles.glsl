// The triangle primitives of `tiles --tiles-geometry triangles`: the cached tube mesh.

// Per vertex: x, y, z, attribute value; then the normal (x, y, z, 0).
layout(set = 0, binding = 1, std430) readonly buffer Vertices { vec4 vertices[]; };
// Three vertex indices per triangle, counter-clockwise seen from outside.
layout(set = 0, binding = 2, std430) readonly buffer Indices { uint indices[]; };
