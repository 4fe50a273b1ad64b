#version 460
// The opaque setting: depth-tested, shaded with the transfer function's colour.
#include "fragment.glsl"

layout(location = 0) out vec4 colour;

void main() {
  colour = vec4(shaded_fragment().rgb, 1.0);
}
