#include "render/vulkan/context.hpp"

#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>

#include "core/error.hpp"
#include "core/measure.hpp"
#include "core/memory_budget.hpp"

namespace linebake::vk {
namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

bool has_extension(VkPhysicalDevice device, const char* name) {
  uint32_t count = 0;
  vkEnumerateDeviceExtensionProperties(device, nullptr, &count, nullptr);
  std::vector<VkExtensionProperties> extensions(count);
  vkEnumerateDeviceExtensionProperties(device, nullptr, &count, extensions.data());
  return std::any_of(extensions.begin(), extensions.end(), [&](const VkExtensionProperties& e) {
    return std::strcmp(e.extensionName, name) == 0;
  });
}

bool has_layer(const char* name) {
  uint32_t count = 0;
  vkEnumerateInstanceLayerProperties(&count, nullptr);
  std::vector<VkLayerProperties> layers(count);
  vkEnumerateInstanceLayerProperties(&count, layers.data());
  return std::any_of(layers.begin(), layers.end(), [&](const VkLayerProperties& l) {
    return std::strcmp(l.layerName, name) == 0;
  });
}

DeviceInfo describe(VkPhysicalDevice device) {
  VkPhysicalDeviceIDProperties id{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ID_PROPERTIES};
  VkPhysicalDeviceSubgroupProperties subgroups{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES, &id};
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES,
                                          &subgroups};
  VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2, &driver};
  vkGetPhysicalDeviceProperties2(device, &props);
  DeviceInfo info;
  info.name = props.properties.deviceName;
  info.driver = driver.driverName;
  info.lavapipe = info.driver.find("llvmpipe") != std::string::npos ||
                  info.name.find("llvmpipe") != std::string::npos;
  info.type = props.properties.deviceType;
  info.api_version = props.properties.apiVersion;
  info.fragment_shader_interlock = has_extension(device, "VK_EXT_fragment_shader_interlock");
  info.ray_tracing = has_extension(device, "VK_KHR_ray_tracing_pipeline") &&
                     has_extension(device, "VK_KHR_acceleration_structure") &&
                     has_extension(device, "VK_KHR_deferred_host_operations");
  info.shader_statistics = has_extension(device, "VK_KHR_pipeline_executable_properties");
  info.subgroup_size = subgroups.subgroupSize;
  const VkSubgroupFeatureFlags wanted = VK_SUBGROUP_FEATURE_BASIC_BIT |
                                        VK_SUBGROUP_FEATURE_BALLOT_BIT |
                                        VK_SUBGROUP_FEATURE_ARITHMETIC_BIT;
  info.subgroup_ballot_arithmetic = (subgroups.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT) &&
                                    (subgroups.supportedOperations & wanted) == wanted;
  std::copy(std::begin(id.driverUUID), std::end(id.driverUUID), info.driver_uuid.begin());
  return info;
}

