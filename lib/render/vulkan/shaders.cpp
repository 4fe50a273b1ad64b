#include "render/vulkan/shaders.hpp"

#include "core/error.hpp"

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

template <size_t N>
Spirv view(const uint32_t (&words)[N]) {
  return {words, sizeof(words)};
}

}  // namespace

Spirv shader_spirv(const std::string& name) {
  if (name == "tube.vert") return view(kTubeVert);
  if (name == "opaque.frag") return view(kOpaqueFrag);
  if (name == "ll_gather.frag") return view(kLlGatherFrag);
  if (name == "ll_resolve.comp") return view(kLlResolveComp);
  throw Error("no embedded shader named '" + name + "'");
}

}  // namespace linebake::vk
