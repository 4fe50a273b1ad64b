#version 460
// Nothing more along the ray. The ray generation shader empties the window before each trace,
// so a miss leaves it as it is: empty for `--hits stepping`, and for `--hits filter` holding the
// hits the any-hit shaders collected (a trace that accepts no hit ends in the miss shader).

#include "rtx_common.glsl"

layout(location = 0) rayPayloadInEXT Payload payload;

void main() {}