VkInstance create_instance(bool validation, const std::vector<std::string>& wanted = {}) {
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "linebake";
  app.apiVersion = VK_API_VERSION_1_3;
  VkInstanceCreateInfo create{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  create.pApplicationInfo = &app;
  const char* layers[] = {kValidationLayer};
  std::vector<const char*> extensions;
  for (const std::string& e : wanted) extensions.push_back(e.c_str());
  if (validation) {
    if (!has_layer(kValidationLayer))
      throw Error(
          "Vulkan: validation requested but VK_LAYER_KHRONOS_validation is not installed "
          "(vulkan-validationlayers)");
    create.enabledLayerCount = 1;
    create.ppEnabledLayerNames = layers;
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  create.enabledExtensionCount = uint32_t(extensions.size());
  create.ppEnabledExtensionNames = extensions.data();
  VkInstance instance = VK_NULL_HANDLE;
  const VkResult r = vkCreateInstance(&create, nullptr, &instance);
  // A driver that cannot be loaded for lack of address space is "no driver" to the loader.
  const uint64_t left = address_space_left();
  const std::string limited =
      left == UINT64_MAX
          ? std::string()
          : " (or it could not load: ulimit -v leaves this process " + format_bytes(left) +
                " of address space, and loading lavapipe takes about 150 MiB)";
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER)
    throw Error("Vulkan: no Vulkan driver found (install mesa-vulkan-drivers for lavapipe)" +
                limited);
  if (r != VK_SUCCESS && !limited.empty())
    throw Error("Vulkan: vkCreateInstance failed (VkResult " + std::to_string(int(r)) + ")" +
                limited);
  check(r, "vkCreateInstance");
  return instance;
}

// lavapipe (Mesa 22.3) frees memory twice when an allocation fails inside vkCreateDevice, and the
// process aborts; under ulimit -v that is where it fails, as its device reserves address space
// for each worker thread (a malloc arena and a stack). Measured on the development VM through
// /proc/self/status VmSize, its growth across vkCreateDevice: 148 MiB without worker threads,
// 292 with 1, 436 with 2, 1,108 with 8. So refuse first. lavapipe starts a thread for each CPU the
// process may run on (its affinity: 8 CPUs under `taskset -c 0-7`), none where that is one, or
// LP_NUM_THREADS.
void check_lavapipe_address_space() {
  const uint64_t left = address_space_left();
  if (left == UINT64_MAX) return;
  cpu_set_t cpus;
  CPU_ZERO(&cpus);
  long threads = ::sched_getaffinity(0, sizeof cpus, &cpus) == 0 ? long(CPU_COUNT(&cpus))
                                                                 : ::sysconf(_SC_NPROCESSORS_ONLN);
  if (threads <= 1) threads = 0;
  if (const char* lp = std::getenv("LP_NUM_THREADS")) threads = std::strtol(lp, nullptr, 10);
  threads = std::clamp(threads, 0L, 32L);
  const uint64_t needed = (192ull + 128ull * uint64_t(threads)) << 20;
  if (left < needed)
    throw BudgetExceeded("Vulkan: lavapipe's device needs about " + format_bytes(needed) +
                         " of address space (" + std::to_string(threads) +
                         " worker threads; LP_NUM_THREADS sets how many), but ulimit -v leaves "
                         "this process " +
                         format_bytes(left) + "; raise ulimit -v or lower LP_NUM_THREADS");
}

std::vector<VkPhysicalDevice> physical_devices(VkInstance instance) {
  uint32_t count = 0;
  check(vkEnumeratePhysicalDevices(instance, &count, nullptr), "vkEnumeratePhysicalDevices");
  std::vector<VkPhysicalDevice> devices(count);
  check(vkEnumeratePhysicalDevices(instance, &count, devices.data()), "vkEnumeratePhysicalDevices");
  return devices;
}

}  // namespace

std::string to_hex(const std::array<uint8_t, 16>& uuid) {
  static const char* digits = "0123456789abcdef";
  std::string out;
  for (uint8_t b : uuid) out += digits[b >> 4], out += digits[b & 15];
  return out;
}

void check(VkResult result, const char* what) {
  if (result != VK_SUCCESS)
    throw Error(std::string("Vulkan: ") + what + " failed (VkResult " +
                std::to_string(int(result)) + ")");
}

std::vector<DeviceInfo> list_devices() {
  VkInstance instance = create_instance(false);
  std::vector<DeviceInfo> out;
  try {
    for (VkPhysicalDevice d : physical_devices(instance)) out.push_back(describe(d));
  } catch (...) {
    vkDestroyInstance(instance, nullptr);
    throw;
  }
  vkDestroyInstance(instance, nullptr);
  return out;
}

VKAPI_ATTR VkBool32 VKAPI_CALL Context::on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                   VkDebugUtilsMessageTypeFlagsEXT /*types*/,
                                                   const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                   void* user) {
  auto* self = static_cast<Context*>(user);
  if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
    ++self->validation_errors_;
    self->last_validation_error_ = data && data->pMessage ? data->pMessage : "";
  }
  return VK_FALSE;
}

