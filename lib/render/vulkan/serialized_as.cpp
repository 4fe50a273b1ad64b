#include "render/vulkan/serialized_as.hpp"

#include <algorithm>
#include <cstring>

#include "core/error.hpp"
#include "render/vulkan/context.hpp"

namespace linebake::vk {
namespace {

uint64_t read_u64(std::span<const uint8_t> blob, size_t offset) {
  uint64_t value = 0;  // little endian, as every Vulkan ray tracing device writes it
  for (size_t k = 0; k < 8; ++k) value |= uint64_t(blob[offset + k]) << (8 * k);
  return value;
}

}  // namespace

SerializedAsHeader parse_serialized_as(std::span<const uint8_t> blob) {
  if (blob.size() < kSerializedAsHeaderBytes)
    throw Error("serialised acceleration structure: " + std::to_string(blob.size()) +
                " bytes, shorter than its " + std::to_string(kSerializedAsHeaderBytes) +
                "-byte header");
  SerializedAsHeader h;
  std::copy_n(blob.begin(), 16, h.driver_uuid.begin());
  std::copy_n(blob.begin() + 16, 16, h.compatibility.begin());
  h.serialized_size = read_u64(blob, 32);
  h.deserialized_size = read_u64(blob, 40);
  h.handle_count = read_u64(blob, 48);
  const uint64_t minimum = kSerializedAsHeaderBytes + 8 * h.handle_count;
  if (h.handle_count > (uint64_t(1) << 40) || h.serialized_size < minimum)
    throw Error("serialised acceleration structure: the header's size " +
                std::to_string(h.serialized_size) + " cannot hold its " +
                std::to_string(h.handle_count) + " handles");
  if (h.serialized_size != blob.size())
    throw Error("serialised acceleration structure: the header says " +
                std::to_string(h.serialized_size) + " bytes, the blob has " +
                std::to_string(blob.size()));
  if (h.deserialized_size == 0)
    throw Error("serialised acceleration structure: the deserialised size is 0");
  return h;
}

std::optional<std::string> serialized_as_problem(std::span<const uint8_t> blob,
                                                 const std::array<uint8_t, 16>& driver_uuid) {
  SerializedAsHeader h;
  try {
    h = parse_serialized_as(blob);
  } catch (const Error& e) {
    return std::string(e.what());
  }
  if (h.driver_uuid != driver_uuid)
    return "it was written by driver " + to_hex(h.driver_uuid) + ", this device's driver is " +
           to_hex(driver_uuid);
  if (h.handle_count != 0) return std::string("it is a top-level structure, not a BLAS");
  return std::nullopt;
}

}  // namespace linebake::vk
