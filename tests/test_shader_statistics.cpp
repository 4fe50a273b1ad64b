// The SPIR-V layout reader against what the shaders' GLSL declares and uses, and against the
// Khronos validation layer's own reading of the same modules (lavapipe); the compiler statistics
// themselves need a driver that reports them, which CTest's cli test runs on RADV's null device.

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "core/error.hpp"
#include "render/vulkan/context.hpp"
#include "render/vulkan/shader_statistics.hpp"
#include "render/vulkan/shaders.hpp"
#include "render/vulkan/spirv_layout.hpp"

namespace linebake {
namespace {

std::vector<uint32_t> binding_numbers(const vk::SpirvLayout& layout, VkDescriptorType type) {
  std::vector<uint32_t> numbers;
  for (const vk::SpirvBinding& b : layout.bindings)
    if (b.type == type) numbers.push_back(b.binding);
  return numbers;
}

TEST(SpirvLayout, ReadsTheBindingsTheShaderUses) {
  // shaders/radix_count.comp reads keys_in (binding 0) and writes counts (binding 4) of
  // radix_sort.glsl's six buffers, and reads the push constants; glslc drops the four it does
  // not use.
  const vk::SpirvLayout count =
      vk::reflect_layout(vk::shader_spirv("radix_count.comp"), "radix_count.comp");
  EXPECT_EQ(count.stage, VK_SHADER_STAGE_COMPUTE_BIT);
  EXPECT_TRUE(count.push_constants);
  EXPECT_EQ(binding_numbers(count, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER),
            (std::vector<uint32_t>{0, 4}));
  EXPECT_EQ(count.bindings.size(), 2u);
  EXPECT_EQ(count.set_count(), 1u);

  // tiles' composite over capsules: the uniforms (binding 0) and every storage buffer of
  // tiles.glsl, tiles_capsules.glsl and tiles_composite.glsl but binning's counters (5) and
  // per-row key counts (12), which it never touches; 19 and 20 are the capsules' pages past the
  // first, arrays of 7 and 3.
  const vk::SpirvLayout composite =
      vk::reflect_layout(vk::shader_spirv("tiles_composite.comp"), "tiles_composite.comp");
  EXPECT_FALSE(composite.push_constants);
  EXPECT_EQ(binding_numbers(composite, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER),
            (std::vector<uint32_t>{0}));
  EXPECT_EQ(
      binding_numbers(composite, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER),
      (std::vector<uint32_t>{1, 2, 3, 4, 6, 7, 8, 9, 10, 11, 13, 14, 15, 16, 17, 18, 19, 20}));
  for (const vk::SpirvBinding& b : composite.bindings)
    EXPECT_EQ(b.count, b.binding == 19 ? 7u : b.binding == 20 ? 3u : 1u) << b.binding;
  // The stride of a block's runtime array: the pixels' states (binding 11), by std430's rules
  // from the GLSL's PixelState: a vec4, 11 words and 3 + 3 words of the last hits passed with a
  // word to pad make 80 bytes, then t and primitive of each of the window's hits (8 or 16) and,
  // unless the build shades late, a vec4 colour. The slice's block (10) ends in no array.
  const auto stride = [](const std::string& shader, uint32_t binding) {
    for (const vk::SpirvBinding& b : vk::reflect_layout(vk::shader_spirv(shader), shader).bindings)
      if (b.binding == binding) return b.array_stride;
    return ~0u;
  };
  EXPECT_EQ(stride("tiles_composite.comp", 11), 80u + 8 * (4 + 4 + 16));
  EXPECT_EQ(stride("tiles_composite.comp:late", 11), 80u + 8 * (4 + 4));
  EXPECT_EQ(stride("tiles_composite.comp:exits", 11), 80u + 16 * (4 + 4 + 16));
  EXPECT_EQ(stride("tiles_composite_triangles.comp:deep-pixels-late", 11), 80u + 16 * (4 + 4));
  EXPECT_EQ(stride("tiles_composite.comp", 10), 0u);

  // A vertex shader is read as one.
  EXPECT_EQ(vk::reflect_layout(vk::shader_spirv("tube.vert"), "tube.vert").stage,
            VK_SHADER_STAGE_VERTEX_BIT);
}

TEST(SpirvLayout, RefusesWhatIsNotAModule) {
  const std::vector<uint32_t> text(16, 0x41414141u);
  EXPECT_THROW(vk::reflect_layout({text.data(), text.size() * 4}, "text"), Error);
  // A real module cut inside its first instruction (OpCapability, two words, after the five of
  // the header): that instruction runs past the end.
  const vk::Spirv whole = vk::shader_spirv("radix_count.comp");
  std::vector<uint32_t> cut(whole.words, whole.words + 6);
  ASSERT_EQ(cut[5] >> 16, 2u);
  try {
    vk::reflect_layout({cut.data(), cut.size() * 4}, "cut.spv");
    ADD_FAILURE() << "a cut module was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cut.spv"), std::string::npos) << e.what();
  }
}

TEST(SpirvLayout, EveryComputeShaderBuildsWithTheLayoutItDeclares) {
  // The validation layer reads each module itself and reports a binding the layout lacks or
  // types differently (VUID-VkComputePipelineCreateInfo-layout-07988, -07990).
  vk::ContextOptions options;
  options.validation = true;
  vk::Context ctx(options);
  const std::vector<std::string> names = vk::compute_shader_names();
  EXPECT_GE(names.size(), 20u);
  EXPECT_NE(std::find(names.begin(), names.end(), "tiles_composite.comp:exits"), names.end());
  for (const std::string& name : names) {
    const vk::SpirvLayout layout = vk::reflect_layout(vk::shader_spirv(name), name);
    const vk::ReflectedPipeline pipeline(ctx, name, layout);
    EXPECT_NE(pipeline.pipeline(), VK_NULL_HANDLE) << name;
    EXPECT_EQ(ctx.validation_errors(), 0u) << name << ": " << ctx.last_validation_error();
  }
  // The same check catches a layout that is wrong: the composite without its uniforms, and
  // with them as a storage buffer.
  vk::SpirvLayout wrong =
      vk::reflect_layout(vk::shader_spirv("tiles_composite.comp"), "tiles_composite.comp");
  wrong.bindings.erase(wrong.bindings.begin());
  { const vk::ReflectedPipeline missing(ctx, "tiles_composite.comp", wrong); }
  const uint64_t after_missing = ctx.validation_errors();
  EXPECT_GT(after_missing, 0u);
  wrong = vk::reflect_layout(vk::shader_spirv("tiles_composite.comp"), "tiles_composite.comp");
  wrong.bindings.front().type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  { const vk::ReflectedPipeline retyped(ctx, "tiles_composite.comp", wrong); }
  EXPECT_GT(ctx.validation_errors(), after_missing);
}

TEST(ShaderStatistics, LavapipeSaysItHasNone) {
  vk::ContextOptions options;
  options.shader_statistics = true;
  vk::Context ctx(options);
  if (!ctx.info().lavapipe) GTEST_SKIP() << "not lavapipe: " << ctx.info().name;
  EXPECT_FALSE(ctx.info().shader_statistics);
  try {
    vk::compute_shader_statistics(ctx, "tiles_bin.comp");
    ADD_FAILURE() << "statistics from lavapipe";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("VK_KHR_pipeline_executable_properties"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace linebake