Context::Context(const ContextOptions& options) {
  instance_ = create_instance(options.validation, options.instance_extensions);
  try {
    if (options.validation) {
      auto create_messenger = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
          vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
      VkDebugUtilsMessengerCreateInfoEXT m{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
      m.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT |
                          VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT;
      m.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                      VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT;
      m.pfnUserCallback = &Context::on_message;
      m.pUserData = this;
      if (create_messenger)
        check(create_messenger(instance_, &m, nullptr, &messenger_), "debug messenger");
    }
    // The device: the named one, else the first discrete GPU, else the first device.
    const auto devices = physical_devices(instance_);
    std::string names;
    for (VkPhysicalDevice d : devices) {
      const DeviceInfo info = describe(d);
      names += (names.empty() ? "" : ", ") + info.name;
      const bool wanted = options.device.empty()
                              ? info.type == VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU
                              : info.name.find(options.device) != std::string::npos;
      if (wanted && !physical_) physical_ = d, info_ = info;
    }
    if (!physical_ && options.device.empty() && !devices.empty())
      physical_ = devices.front(), info_ = describe(physical_);
    // A name no device has is a wrong --device (exit 1), none at all this machine's lack (4).
    if (!physical_ && !options.device.empty())
      throw UsageError("--device: no Vulkan device named '" + options.device + "' (have: " + names +
                       ")");
    if (!physical_) throw Error("Vulkan: no device found");
    if (VK_API_VERSION_MINOR(info_.api_version) < 3 && VK_API_VERSION_MAJOR(info_.api_version) == 1)
      throw Error("Vulkan: " + info_.name + " supports Vulkan " +
                  std::to_string(VK_API_VERSION_MAJOR(info_.api_version)) + "." +
                  std::to_string(VK_API_VERSION_MINOR(info_.api_version)) + "; 1.3 is needed");

    uint32_t count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical_, &count, nullptr);
    std::vector<VkQueueFamilyProperties> families(count);
    vkGetPhysicalDeviceQueueFamilyProperties(physical_, &count, families.data());
    const VkQueueFlags needed = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
    family_ = count;
    for (uint32_t i = 0; i < count; ++i)
      if ((families[i].queueFlags & needed) == needed) {
        family_ = i;
        break;
      }
    if (family_ == count) throw Error("Vulkan: " + info_.name + " has no graphics+compute queue");
    timestamps_ = families[family_].timestampValidBits > 0;
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(physical_, &props);
    timestamp_period_ns_ = props.limits.timestampPeriod;

    if (options.ray_tracing && !info_.ray_tracing)
      throw RayTracingUnsupported(
          "ray tracing is not supported on this device (" + info_.name +
          "): it needs VK_KHR_ray_tracing_pipeline and VK_KHR_acceleration_structure");
    VkPhysicalDeviceAccelerationStructureFeaturesKHR supported_as{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
    VkPhysicalDeviceRayTracingPipelineFeaturesKHR supported_rt{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR, &supported_as};
    VkPhysicalDeviceFragmentShaderInterlockFeaturesEXT supported_interlock{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FRAGMENT_SHADER_INTERLOCK_FEATURES_EXT};
    VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR supported_statistics{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
    VkPhysicalDeviceVulkan12Features supported12{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceVulkan13Features supported13{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES, &supported12};
    // Queried chain: 1.3 -> (interlock) -> 1.2 -> (ray tracing -> acceleration structures)
    // -> (executable properties).
    if (info_.fragment_shader_interlock) {
      supported_interlock.pNext = &supported12;
      supported13.pNext = &supported_interlock;
    }
    void** chain_tail = &supported12.pNext;
    if (options.ray_tracing) *chain_tail = &supported_rt, chain_tail = &supported_as.pNext;
    if (options.shader_statistics && info_.shader_statistics) *chain_tail = &supported_statistics;
    VkPhysicalDeviceFeatures2 supported{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, &supported13};
    vkGetPhysicalDeviceFeatures2(physical_, &supported);
    if (!supported.features.fragmentStoresAndAtomics || !supported13.dynamicRendering)
      throw Error("Vulkan: " + info_.name + " lacks fragmentStoresAndAtomics or dynamicRendering");
    if (options.ray_tracing &&
        (!supported_rt.rayTracingPipeline || !supported_as.accelerationStructure ||
         !supported12.bufferDeviceAddress))
      throw RayTracingUnsupported("ray tracing is not supported on this device (" + info_.name +
                                  "): the ray tracing pipeline, acceleration structure or "
                                  "buffer device address feature is off");
    // MLAB's ordered critical section; without it the shaders fall back to a spin lock.
    info_.fragment_shader_interlock =
        info_.fragment_shader_interlock && supported_interlock.fragmentShaderPixelInterlock;
    info_.compute_full_subgroups = supported13.computeFullSubgroups;
    info_.shader_int64 = supported.features.shaderInt64;
    info_.shader_statistics = options.shader_statistics && info_.shader_statistics &&
                              supported_statistics.pipelineExecutableInfo;
    ray_tracing_ = options.ray_tracing;
    // Integrated and CPU devices share their memory with the host: no staging copy there.
    staging_piece_bytes_ = std::max<uint64_t>(options.staging_piece_bytes / 4 * 4, 4);
    if (!options.force_staging && (info_.type == VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU ||
                                   info_.type == VK_PHYSICAL_DEVICE_TYPE_CPU)) {
      VkPhysicalDeviceMemoryProperties memory;
      vkGetPhysicalDeviceMemoryProperties(physical_, &memory);
      const VkMemoryPropertyFlags shared = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT |
                                           VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                           VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
      for (uint32_t i = 0; i < memory.memoryTypeCount; ++i)
        in_place_uploads_ |= (memory.memoryTypes[i].propertyFlags & shared) == shared;
    }

    // The features enabled: a chain built from the end.
    std::vector<const char*> device_extensions;
    VkPhysicalDeviceAccelerationStructureFeaturesKHR as_features{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR};
    as_features.accelerationStructure = VK_TRUE;
    VkPhysicalDeviceRayTracingPipelineFeaturesKHR rt_features{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR, &as_features};
    rt_features.rayTracingPipeline = VK_TRUE;
    VkPhysicalDeviceFragmentShaderInterlockFeaturesEXT interlock{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FRAGMENT_SHADER_INTERLOCK_FEATURES_EXT};
    interlock.fragmentShaderPixelInterlock = VK_TRUE;
    VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR statistics{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
    statistics.pipelineExecutableInfo = VK_TRUE;
    VkPhysicalDeviceVulkan12Features features12{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
    VkPhysicalDeviceVulkan13Features features13{
        VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES, &features12};
    features13.dynamicRendering = VK_TRUE;
    features13.computeFullSubgroups = info_.compute_full_subgroups ? VK_TRUE : VK_FALSE;
    void* chain_end = nullptr;
    if (info_.fragment_shader_interlock) {
      device_extensions.push_back("VK_EXT_fragment_shader_interlock");
      interlock.pNext = chain_end;
      chain_end = &interlock;
    }
    if (ray_tracing_) {
      for (const char* e : {"VK_KHR_acceleration_structure", "VK_KHR_ray_tracing_pipeline",
                            "VK_KHR_deferred_host_operations"})
        device_extensions.push_back(e);
      features12.bufferDeviceAddress = VK_TRUE;
      as_features.pNext = chain_end;
      chain_end = &rt_features;
    }
    if (info_.shader_statistics) {
      device_extensions.push_back("VK_KHR_pipeline_executable_properties");
      statistics.pNext = chain_end;
      chain_end = &statistics;
    }
    if (options.swapchain) {
      if (!has_extension(physical_, VK_KHR_SWAPCHAIN_EXTENSION_NAME))
        throw Error("Vulkan: " + info_.name + " cannot present to a window (no VK_KHR_swapchain)");
      device_extensions.push_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
    }
    features12.pNext = chain_end;
    VkPhysicalDeviceFeatures features{};
    features.fragmentStoresAndAtomics = VK_TRUE;
    features.shaderInt64 = info_.shader_int64 ? VK_TRUE : VK_FALSE;
    const float priority = 1;
    VkDeviceQueueCreateInfo queue{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    queue.queueFamilyIndex = family_;
    queue.queueCount = 1;
    queue.pQueuePriorities = &priority;
    VkDeviceCreateInfo create{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    create.queueCreateInfoCount = 1;
    create.pQueueCreateInfos = &queue;
    create.pEnabledFeatures = &features;
    create.pNext = &features13;
    create.enabledExtensionCount = uint32_t(device_extensions.size());
    create.ppEnabledExtensionNames = device_extensions.data();
    if (info_.lavapipe) check_lavapipe_address_space();
    check(vkCreateDevice(physical_, &create, nullptr, &device_), "vkCreateDevice");
    compile_only_ = options.compile_only;
    if (compile_only_) return;
    vkGetDeviceQueue(device_, family_, 0, &queue_);
    VkCommandPoolCreateInfo pool{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pool.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
    pool.queueFamilyIndex = family_;
    check(vkCreateCommandPool(device_, &pool, nullptr, &pool_), "vkCreateCommandPool");
    VkFenceCreateInfo fence{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    check(vkCreateFence(device_, &fence, nullptr, &fence_), "vkCreateFence");
  } catch (...) {
    release();
    throw;
  }
}

Context::~Context() {
  release();
}

void Context::release() {
  if (device_) {
    if (!compile_only_) vkDeviceWaitIdle(device_);
    if (fence_) vkDestroyFence(device_, fence_, nullptr);
    if (pool_) vkDestroyCommandPool(device_, pool_, nullptr);
    vkDestroyDevice(device_, nullptr);
    device_ = VK_NULL_HANDLE;
  }
  if (messenger_) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(instance_, messenger_, nullptr);
    messenger_ = VK_NULL_HANDLE;
  }
  if (instance_) vkDestroyInstance(instance_, nullptr);
  instance_ = VK_NULL_HANDLE;
}

uint32_t Context::memory_type(uint32_t type_bits, VkMemoryPropertyFlags properties) const {
  VkPhysicalDeviceMemoryProperties memory;
  vkGetPhysicalDeviceMemoryProperties(physical_, &memory);
  for (uint32_t i = 0; i < memory.memoryTypeCount; ++i)
    if ((type_bits & (1u << i)) && (memory.memoryTypes[i].propertyFlags & properties) == properties)
      return i;
  throw Error("Vulkan: no suitable memory type");
}

Buffer Context::create_buffer(uint64_t size, VkBufferUsageFlags usage, bool host_visible) {
  Buffer b;
  b.size = std::max<uint64_t>(size, 4);
  VkBufferCreateInfo create{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  create.size = b.size;
  create.usage = usage;
  create.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  check(vkCreateBuffer(device_, &create, nullptr, &b.buffer), "vkCreateBuffer");
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(device_, b.buffer, &req);
  VkMemoryAllocateFlagsInfo flags{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
  flags.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
  VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  if (usage & VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT) alloc.pNext = &flags;
  alloc.allocationSize = req.size;
  try {
    const VkMemoryPropertyFlags host =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    if (!host_visible) {
      alloc.memoryTypeIndex = memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    } else {
      // Device-local memory the host can write where uploads go in place (lavapipe, integrated
      // GPUs); else host-cached where offered, as results are read back by the CPU.
      const VkMemoryPropertyFlags preferred =
          in_place_uploads_ && (usage & VK_BUFFER_USAGE_TRANSFER_SRC_BIT) == 0
              ? host | VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT
              : host | VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
      try {
        alloc.memoryTypeIndex = memory_type(req.memoryTypeBits, preferred);
      } catch (const Error&) {
        alloc.memoryTypeIndex = memory_type(req.memoryTypeBits, host);
      }
    }
    b.memory = allocate_memory(alloc, b.host_bytes);
    check(vkBindBufferMemory(device_, b.buffer, b.memory, 0), "vkBindBufferMemory");
    if (host_visible)
      check(vkMapMemory(device_, b.memory, 0, VK_WHOLE_SIZE, 0, &b.mapped), "vkMapMemory");
  } catch (...) {
    destroy(b);
    throw;
  }
  return b;
}

VkDeviceAddress Context::address(const Buffer& b) const {
  VkBufferDeviceAddressInfo info{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
  info.buffer = b.buffer;
  return vkGetBufferDeviceAddress(device_, &info);
}

Buffer Context::create_filled(uint64_t bytes, VkBufferUsageFlags usage, const Filler& write) {
  const uint64_t size = std::max<uint64_t>((bytes + 3) / 4 * 4, 4);
  if (in_place_uploads_) {
    Buffer out = create_buffer(size, usage, true);
    try {
      auto* dst = static_cast<uint8_t*>(out.mapped);
      if (bytes > 0) write(dst, 0, bytes);
      std::memset(dst + bytes, 0, size - bytes);
    } catch (...) {
      destroy(out);
      throw;
    }
    return out;
  }
  const uint64_t piece = std::min(size, staging_piece_bytes_);
  Buffer staging = create_buffer(piece, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  Buffer out;
  try {
    out = create_buffer(size, usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
    auto* dst = static_cast<uint8_t*>(staging.mapped);
    for (uint64_t offset = 0; offset < size; offset += piece) {
      const uint64_t count = std::min(piece, size - offset);
      const uint64_t data = offset < bytes ? std::min(count, bytes - offset) : 0;
      if (data > 0) write(dst, offset, data);
      std::memset(dst + data, 0, count - data);
      submit([&](VkCommandBuffer cmd) {
        const VkBufferCopy region{0, offset, count};
        vkCmdCopyBuffer(cmd, staging.buffer, out.buffer, 1, &region);
        VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        barrier.dstAccessMask = VK_ACCESS_MEMORY_READ_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, 0, 1, &barrier, 0, nullptr, 0,
                             nullptr);
      });
    }
  } catch (...) {
    destroy(staging);
    destroy(out);
    throw;
  }
  destroy(staging);
  return out;
}

Buffer Context::upload(const void* data, uint64_t bytes, VkBufferUsageFlags usage) {
  return create_filled(bytes, usage, [data](void* dst, uint64_t offset, uint64_t count) {
    std::memcpy(dst, static_cast<const uint8_t*>(data) + offset, count);
  });
}

void Context::destroy(Buffer& b) {
  if (b.buffer) vkDestroyBuffer(device_, b.buffer, nullptr);
  free_memory(b.memory, b.host_bytes);
  b = Buffer{};
}

bool Context::memory_is_host() const {
  return info_.type == VK_PHYSICAL_DEVICE_TYPE_CPU ||
         info_.type == VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU;
}

// What allocations may hold under `b` with its reserve: the room left beside the reserve.
static uint64_t host_limit(const Context::HostBudget& b) {
  if (b.total == 0) return Context::kNoHostLimit;
  return b.held + (b.room > b.reserved ? b.room - b.reserved : 0);
}

uint64_t Context::set_host_budget(uint64_t total, uint64_t reserved, uint64_t compile) {
  HostBudget b;
  b.total = total, b.reserved = reserved + compile, b.compile = compile;
  b.serial = ++host_budgets_set_;
  if (total > 0) {
    const uint64_t resident = trimmed_rss_bytes();  // freed memory still in the heap is not held
    b.held = host_bytes_;
    b.room = total > resident ? total - resident : 0;
  }
  b.limit = host_limit(b);
  host_budget_ = b;
  return b.serial;
}

Context::HostBudget Context::host_budget_state() const {
  return host_budget_;
}

void Context::restore_host_budget(uint64_t serial, const HostBudget& previous) {
  if (serial == host_budget_.serial) host_budget_ = previous;
}

void Context::set_host_reserve(uint64_t reserved) {
  host_budget_.reserved = reserved + host_budget_.compile;
  host_budget_.limit = host_limit(host_budget_);
}

uint64_t Context::first_draw_compile_bytes() const {
  return info_.lavapipe ? uint64_t{96} << 20 : 0;
}

void Context::drop_compile_reserve() {
  host_budget_.reserved -= std::min(host_budget_.compile, host_budget_.reserved);
  host_budget_.compile = 0;
  host_budget_.limit = host_limit(host_budget_);
}

uint64_t Context::host_bytes_left() const {
  const HostBudget& b = host_budget_;
  if (b.total == 0) return kNoHostLimit;
  // What the reserve's own allocations hold is resident and counted already.
  const uint64_t credit = reserve_credit(), limit = b.limit + credit;
  const uint64_t used = current_rss_bytes() + (b.reserved - credit);
  const uint64_t process = b.total > used ? b.total - used : 0;
  return std::min(process, limit > host_bytes_ ? limit - host_bytes_ : 0);
}

// ", and N is kept for the frame's outputs (and M for ...)": what the reserve holds back.
std::string Context::kept_for() const {
  const HostBudget& b = host_budget_;
  const uint64_t outputs = b.reserved - std::min(b.compile, b.reserved);
  const uint64_t kept = outputs - std::min(reserve_credit(), outputs);
  std::string out;
  if (kept > 0) out = ", and " + format_bytes(kept) + " is kept for the frame's outputs";
  if (b.compile > 0)
    out += (out.empty() ? ", and " : " and ") + format_bytes(b.compile) +
           " for the driver's shader compiles at the first draw";
  return out;
}

VkDeviceMemory Context::allocate_memory(const VkMemoryAllocateInfo& info, uint64_t& host_bytes) {
  VkPhysicalDeviceMemoryProperties memory;
  vkGetPhysicalDeviceMemoryProperties(physical_, &memory);
  const uint32_t heap = memory.memoryTypes[info.memoryTypeIndex].heapIndex;
  const bool host =
      memory_is_host() || (memory.memoryHeaps[heap].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT) == 0;
  host_bytes = host ? info.allocationSize : 0;
  // Device memory freed before (lavapipe's comes from malloc) can stay resident in the C
  // library's heap: it is given back before the resident count refuses.
  const auto refused = [&] { return host_bytes > 0 && host_bytes > host_bytes_left(); };
  if (reserved_scopes_ == 0 && refused()) trimmed_rss_bytes();
  if (reserved_scopes_ == 0 && refused())
    throw HostBudgetExceeded(
        "Vulkan: allocating " + format_bytes(host_bytes) + " on " + info_.name +
        (memory_is_host() ? ", whose memory is this machine's," : " in host memory") +
        " would pass the memory budget of " + format_bytes(host_budget_.total) +
        " (the device's allocations hold " + format_bytes(host_bytes_) + ", the process " +
        format_bytes(current_rss_bytes()) + " resident" + kept_for() + ")");
  VkDeviceMemory out = VK_NULL_HANDLE;
  const VkResult r = vkAllocateMemory(device_, &info, nullptr, &out);
  if (r == VK_ERROR_OUT_OF_DEVICE_MEMORY || r == VK_ERROR_OUT_OF_HOST_MEMORY)
    throw Error("Vulkan: out of memory allocating " + std::to_string(info.allocationSize) +
                " bytes on " + info_.name);
  check(r, "vkAllocateMemory");
  host_bytes_ += host_bytes;
  if (reserved_scopes_ > 0 && host_bytes > 0) {
    reserve_allocations_.emplace_back(out, host_bytes);
    reserve_taken_ += host_bytes;
  }
  return out;
}

void Context::free_memory(VkDeviceMemory memory, uint64_t host_bytes) {
  if (!memory) return;
  vkFreeMemory(device_, memory, nullptr);
  host_bytes_ -= std::min(host_bytes, host_bytes_);
  const auto taken = std::find_if(reserve_allocations_.begin(), reserve_allocations_.end(),
                                  [&](const auto& a) { return a.first == memory; });
  if (taken != reserve_allocations_.end()) {
    reserve_taken_ -= taken->second;
    reserve_allocations_.erase(taken);
  }
}

void Context::destroy(ResultBuffer& r) {
  destroy(r.gpu);
  destroy(r.host);
}

ResultBuffer Context::create_result(uint64_t size, VkBufferUsageFlags usage) {
  usage |= VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  ResultBuffer r;
  r.gpu = create_buffer(size, usage, in_place_uploads_);
  if (in_place_uploads_) return r;
  try {
    r.host = create_buffer(r.gpu.size, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  } catch (...) {
    destroy(r);
    throw;
  }
  return r;
}

const void* Context::read_back(const ResultBuffer& r, uint64_t bytes) {
  if (r.gpu.mapped) return r.gpu.mapped;
  const uint64_t count = std::min(bytes, r.gpu.size);
  if (count > 0)
    submit([&](VkCommandBuffer cmd) {
      // The writes of earlier submissions (shaders, copies, fills) become visible to the copy,
      // and the copy to the host.
      VkMemoryBarrier before{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
      before.srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT;
      before.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
      vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                           0, 1, &before, 0, nullptr, 0, nullptr);
      const VkBufferCopy region{0, 0, count};
      vkCmdCopyBuffer(cmd, r.gpu.buffer, r.host.buffer, 1, &region);
      VkMemoryBarrier after{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
      after.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      after.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
      vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                           &after, 0, nullptr, 0, nullptr);
    });
  return r.host.mapped;
}

VkQueryPool Context::create_timestamp_pair() {
  if (!timestamps_) return VK_NULL_HANDLE;
  VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  q.queryType = VK_QUERY_TYPE_TIMESTAMP;
  q.queryCount = 2;
  VkQueryPool pool = VK_NULL_HANDLE;
  check(vkCreateQueryPool(device_, &q, nullptr, &pool), "vkCreateQueryPool (timestamps)");
  return pool;
}

void Context::write_first_timestamp(VkCommandBuffer cmd, VkQueryPool pair) {
  vkCmdResetQueryPool(cmd, pair, 0, 2);
  vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, pair, 0);
}

double Context::elapsed_ms(VkQueryPool pair) const {
  if (!pair) return 0;
  uint64_t ticks[2] = {};
  if (vkGetQueryPoolResults(device_, pair, 0, 2, sizeof ticks, ticks, 8,
                            VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) != VK_SUCCESS)
    return 0;
  return double(ticks[1] - ticks[0]) * timestamp_period_ns_ * 1e-6;
}

VkCommandBuffer Context::begin_commands() {
  if (compile_only_)
    throw Error("Vulkan: a context made to compile pipelines only cannot record commands");
  VkCommandBufferAllocateInfo alloc{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  alloc.commandPool = pool_;
  alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  alloc.commandBufferCount = 1;
  VkCommandBuffer cmd;
  check(vkAllocateCommandBuffers(device_, &alloc, &cmd), "vkAllocateCommandBuffers");
  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
  return cmd;
}

void Context::end_and_wait(VkCommandBuffer cmd) {
  check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &cmd;
  check(vkResetFences(device_, 1, &fence_), "vkResetFences");
  check(vkQueueSubmit(queue_, 1, &submit, fence_), "vkQueueSubmit");
  const VkResult r = vkWaitForFences(device_, 1, &fence_, VK_TRUE, UINT64_MAX);
  vkFreeCommandBuffers(device_, pool_, 1, &cmd);
  check(r, "vkWaitForFences");
}

}  // namespace linebake::vk
