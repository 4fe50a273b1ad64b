#pragma once
// A headless Vulkan 1.3 device for the rasterisation techniques: instance (with the Khronos
// validation layer on request, its errors counted), the device choice (a named one, else a
// discrete GPU, else any, lavapipe included), one queue for graphics and compute, and the few
// helpers every technique needs: buffers, one-shot command submission, timestamps.

#include <vulkan/vulkan.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
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
  // Uploads to device-local memory go through one staging buffer of this many bytes (rounded
  // down to 4), piece by piece: never a second full copy of the mesh in host memory.
  uint64_t staging_piece_bytes = uint64_t{64} << 20;
  // Stage even where device-local memory is host-visible (tests of the staged path on lavapipe).
  bool force_staging = false;
  // Enable VK_KHR_pipeline_executable_properties where the device has it, so that pipelines can
  // report their compiler's statistics (shader_statistics.hpp; DeviceInfo::shader_statistics).
  bool shader_statistics = false;
  // A device that only compiles pipelines: no command pool or fence, nothing submitted (RADV's
  // null device, RADV_FORCE_FAMILY without the GPU, compiles but has no queue to run on).
  bool compile_only = false;
};

// An allocation refused by the memory budget (Context::set_host_budget).
class HostBudgetExceeded : public BudgetExceeded {
 public:
  using BudgetExceeded::BudgetExceeded;
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
  // Mesa's lavapipe (llvmpipe): the CPU driver of the tests, whose limits and quirks some passes
  // work around (its loop limit, its held-back timestamps, its SIMD units' branches).
  bool lavapipe = false;
  // Compute-stage subgroups: their size (VkPhysicalDeviceSubgroupProperties::subgroupSize, what
  // a compute pipeline gets unless it asks for another), whether basic, ballot and arithmetic
  // operations are there, and whether a pipeline may require full subgroups (Vulkan 1.3's
  // computeFullSubgroups: known, and enabled, once a Context has made the device).
  uint32_t subgroup_size = 0;
  bool subgroup_ballot_arithmetic = false;
  bool compute_full_subgroups = false;
  // 64-bit integers in shaders (shaderInt64: known, and enabled, once a Context has made the
  // device).
  bool shader_int64 = false;
  // The compiler's statistics of a pipeline (VK_KHR_pipeline_executable_properties): whether the
  // device has them; in a Context, whether they are enabled (ContextOptions::shader_statistics).
  bool shader_statistics = false;
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
  void* mapped = nullptr;   // host-visible buffers stay mapped
  uint64_t host_bytes = 0;  // what its memory takes of the machine's (Context::host_bytes)
};

// A buffer the GPU writes and the host reads (images, per-pixel counts, counters). On a GPU with
// memory of its own `gpu` is device-local, so shader writes and atomics stay in video memory
// rather than crossing PCIe, and `host` is a host-cached mirror that Context::read_back fills by
// a copy; where device-local memory is the host's (lavapipe, integrated GPUs) `gpu` is mapped and
// `host` stays empty.
struct ResultBuffer {
  Buffer gpu;   // what shaders bind and commands fill
  Buffer host;  // the mirror, or empty
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

  // Host-visible, coherent buffers (host-cached where the device offers it, for readbacks):
  // uniforms and results; device-local ones for the large per-frame arrays on GPUs.
  Buffer create_buffer(uint64_t size, VkBufferUsageFlags usage, bool host_visible);
  // With ray tracing enabled: the buffer's device address (it needs
  // VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT; create_buffer allocates such buffers with the
  // device-address flag).
  VkDeviceAddress address(const Buffer& buffer) const;
  // Writes bytes [offset, offset + count) of a buffer's content to `dst`.
  using Filler = std::function<void(void* dst, uint64_t offset, uint64_t count)>;
  // A device-local buffer of `bytes` (rounded up to 4, the padding zero) filled by `write`, piece
  // by piece through one staging buffer (usage gains TRANSFER_DST), or written in place where
  // device-local memory is also host-visible (lavapipe, integrated GPUs; see force_staging).
  Buffer create_filled(uint64_t bytes, VkBufferUsageFlags usage, const Filler& write);
  // create_filled with a copy of `data`.
  Buffer upload(const void* data, uint64_t bytes, VkBufferUsageFlags usage);
  // Whether create_filled writes device-local memory in place (no staging copy).
  bool uploads_in_place() const { return in_place_uploads_; }
  bool ray_tracing() const { return ray_tracing_; }
  // A ResultBuffer of `size` bytes (usage gains TRANSFER_SRC and TRANSFER_DST, for the readback
  // copy and for clearing with vkCmdFillBuffer).
  ResultBuffer create_result(uint64_t size, VkBufferUsageFlags usage);
  // The host's view of bytes [0, bytes) of a result, after the GPU work that wrote them has been
  // waited for: the mapped buffer itself, or the mirror after a copy (one submission, waited for).
  const void* read_back(const ResultBuffer& result, uint64_t bytes = VK_WHOLE_SIZE);
  void destroy(Buffer& buffer);
  void destroy(ResultBuffer& result);
  uint32_t memory_type(uint32_t type_bits, VkMemoryPropertyFlags properties) const;

