#include "render/vulkan/spirv_layout.hpp"

#include <algorithm>
#include <map>

#include "core/error.hpp"

namespace linebake::vk {
namespace {

// The few opcodes, decorations, storage classes and execution models this reader needs (SPIR-V
// specification, section 3).
enum Op : uint32_t {
  kOpEntryPoint = 15,
  kOpTypeImage = 25,
  kOpTypeSampler = 26,
  kOpTypeSampledImage = 27,
  kOpTypeArray = 28,
  kOpTypeRuntimeArray = 29,
  kOpTypeStruct = 30,
  kOpTypePointer = 32,
  kOpConstant = 43,
  kOpVariable = 59,
  kOpDecorate = 71,
  kOpTypeAccelerationStructureKHR = 5341,
};
enum Decoration : uint32_t {
  kBlock = 2,
  kBufferBlock = 3,
  kArrayStride = 6,
  kBinding = 33,
  kDescriptorSet = 34,
};
enum StorageClass : uint32_t {
  kUniformConstant = 0,
  kUniform = 2,
  kPushConstant = 9,
  kStorageBuffer = 12,
};
constexpr uint32_t kMagic = 0x07230203;
constexpr uint32_t kDimBuffer = 5, kDimSubpassData = 6;

VkShaderStageFlagBits stage_of(uint32_t model) {
  switch (model) {
    case 0:
      return VK_SHADER_STAGE_VERTEX_BIT;
    case 1:
      return VK_SHADER_STAGE_TESSELLATION_CONTROL_BIT;
    case 2:
      return VK_SHADER_STAGE_TESSELLATION_EVALUATION_BIT;
    case 3:
      return VK_SHADER_STAGE_GEOMETRY_BIT;
    case 4:
      return VK_SHADER_STAGE_FRAGMENT_BIT;
    case 5:
      return VK_SHADER_STAGE_COMPUTE_BIT;
    case 5313:
      return VK_SHADER_STAGE_RAYGEN_BIT_KHR;
    case 5314:
      return VK_SHADER_STAGE_INTERSECTION_BIT_KHR;
    case 5315:
      return VK_SHADER_STAGE_ANY_HIT_BIT_KHR;
    case 5316:
      return VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR;
    case 5317:
      return VK_SHADER_STAGE_MISS_BIT_KHR;
    case 5318:
      return VK_SHADER_STAGE_CALLABLE_BIT_KHR;
    default:
      return VK_SHADER_STAGE_ALL;
  }
}

// One instruction's words: the opcode's and its operands.
struct Instruction {
  uint32_t opcode;
  const uint32_t* operands;
  uint32_t operand_count;
};

}  // namespace

uint32_t SpirvLayout::set_count() const {
  uint32_t count = 0;
  for (const SpirvBinding& b : bindings) count = std::max(count, b.set + 1);
  return count;
}

SpirvLayout reflect_layout(const Spirv& code, const std::string& name) {
  const auto fail = [&](const std::string& why) -> Error {
    return Error("shader " + name + ": " + why);
  };
  const uint32_t* words = code.words;
  const size_t count = code.size_bytes / 4;
  if (count < 5 || words[0] != kMagic) throw fail("not a SPIR-V module");
  std::vector<Instruction> instructions;
  for (size_t at = 5; at < count;) {
    const uint32_t length = words[at] >> 16;
    if (length == 0 || at + length > count)
      throw fail("instruction at word " + std::to_string(at) + " runs past the module's end");
    instructions.push_back({words[at] & 0xFFFFu, words + at + 1, length - 1});
    at += length;
  }

  SpirvLayout layout;
  bool entry_seen = false;
  std::map<uint32_t, uint32_t> set_of, binding_of, constant, array_stride;
  std::map<uint32_t, uint32_t> last_member;  // struct type id: its last member's type id
  std::map<uint32_t, bool> buffer_block;     // struct id: BufferBlock (or Block)
  std::map<uint32_t, std::pair<uint32_t, uint32_t>> array;  // id: element type, length id
  std::map<uint32_t, uint32_t> pointee;                     // pointer type id: pointee type id
  std::map<uint32_t, VkDescriptorType> opaque;              // image, sampler, AS type ids
  struct Variable {
    uint32_t id, pointer_type, storage;
  };
  std::vector<Variable> variables;
  for (const Instruction& in : instructions) {
    const uint32_t* o = in.operands;
    const uint32_t n = in.operand_count;
    if (in.opcode == kOpEntryPoint && n >= 1 && !entry_seen) {
      layout.stage = stage_of(o[0]);
      entry_seen = true;
    } else if (in.opcode == kOpDecorate && n >= 2) {
      if (o[1] == kDescriptorSet && n >= 3) set_of[o[0]] = o[2];
      if (o[1] == kBinding && n >= 3) binding_of[o[0]] = o[2];
      if (o[1] == kBlock) buffer_block.emplace(o[0], false);
      if (o[1] == kBufferBlock) buffer_block[o[0]] = true;
      if (o[1] == kArrayStride && n >= 3) array_stride[o[0]] = o[2];
    } else if (in.opcode == kOpConstant && n >= 3) {
      constant[o[1]] = o[2];
    } else if (in.opcode == kOpTypeArray && n >= 3) {
      array[o[0]] = {o[1], o[2]};
    } else if (in.opcode == kOpTypeRuntimeArray && n >= 2) {
      array[o[0]] = {o[1], 0};
    } else if (in.opcode == kOpTypeStruct && n >= 2) {
      last_member[o[0]] = o[n - 1];
    } else if (in.opcode == kOpTypePointer && n >= 3) {
      pointee[o[0]] = o[2];
    } else if (in.opcode == kOpTypeImage && n >= 7) {
      const bool storage = o[6] == 2;
      opaque[o[0]] = o[2] == kDimSubpassData ? VK_DESCRIPTOR_TYPE_INPUT_ATTACHMENT
                     : o[2] == kDimBuffer    ? (storage ? VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER
                                                        : VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER)
                     : storage               ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE
                                             : VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE;
    } else if (in.opcode == kOpTypeSampler && n >= 1) {
      opaque[o[0]] = VK_DESCRIPTOR_TYPE_SAMPLER;
    } else if (in.opcode == kOpTypeSampledImage && n >= 1) {
      opaque[o[0]] = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
    } else if (in.opcode == kOpTypeAccelerationStructureKHR && n >= 1) {
      opaque[o[0]] = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;
    } else if (in.opcode == kOpVariable && n >= 3) {
      variables.push_back({o[1], o[0], o[2]});
    }
  }
  if (!entry_seen) throw fail("no entry point");

  for (const Variable& v : variables) {
    if (v.storage == kPushConstant) layout.push_constants = true;
    if (v.storage != kUniformConstant && v.storage != kUniform && v.storage != kStorageBuffer)
      continue;
    const auto set = set_of.find(v.id), binding = binding_of.find(v.id);
    if (set == set_of.end() || binding == binding_of.end()) continue;
    const auto pointer = pointee.find(v.pointer_type);
    if (pointer == pointee.end())
      throw fail("variable %" + std::to_string(v.id) + " is not of a pointer type");
    SpirvBinding b{set->second, binding->second};
    uint32_t type = pointer->second;
    // An array of descriptors: its length from the constant.
    if (const auto a = array.find(type); a != array.end()) {
      if (a->second.second == 0)
        throw fail("binding " + std::to_string(b.binding) +
                   " is a runtime array of descriptors, which this reader does not size");
      const auto length = constant.find(a->second.second);
      if (length == constant.end())
        throw fail("binding " + std::to_string(b.binding) +
                   " has an array length that is not "
                   "a plain constant (a specialisation constant?)");
      b.count = length->second;
      type = a->second.first;
    }
    if (const auto member = last_member.find(type); member != last_member.end()) {
      const auto a = array.find(member->second);
      const auto stride = array_stride.find(member->second);
      if (a != array.end() && a->second.second == 0 && stride != array_stride.end())
        b.array_stride = stride->second;
    }
    if (v.storage == kStorageBuffer) {
      b.type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    } else if (v.storage == kUniform) {
      const auto block = buffer_block.find(type);
      if (block == buffer_block.end())
        throw fail("binding " + std::to_string(b.binding) + " is a uniform that is not a block");
      b.type =
          block->second ? VK_DESCRIPTOR_TYPE_STORAGE_BUFFER : VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
    } else {
      const auto kind = opaque.find(type);
      if (kind == opaque.end())
        throw fail("binding " + std::to_string(b.binding) +
                   " is of a kind this reader does not "
                   "know");
      b.type = kind->second;
    }
    layout.bindings.push_back(b);
  }
  std::sort(layout.bindings.begin(), layout.bindings.end(),
            [](const SpirvBinding& a, const SpirvBinding& b) {
              return a.set != b.set ? a.set < b.set : a.binding < b.binding;
            });
  return layout;
}

}  // namespace linebake::vk
