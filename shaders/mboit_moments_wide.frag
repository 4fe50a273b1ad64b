#version 460
#define WIDE_MOMENTS
#include "mboit_moments.glsl"
