#pragma once
// The view and shading fields every per-pixel GPU technique's uniform block starts with (eye,
// forward, right, up, shading, background: shading.glsl and the ray set-up read them), filled
// from the camera's image plane as the CPU tracer builds its rays (Camera::ray_direction).

#include "render/camera.hpp"
#include "render/ray_tracer.hpp"

namespace linebake::vk {

template <class Uniforms>
void write_view(Uniforms& u, const Camera& camera, int width, int height, const Shading& shading) {
  const Camera::ImagePlane plane = camera.image_plane(width, height);
  for (int k = 0; k < 3; ++k) {
    u.eye[k] = float(camera.eye[k]);
    u.forward[k] = float(plane.forward[k]);
    u.right[k] = float(plane.right[k]);
    u.up[k] = float(plane.up[k]);
    u.background[k] = float(shading.background[size_t(k)]);
  }
  u.shading[0] = float(shading.ambient), u.shading[1] = float(shading.diffuse);
  u.shading[2] = float(shading.specular), u.shading[3] = float(shading.shininess);
}

}  // namespace linebake::vk
