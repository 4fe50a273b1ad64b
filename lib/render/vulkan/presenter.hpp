#pragma once
// Shows finished frames in a window: a swapchain on a window surface, into whose images each
// frame is copied (transfer, no pipeline). Every technique, the CPU ones included, reaches the
// screen the same way, so what the window shows is exactly the image the technique produced.

#include <vulkan/vulkan.h>

#include <cstdint>

#include "render/image.hpp"
#include "render/vulkan/context.hpp"

namespace linebake::vk {

class Presenter {
 public:
  // Takes ownership of `surface` (made on context.instance(); the context needs
  // ContextOptions::swapchain). Throws Error when the context's queue cannot present to it.
  Presenter(Context& context, VkSurfaceKHR surface);
  Presenter(const Presenter&) = delete;
  Presenter& operator=(const Presenter&) = delete;
  ~Presenter();

  // Copies `frame` (linear or sRGB-encoded; encoded on the way) to the top-left of the next
  // swapchain image, clears the rest, and presents it. `width` x `height` is the window's
  // framebuffer size: the swapchain is rebuilt when it changes or the surface reports it stale.
  // A zero-size (minimised) window presents nothing.
  void present(const Image& frame, int width, int height);

 private:
  void create_swapchain(int width, int height);
  void destroy_swapchain();

  Context& context_;
  VkSurfaceKHR surface_ = VK_NULL_HANDLE;
  VkSwapchainKHR swapchain_ = VK_NULL_HANDLE;
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  VkExtent2D extent_{0, 0};
  uint32_t image_count_ = 0;
  VkImage images_[8] = {};
  VkFence acquired_ = VK_NULL_HANDLE;
  Buffer staging_;
  bool stale_ = false;
};

}  // namespace linebake::vk
