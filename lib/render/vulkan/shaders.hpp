#pragma once
// The SPIR-V of shaders/, compiled by glslc at build time and embedded in the binary.

#include <cstddef>
#include <cstdint>
#include <string>

namespace linebake::vk {

struct Spirv {
  const uint32_t* words = nullptr;
  size_t size_bytes = 0;
};

// By source file name, e.g. "tube.vert" or "ll_resolve.comp"; throws for other names.
Spirv shader_spirv(const std::string& name);

}  // namespace linebake::vk
