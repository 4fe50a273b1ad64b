#pragma once
// What the viewer draws with: one source per technique, each rendering a camera view of the
// cached assets into an image and reporting the technique's own frame time and per-frame memory.
// The same library calls as `linebake render`, so a view matches a render of the same camera.

#include <memory>
#include <optional>
#include <string>

#include "cache/cache.hpp"
#include "lines/line_set.hpp"
#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/transfer_function.hpp"
#include "render/vulkan/context.hpp"

namespace linebake::cli {

struct ViewFrame {
  Image image;  // linear RGB
  double seconds = 0;
  uint64_t frame_bytes = 0;
};

class ViewSource {
 public:
  virtual ~ViewSource() = default;
  virtual ViewFrame render(const Camera& camera, const TransferFunction& tf, int width,
                           int height) = 0;
  // The box `linebake render` frames its flight around for this technique.
  virtual Bounds bounds() const = 0;
  // Before the first frame at a window size: throws BudgetExceeded, as `linebake render` does,
  // when the technique's estimate of a frame that size passes the memory budget; else keeps the
  // frame's image in the Vulkan context's reserve (vk::Context::set_host_reserve).
  virtual void fit_frame(int width, int height) = 0;
};

// The techniques the viewer cycles through, in order.
const std::vector<std::string>& view_techniques();

// A source for `technique` (a view_techniques() name) over `cache`, prepared for frames of
// `width` x `height` (the window's); the Vulkan techniques render on `context`, every technique
// within `memory_budget` (--memory-budget's text). Throws Error naming what is missing (an
// asset, a device feature) or does not fit.
std::unique_ptr<ViewSource> make_view_source(const std::string& technique, const CacheReader& cache,
                                             vk::Context& context, int width, int height,
                                             const std::string& memory_budget = "");

}  // namespace linebake::cli
