#pragma once
// The object-order techniques on Vulkan: the cached tube mesh drawn headless (dynamic rendering,
// no window) with the rendering core's camera, transfer function and Blinn-Phong shading, so
// images compare with the CPU ray tracer's. Techniques: `opaque` (depth-tested) and `ll`
// (per-pixel linked lists: gather every fragment, sort per pixel, blend front to back; the node
// buffer grows and the frame is re-rendered when it overflows, never dropping fragments).

#include <memory>
#include <string>
#include <vector>

#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/ray_tracer.hpp"
#include "render/transfer_function.hpp"
#include "render/vulkan/context.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake::vk {

enum class RasterTechnique { Opaque, LinkedLists };
RasterTechnique parse_raster_technique(const std::string& name);  // opaque | ll
const char* to_string(RasterTechnique technique);

// Per-pixel sort of the linked-list resolve (techniques.md section 3).
enum class ListSort { Insertion, Shell, Heap };
ListSort parse_list_sort(const std::string& name);  // insertion | shell | heap
const char* to_string(ListSort sort);

struct RasterOptions {
  RasterTechnique technique = RasterTechnique::LinkedLists;
  int width = 1280, height = 720;
  ListSort sort = ListSort::Heap;
  // Node capacity of the fragment buffer; 0: expected mean depth complexity x pixels.
  uint64_t capacity = 0;
  double expected_depth_complexity = 20;  // the public presets: 20 (<= 1M segments), 120 above
  bool early_termination = false;
  double termination_alpha = 0.99;
  Shading shading;
};

struct RasterStats {
  double seconds = 0;  // wall time of the frame, re-renders included
  std::vector<std::pair<std::string, double>> pass_ms;  // GPU timestamps of the final render
  uint64_t frame_bytes = 0;  // the technique's per-frame buffers and images
  uint64_t fragments = 0;    // fragments gathered (linked lists)
  uint64_t capacity = 0;     // node capacity used for the final render
  int regrows = 0;           // re-renders after an overflow of the node buffer
  uint32_t max_depth_complexity = 0;
  double mean_depth_complexity = 0;
};

struct RasterFrame {
  Image image;                             // linear RGB
  std::vector<uint32_t> depth_complexity;  // fragments per pixel (linked lists)
  RasterStats stats;
};

class RasterRenderer {
 public:
  // Uploads the mesh (every chunk its own vertex and index buffers, drawn in chunk order).
  RasterRenderer(Context& context, const TubeMesh& mesh);
  RasterRenderer(const RasterRenderer&) = delete;
  RasterRenderer& operator=(const RasterRenderer&) = delete;
  ~RasterRenderer();

  RasterFrame render(const Camera& camera, const TransferFunction& tf,
                     const RasterOptions& options);

  uint64_t mesh_bytes() const;

  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace linebake::vk
