#pragma once
// A headless Vulkan 1.3 device for the rasterisation techniques: instance (with the Khronos
// validation layer on request, its errors counted), the device choice (a named one, else a
// discrete GPU, else any, lavapipe included), one queue for graphics and compute, and the few
// helpers every technique needs: buffers, one-shot command submission, timestamps.

#include <vulkan/vulkan.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/error.hpp"

namespace linebake::vk {

// Throws linebake::Error naming the call and the VkResult.
void check(VkResult result, const char* what);

struct ContextOptions {
  std::string device;       // substring of the device name; "" picks a discrete GPU, else any
  bool validation = false;  // enable VK_LAYER_KHRONOS_validation (must be installed)
  // Enable VK_KHR_acceleration_structure + VK_KHR_ray_tracing_pipeline and buffer device
  // addresses; the Context throws RayTracingUnsupported on a device without them.
  bool ray_tracing = false;
  // A window's needs (the viewer): the instance extensions its surface takes (GLFW's list) and
  // VK_KHR_swapchain on the device.
  std::vector<std::string> instance_extensions;
  bool swapchain = false;
};

// The chosen device cannot ray trace (lavapipe, older GPUs): the message is the one line users see.
class RayTracingUnsupported : public Error {
 public:
  using Error::Error;
};

struct DeviceInfo {
  std::string name, driver;
  VkPhysicalDeviceType type = VK_PHYSICAL_DEVICE_TYPE_OTHER;
  uint32_t api_version = 0;
  bool fragment_shader_interlock = false;
  bool ray_tracing = false;  // VK_KHR_ray_tracing_pipeline + VK_KHR_acceleration_structure
  std::array<uint8_t, 16> driver_uuid{};  // VkPhysicalDeviceIDProperties::driverUUID
};

// "0123abcd..." (32 hex digits).
std::string to_hex(const std::array<uint8_t, 16>& uuid);

// Names every Vulkan device the loader sees (for `--device` and error messages).
std::vector<DeviceInfo> list_devices();

struct Buffer {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  uint64_t size = 0;
  void* mapped = nullptr;  // host-visible buffers stay mapped
};

class Context {
 public:
  explicit Context(const ContextOptions& options = {});
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;
  ~Context();

  const DeviceInfo& info() const { return info_; }
  VkInstance instance() const { return instance_; }
  VkDevice device() const { return device_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return family_; }
  double timestamp_period_ns() const { return timestamp_period_ns_; }
  bool timestamps() const { return timestamps_; }
  // Validation-layer messages of severity error seen so far (0 without validation).
  uint64_t validation_errors() const { return validation_errors_; }
  const std::string& last_validation_error() const { return last_validation_error_; }

  // Host-visible, coherent buffers: simple and enough for lavapipe and for readbacks; device-
  // local ones for the large per-frame arrays on GPUs.
  Buffer create_buffer(uint64_t size, VkBufferUsageFlags usage, bool host_visible);
  // With ray tracing enabled: the buffer's device address (it needs
  // VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT; create_buffer allocates such buffers with the
  // device-address flag).
  VkDeviceAddress address(const Buffer& buffer) const;
  // A device-local buffer holding `bytes` of `data` (through a staging buffer; usage gains
  // TRANSFER_DST). Sizes round up to 4 bytes.
  Buffer upload(const void* data, uint64_t bytes, VkBufferUsageFlags usage);
  bool ray_tracing() const { return ray_tracing_; }
  void destroy(Buffer& buffer);
  uint32_t memory_type(uint32_t type_bits, VkMemoryPropertyFlags properties) const;

  // Records `record` into a fresh command buffer, submits it and waits.
  template <class Record>
  void submit(Record&& record) {
    VkCommandBuffer cmd = begin_commands();
    record(cmd);
    end_and_wait(cmd);
  }

  // Two timestamp queries for timing one submission, or VK_NULL_HANDLE when the queue has no
  // timestamps (the caller destroys the pool); elapsed_ms reads them (0 without a pool).
  VkQueryPool create_timestamp_pair();
  double elapsed_ms(VkQueryPool pair) const;

  VkCommandBuffer begin_commands();
  void end_and_wait(VkCommandBuffer cmd);

 private:
  static VKAPI_ATTR VkBool32 VKAPI_CALL on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                   VkDebugUtilsMessageTypeFlagsEXT types,
                                                   const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                   void* user);
  void release();
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
  uint32_t family_ = 0;
  double timestamp_period_ns_ = 1;
  bool timestamps_ = false;
  bool ray_tracing_ = false;
  DeviceInfo info_;
  uint64_t validation_errors_ = 0;
  std::string last_validation_error_;
};

}  // namespace linebake::vk
