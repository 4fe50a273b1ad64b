#version 460
#include "mboit_moments.glsl"
