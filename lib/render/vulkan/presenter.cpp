#include "render/vulkan/presenter.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/transfer_function.hpp"

namespace linebake::vk {
namespace {

VkImageMemoryBarrier layout_change(VkImage image, VkImageLayout from, VkImageLayout to,
                                   VkAccessFlags src, VkAccessFlags dst) {
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.srcAccessMask = src;
  b.dstAccessMask = dst;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image;
  b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  return b;
}

}  // namespace

Presenter::Presenter(Context& context, VkSurfaceKHR surface)
    : context_(context), surface_(surface) {
  VkBool32 supported = VK_FALSE;
  vkGetPhysicalDeviceSurfaceSupportKHR(context.physical_device(), context.queue_family(), surface,
                                       &supported);
  if (!supported) {
    vkDestroySurfaceKHR(context.instance(), surface_, nullptr);
    throw Error("Vulkan: " + context.info().name + "'s queue cannot present to this window");
  }
  VkFenceCreateInfo fence{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  check(vkCreateFence(context.device(), &fence, nullptr, &acquired_), "vkCreateFence");
}

Presenter::~Presenter() {
  vkDeviceWaitIdle(context_.device());
  destroy_swapchain();
  context_.destroy(staging_);
  vkDestroyFence(context_.device(), acquired_, nullptr);
  vkDestroySurfaceKHR(context_.instance(), surface_, nullptr);
}

void Presenter::destroy_swapchain() {
  if (swapchain_) vkDestroySwapchainKHR(context_.device(), swapchain_, nullptr);
  swapchain_ = VK_NULL_HANDLE;
  image_count_ = 0;
}

void Presenter::create_swapchain(int width, int height) {
  VkPhysicalDevice physical = context_.physical_device();
  VkSurfaceCapabilitiesKHR caps;
  check(vkGetPhysicalDeviceSurfaceCapabilitiesKHR(physical, surface_, &caps),
        "vkGetPhysicalDeviceSurfaceCapabilitiesKHR");
  if (!(caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_DST_BIT))
    throw Error("Vulkan: the window's swapchain images cannot be transfer destinations");
  uint32_t count = 0;
  vkGetPhysicalDeviceSurfaceFormatsKHR(physical, surface_, &count, nullptr);
  std::vector<VkSurfaceFormatKHR> formats(count);
  vkGetPhysicalDeviceSurfaceFormatsKHR(physical, surface_, &count, formats.data());
  // Frames arrive sRGB-encoded and are copied byte for byte, so any 8-bit RGBA/BGRA format
  // shows them right: the display takes the bytes as sRGB either way.
  format_ = VK_FORMAT_UNDEFINED;
  VkColorSpaceKHR colour_space = VK_COLOR_SPACE_SRGB_NONLINEAR_KHR;
  for (VkFormat wanted : {VK_FORMAT_B8G8R8A8_UNORM, VK_FORMAT_B8G8R8A8_SRGB,
                          VK_FORMAT_R8G8B8A8_UNORM, VK_FORMAT_R8G8B8A8_SRGB})
    for (const VkSurfaceFormatKHR& f : formats)
      if (format_ == VK_FORMAT_UNDEFINED && f.format == wanted) {
        format_ = f.format;
        colour_space = f.colorSpace;
      }
  if (format_ == VK_FORMAT_UNDEFINED) throw Error("Vulkan: the window has no 8-bit RGBA format");
  extent_ = caps.currentExtent;
  if (extent_.width == 0xFFFFFFFFu) {
    extent_.width =
        std::clamp(uint32_t(width), caps.minImageExtent.width, caps.maxImageExtent.width);
    extent_.height =
        std::clamp(uint32_t(height), caps.minImageExtent.height, caps.maxImageExtent.height);
  }
  VkSwapchainCreateInfoKHR create{VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR};
  create.surface = surface_;
  create.minImageCount = std::max(caps.minImageCount, 2u);
  if (caps.maxImageCount > 0)
    create.minImageCount = std::min(create.minImageCount, caps.maxImageCount);
  create.imageFormat = format_;
  create.imageColorSpace = colour_space;
  create.imageExtent = extent_;
  create.imageArrayLayers = 1;
  create.imageUsage = VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  create.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
  create.preTransform = caps.currentTransform;
  create.compositeAlpha = VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR;
  for (VkCompositeAlphaFlagBitsKHR a :
       {VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR, VK_COMPOSITE_ALPHA_INHERIT_BIT_KHR,
        VK_COMPOSITE_ALPHA_PRE_MULTIPLIED_BIT_KHR, VK_COMPOSITE_ALPHA_POST_MULTIPLIED_BIT_KHR})
    if (caps.supportedCompositeAlpha & a) {
      create.compositeAlpha = a;
      break;
    }
  create.presentMode = VK_PRESENT_MODE_FIFO_KHR;  // always supported
  create.clipped = VK_TRUE;
  create.oldSwapchain = swapchain_;
  VkSwapchainKHR created = VK_NULL_HANDLE;
  check(vkCreateSwapchainKHR(context_.device(), &create, nullptr, &created),
        "vkCreateSwapchainKHR");
  destroy_swapchain();
  swapchain_ = created;
  vkGetSwapchainImagesKHR(context_.device(), swapchain_, &image_count_, nullptr);
  image_count_ = std::min<uint32_t>(image_count_, 8);
  vkGetSwapchainImagesKHR(context_.device(), swapchain_, &image_count_, images_);
  stale_ = false;
}

void Presenter::present(const Image& frame, int width, int height) {
  if (width <= 0 || height <= 0) return;
  if (!swapchain_ || stale_ || extent_.width != uint32_t(width) ||
      extent_.height != uint32_t(height)) {
    vkDeviceWaitIdle(context_.device());
    create_swapchain(width, height);
  }
  // The frame as 8-bit sRGB in the swapchain's byte order.
  const uint32_t w = std::min<uint32_t>(uint32_t(frame.width), extent_.width);
  const uint32_t h = std::min<uint32_t>(uint32_t(frame.height), extent_.height);
  const uint64_t bytes = std::max<uint64_t>(uint64_t(w) * h * 4, 4);
  if (staging_.size < bytes) {
    context_.destroy(staging_);
    staging_ = context_.create_buffer(bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  }
  const bool bgr = format_ == VK_FORMAT_B8G8R8A8_UNORM || format_ == VK_FORMAT_B8G8R8A8_SRGB;
  auto* out = static_cast<uint8_t*>(staging_.mapped);
  const auto byte = [&](int x, int y, int c) {
    const float v = frame.channels == 1 ? frame.at(x, y, 0) : frame.at(x, y, c);
    const double encoded = frame.srgb_encoded ? double(v) : linear_to_srgb(double(v));
    return uint8_t(std::lround(std::clamp(encoded, 0.0, 1.0) * 255.0));
  };
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      uint8_t* p = out + (uint64_t(y) * w + x) * 4;
      const uint8_t r = byte(int(x), int(y), 0), g = byte(int(x), int(y), 1),
                    b = byte(int(x), int(y), 2);
      p[0] = bgr ? b : r;
      p[1] = g;
      p[2] = bgr ? r : b;
      p[3] = 255;
    }
  uint32_t index = 0;
  VkResult acquired = vkAcquireNextImageKHR(context_.device(), swapchain_, UINT64_MAX,
                                            VK_NULL_HANDLE, acquired_, &index);
  if (acquired == VK_ERROR_OUT_OF_DATE_KHR) {
    stale_ = true;
    return;  // the next frame rebuilds the swapchain
  }
  if (acquired != VK_SUBOPTIMAL_KHR) check(acquired, "vkAcquireNextImageKHR");
  check(vkWaitForFences(context_.device(), 1, &acquired_, VK_TRUE, UINT64_MAX), "vkWaitForFences");
  check(vkResetFences(context_.device(), 1, &acquired_), "vkResetFences");
  VkImage image = images_[index];
  context_.submit([&](VkCommandBuffer cmd) {
    VkImageMemoryBarrier to_transfer =
        layout_change(image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0,
                      VK_ACCESS_TRANSFER_WRITE_BIT);
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                         0, nullptr, 0, nullptr, 1, &to_transfer);
    const VkClearColorValue black{{0, 0, 0, 1}};
    const VkImageSubresourceRange all{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdClearColorImage(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &black, 1, &all);
    VkImageMemoryBarrier cleared = layout_change(
        image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
        VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0,
                         nullptr, 0, nullptr, 1, &cleared);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {w, h, 1};
    if (w > 0 && h > 0)
      vkCmdCopyBufferToImage(cmd, staging_.buffer, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                             &region);
    VkImageMemoryBarrier to_present =
        layout_change(image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR,
                      VK_ACCESS_TRANSFER_WRITE_BIT, 0);
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT,
                         0, 0, nullptr, 0, nullptr, 1, &to_present);
  });
  // The copy has finished (submit waits), so the present needs no semaphore.
  VkPresentInfoKHR info{VK_STRUCTURE_TYPE_PRESENT_INFO_KHR};
  info.swapchainCount = 1;
  info.pSwapchains = &swapchain_;
  info.pImageIndices = &index;
  const VkResult presented = vkQueuePresentKHR(context_.queue(), &info);
  if (presented == VK_ERROR_OUT_OF_DATE_KHR || presented == VK_SUBOPTIMAL_KHR)
    stale_ = true;
  else
    check(presented, "vkQueuePresentKHR");
}

}  // namespace linebake::vk
