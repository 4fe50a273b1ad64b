#version 460
// Nothing more along the ray.

#include "rtx_common.glsl"

layout(location = 0) rayPayloadInEXT Payload payload;

void main() {
  payload.kind = kMiss;
  payload.t = 0.0;
  payload.colour = vec4(0.0);
}
