// The capsule primitives of `tiles` (the default geometry): the lines' points and segments.

// x, y, z and the attribute value per point.
layout(set = 0, binding = 1, std430) readonly buffer Points { vec4 points[]; };
// Per segment: its first point << 2 | neighbour flags (accel/capsule_segments.hpp).
layout(set = 0, binding = 2, std430) readonly buffer Segments { uint segments[]; };
