#version 460
// tiles, pass 3 over the tube mesh's triangles (tiles_composite.glsl): each pixel's ray against
// each front-facing triangle (Moller and Trumbore 1997), the normal and attribute interpolated
// as the CPU ray tracer interpolates them (lib/accel/embree_scene.cpp, surface()).
#include "tiles.glsl"
#include "tiles_triangles.glsl"
#include "shading.glsl"

const uint kBatch = 256;
shared vec4 batch_a[kBatch], batch_b[kBatch], batch_c[kBatch];  // xyz, attribute
shared vec3 batch_na[kBatch], batch_nb[kBatch], batch_nc[kBatch];

void insert(float t, vec4 c, uint primitive, float seam);

void load_primitive(uint lane, uint s) {
  const uint a = indices[3u * s], b = indices[3u * s + 1u], c = indices[3u * s + 2u];
  batch_a[lane] = vertices[2u * a];
  batch_b[lane] = vertices[2u * b];
  batch_c[lane] = vertices[2u * c];
  batch_na[lane] = vertices[2u * a + 1u].xyz;
  batch_nb[lane] = vertices[2u * b + 1u].xyz;
  batch_nc[lane] = vertices[2u * c + 1u].xyz;
}

// The exact test is cheap: no test before it.
const bool kNearTest = false;
bool may_cross(uint i, vec3 direction) { return true; }

void intersect_primitive(uint i, uint primitive, vec3 direction) {
  const vec3 a = batch_a[i].xyz;
  const vec3 e1 = batch_b[i].xyz - a, e2 = batch_c[i].xyz - a;
  const vec3 p = cross(direction, e2);
  const float det = dot(e1, p);
  // det = -dot(direction, n) for the outward normal n = e1 x e2 (counter-clockwise from outside):
  // positive for a front face.
  if (det <= 0.0) return;
  const vec3 s = frame.eye.xyz - a;
  const float u = dot(s, p) / det;
  if (u < 0.0 || u > 1.0) return;
  const vec3 q = cross(s, e1);
  const float v = dot(direction, q) / det;
  if (v < 0.0 || u + v > 1.0) return;
  const float t = dot(e2, q) / det;
  if (t <= 0.0) return;
  const float w = 1.0 - u - v;
  const float value = w * batch_a[i].w + u * batch_b[i].w + v * batch_c[i].w;
  const vec3 n = w * batch_na[i] + u * batch_nb[i] + v * batch_nc[i];
  const vec4 base = transfer_function(value);
  // (No seam test: a ray meets a shared edge of two triangles with probability zero.)
  insert(t, vec4(shade(frame.eye.xyz + t * direction, n, base.rgb), base.a), primitive, 0.0);
}

#include "tiles_composite.glsl"
