#pragma once
// The transfer function as the shaders' tables (shaders/shading.glsl): colour points (x, sRGB r,
// g, b) and opacity points (x, opacity), at most kMaxTfPoints each.

#include <cstdint>

#include "core/error.hpp"
#include "render/transfer_function.hpp"

namespace linebake::vk {

constexpr int kMaxTfPoints = 32;  // shaders/frame.glsl, shaders/vrc.comp

inline void write_transfer_table(const TransferFunction& tf, float (&colours)[kMaxTfPoints][4],
                                 float (&opacities)[kMaxTfPoints][4], uint32_t* counts) {
  if (tf.colours.empty() || tf.opacities.empty() || tf.colours.size() > kMaxTfPoints ||
      tf.opacities.size() > kMaxTfPoints)
    throw Error("transfer function '" + tf.name + "': 1 to " + std::to_string(kMaxTfPoints) +
                " colour and opacity points for the GPU techniques");
  counts[0] = uint32_t(tf.colours.size()), counts[1] = uint32_t(tf.opacities.size());
  for (size_t i = 0; i < tf.colours.size(); ++i) {
    colours[i][0] = float(tf.colours[i].x);
    for (size_t k = 0; k < 3; ++k) colours[i][k + 1] = float(tf.colours[i].srgb[k]);
  }
  for (size_t i = 0; i < tf.opacities.size(); ++i) {
    opacities[i][0] = float(tf.opacities[i].x);
    opacities[i][1] = float(tf.opacities[i].opacity);
  }
}

}  // namespace linebake::vk
