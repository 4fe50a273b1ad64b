#include "render/vulkan/shaders.hpp"

#include "core/error.hpp"
#include "render/vulkan/context.hpp"

namespace linebake::vk {
namespace {

constexpr uint32_t kTubeVert[] =
#include "tube.vert.inc"
    ;
constexpr uint32_t kOpaqueFrag[] =
#include "opaque.frag.inc"
    ;
constexpr uint32_t kLlGatherFrag[] =
#include "ll_gather.frag.inc"
    ;
constexpr uint32_t kLlResolveComp[] =
#include "ll_resolve.comp.inc"
    ;
constexpr uint32_t kCountFrag[] =
#include "count.frag.inc"
    ;
constexpr uint32_t kDpPeelFrag[] =
#include "dp_peel.frag.inc"
    ;
constexpr uint32_t kDpBlendComp[] =
#include "dp_blend.comp.inc"
    ;
constexpr uint32_t kMlabGatherFrag[] =
#include "mlab_gather.frag.inc"
    ;
constexpr uint32_t kMlabGatherInterlockFrag[] =
#include "mlab_gather_interlock.frag.inc"
    ;
constexpr uint32_t kMlabdbDepthFrag[] =
#include "mlabdb_depth.frag.inc"
    ;
constexpr uint32_t kMlabResolveComp[] =
#include "mlab_resolve.comp.inc"
    ;
constexpr uint32_t kMboitMomentsFrag[] =
#include "mboit_moments.frag.inc"
    ;
constexpr uint32_t kMboitMomentsWideFrag[] =
#include "mboit_moments_wide.frag.inc"
    ;
constexpr uint32_t kMboitColourFrag[] =
#include "mboit_colour.frag.inc"
    ;
constexpr uint32_t kMboitResolveComp[] =
#include "mboit_resolve.comp.inc"
    ;
constexpr uint32_t kVrcComp[] =
#include "vrc.comp.inc"
    ;
constexpr uint32_t kWboitAccumulateFrag[] =
#include "wboit_accumulate.frag.inc"
    ;
constexpr uint32_t kWboitResolveComp[] =
#include "wboit_resolve.comp.inc"
    ;

struct Embedded {
  const char* name;
  Spirv code;
};

template <size_t N>
constexpr Spirv view(const uint32_t (&words)[N]) {
  return {words, sizeof(words)};
}

const Embedded kShaders[] = {
    {"tube.vert", view(kTubeVert)},
    {"opaque.frag", view(kOpaqueFrag)},
    {"ll_gather.frag", view(kLlGatherFrag)},
    {"ll_resolve.comp", view(kLlResolveComp)},
    {"count.frag", view(kCountFrag)},
    {"dp_peel.frag", view(kDpPeelFrag)},
    {"dp_blend.comp", view(kDpBlendComp)},
    {"mlab_gather.frag", view(kMlabGatherFrag)},
    {"mlab_gather_interlock.frag", view(kMlabGatherInterlockFrag)},
    {"mlabdb_depth.frag", view(kMlabdbDepthFrag)},
    {"mlab_resolve.comp", view(kMlabResolveComp)},
    {"mboit_moments.frag", view(kMboitMomentsFrag)},
    {"mboit_moments_wide.frag", view(kMboitMomentsWideFrag)},
    {"mboit_colour.frag", view(kMboitColourFrag)},
    {"mboit_resolve.comp", view(kMboitResolveComp)},
    {"wboit_accumulate.frag", view(kWboitAccumulateFrag)},
    {"wboit_resolve.comp", view(kWboitResolveComp)},
    {"vrc.comp", view(kVrcComp)},
};

}  // namespace

Spirv shader_spirv(const std::string& name) {
  for (const Embedded& e : kShaders)
    if (name == e.name) return e.code;
  throw Error("no embedded shader named '" + name + "'");
}

VkShaderModule create_shader_module(VkDevice device, const std::string& name) {
  const Spirv code = shader_spirv(name);
  VkShaderModuleCreateInfo create{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  create.codeSize = code.size_bytes;
  create.pCode = code.words;
  VkShaderModule module;
  check(vkCreateShaderModule(device, &create, nullptr, &module), "vkCreateShaderModule");
  return module;
}

}  // namespace linebake::vk