  // The machine's memory that this Context's allocations hold: all of them where the device's
  // memory is the host's (lavapipe, integrated GPUs), else those from heaps that are not
  // device-local (staging buffers, readback mirrors).
  uint64_t host_bytes() const { return host_bytes_; }
  // Whether every allocation is of the machine's memory (device type CPU or integrated GPU).
  bool memory_is_host() const;
  static constexpr uint64_t kNoHostLimit = UINT64_MAX;
  // Holds those allocations within --memory-budget: `total` bytes of resident memory for the
  // whole process (0: no budget), of which `reserved` are kept for what the host holds besides
  // (a frame's image). From this call on an allocation is refused with BudgetExceeded and the
  // figures when the host_bytes() would pass what the budget left at the call (the process's
  // resident memory then counted as held: the techniques call it once their data is loaded), or
  // when the process's resident memory with it would pass the budget. Allocated memory is
  // resident only once written, so neither count alone is enough.
  // `compile` more are kept, until drop_compile_reserve(), for what the driver takes itself to
  // compile a graphics pipeline's shaders at its first draw (first_draw_compile_bytes()).
  // Returns the budget's number, for restore_host_budget.
  uint64_t set_host_budget(uint64_t total, uint64_t reserved = 0, uint64_t compile = 0);
  // What the driver takes of the machine's memory, beside any allocation, to compile a graphics
  // pipeline's shaders at its first draw: lavapipe compiles them with LLVM then, 60 to 80 MiB
  // resident at the peak on Mesa 22.3 (every raster technique, frames of 32x18 to 1280x720; the
  // same with one rasteriser thread), of which about 40 stay; 96 MiB are kept. 0 elsewhere (not
  // measured).
  uint64_t first_draw_compile_bytes() const;
  // The first draw has compiled: the budget in force no longer keeps room for it.
  void drop_compile_reserve();
  // The budget in force (the default: none), and putting it back: `previous` is put back only
  // if the budget in force is still the one numbered `serial`. A technique that goes puts back
  // the budget it found; one whose preparation fails so puts back the budget of the technique
  // the viewer keeps, and one that goes after a later one set its own leaves that in force.
  struct HostBudget {
    uint64_t total = 0, reserved = 0, limit = kNoHostLimit, serial = 0;
    uint64_t compile = 0;  // of `reserved`: for the first draw's shader compiles
    // At the call: what the device's allocations held, and the budget less the process's
    // resident memory (0 where none was left). The limit is held + room - reserved, at least
    // held, whatever reserve set_host_reserve gives it later.
    uint64_t held = 0, room = 0;
  };
  HostBudget host_budget_state() const;
  void restore_host_budget(uint64_t serial, const HostBudget& previous);
  // While one lives, allocations are counted but not refused: for what the budget's reserve
  // holds already (the viewer's copy of a frame for its window, part of frame_output_bytes).
  // Until freed they are taken from the reserve (up to its size), so they are not counted a
  // second time against what other allocations may hold.
  class ReservedAllocations {
   public:
    explicit ReservedAllocations(Context& context) : context_(context) {
      ++context_.reserved_scopes_;
    }
    ~ReservedAllocations() { --context_.reserved_scopes_; }
    ReservedAllocations(const ReservedAllocations&) = delete;
    ReservedAllocations& operator=(const ReservedAllocations&) = delete;

   private:
    Context& context_;
  };
  // Changes the budget in force's reserve for what the host holds besides (the viewer's window
  // grown or shrunk: its frame's image); what allocations may take moves by the change. Its
  // number stays.
  void set_host_reserve(uint64_t reserved);
  uint64_t host_budget() const { return host_budget_.total; }
  // What one allocation may still take of the host's memory (kNoHostLimit without a budget).
  uint64_t host_bytes_left() const;
  // vkAllocateMemory within the limit: `host_bytes` gets what it took of the machine's memory
  // (for free_memory). Out-of-memory results are an Error naming the bytes and the device.
  VkDeviceMemory allocate_memory(const VkMemoryAllocateInfo& info, uint64_t& host_bytes);
  void free_memory(VkDeviceMemory memory, uint64_t host_bytes);

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
  // Submits `record` between the two timestamps of `pair` (none without a pool), waits, and
  // returns the milliseconds between them. On lavapipe the first timestamp goes in a submission
  // of its own: once a raster pass has run on the device, lavapipe holds a top-of-pipe
  // timestamp back for its rasteriser's next flush, which comes after the commands it should
  // precede (tiles' bin pass, timed after `ll` in one bench, read 0.0-0.2 ms instead of 16 to
  // 184). Elsewhere one submission, so no host round trip is timed.
  template <class Record>
  double timed_submit(VkQueryPool pair, Record&& record) {
    const bool apart = pair && info_.lavapipe;
    if (apart) submit([&](VkCommandBuffer cmd) { write_first_timestamp(cmd, pair); });
    submit([&](VkCommandBuffer cmd) {
      if (pair && !apart) write_first_timestamp(cmd, pair);
      record(cmd);
      if (pair) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pair, 1);
    });
    return elapsed_ms(pair);
  }

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
  static void write_first_timestamp(VkCommandBuffer cmd, VkQueryPool pair);
  bool timestamps_ = false;
  bool ray_tracing_ = false;
  bool compile_only_ = false;
  bool in_place_uploads_ = false;
  uint64_t staging_piece_bytes_ = 0;
  uint64_t host_bytes_ = 0;
  HostBudget host_budget_;   // in force
  int reserved_scopes_ = 0;  // live ReservedAllocations
  // Host bytes of the live allocations made in such a scope, and their memory (few: the
  // presenter's staging buffer).
  uint64_t reserve_taken_ = 0;
  std::vector<std::pair<VkDeviceMemory, uint64_t>> reserve_allocations_;
  uint64_t reserve_credit() const { return std::min(reserve_taken_, host_budget_.reserved); }
  std::string kept_for() const;
  uint64_t host_budgets_set_ = 0;  // numbers them
  DeviceInfo info_;
  uint64_t validation_errors_ = 0;
  std::string last_validation_error_;
};

}  // namespace linebake::vk
