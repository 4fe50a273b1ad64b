#pragma once
// The object-order techniques on Vulkan (techniques.md sections 1-7): the cached tube mesh drawn
// headless (dynamic rendering, no window) with the rendering core's camera, transfer function and
// Blinn-Phong shading, so images compare with the CPU ray tracer's.
//   opaque  depth-tested, the paper's opaque setting
//   dp      depth peeling: a counting pass finds the layers, then one pass per layer (exact)
//   ll      per-pixel linked lists: gather every fragment, sort per pixel, blend front to back;
//           the node buffer grows and the frame is re-rendered on overflow (exact)
//   mlab    multi-layer alpha blending, k nodes per pixel (interlock, else a spin lock)
//   mlabdb  MLAB with depth buckets: a front bucket and k-1 back nodes, opaque cut-off
//   mboit   moment-based OIT: 4, 6 or 8 power moments or 2, 3 or 4 trigonometric moments
//   wboit   weighted blended OIT, the cheap baseline

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/ray_tracer.hpp"
#include "render/transfer_function.hpp"
#include "render/vulkan/context.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake::vk {

enum class RasterTechnique { Opaque, DepthPeeling, LinkedLists, Mlab, MlabBuckets, Mboit, Wboit };
// opaque | dp | ll | mlab | mlabdb | mboit | wboit
RasterTechnique parse_raster_technique(const std::string& name);
// The fewest --layers a technique takes (mlab 1, mlabdb 2: a front bucket and a back node; the
// others none); at most 64.
int min_layers(RasterTechnique technique);
const char* to_string(RasterTechnique technique);
bool is_raster_technique(const std::string& name);

// Per-pixel sort of the linked-list resolve (techniques.md section 3).
enum class ListSort { Insertion, Shell, Heap, QuickHybrid };
// insertion | shell | heap | quick-hybrid (quicksort, insertion sort below 16)
ListSort parse_list_sort(const std::string& name);
const char* to_string(ListSort sort);

// MBOIT's moments (techniques.md section 6): powers of the warped depth, or points on the unit
// circle (trigonometric moments, better for many layers at the same storage).
enum class MomentBasis { Power, Trigonometric };
// power | trigonometric
MomentBasis parse_moment_basis(const std::string& name);
const char* to_string(MomentBasis basis);
// The moment bias for float32 storage that MBOIT's authors and the paper's code use:
// power 5e-7 / 5e-6 / 5e-5 and trigonometric 4e-7 / 8e-6 / 1.5e-5 for 4 / 6 / 8 moments.
double default_moment_bias(MomentBasis basis, int moments);

struct RasterOptions {
  RasterTechnique technique = RasterTechnique::LinkedLists;
  int width = 1280, height = 720;
  ListSort sort = ListSort::Heap;
  // Node capacity of the fragment buffer; 0: expected mean depth complexity x pixels.
  uint64_t capacity = 0;
  // ll nodes: 24 bytes (float colour) or 12 (RGBA8 colour, as LineVis), in as many storage
  // buffers (at most 16) as the pool needs, each at most max_buffer_bytes (0: the device's
  // maxStorageBufferRange; lower it to test the split).
  uint32_t node_bytes = 24;
  uint64_t max_buffer_bytes = 0;
  double expected_depth_complexity = 20;  // the public presets: 20 (<= 1M segments), 120 above
  bool early_termination = false;         // ll: stop the resolve at termination_alpha
  double termination_alpha = 0.99;
  int max_layers = 2000;  // dp: at most this many layers (the public code's cap)
  // mlab / mlabdb: nodes per pixel k; 0 picks the defaults, 8 for mlab and 4 for mlabdb
  // (1 front bucket + 3 back nodes, the paper's runs).
  int layers = 0;
  double tau_alpha = 0.2, tau_opaque = 0.98;  // mlabdb bucket thresholds
  double mboit_beta = 0.1;                    // overestimation (MBOIT's authors suggest 0.25)
  MomentBasis moment_basis = MomentBasis::Power;
  // mboit: real moments beyond b0, 4, 6 or 8 (trigonometric: 2, 3 or 4 complex moments).
  int moments = 4;
  std::optional<double> mboit_bias;  // unset: default_moment_bias(moment_basis, moments)
  int wboit_weight = 0;   // 0: the public code's weight; 7, 8, 9: McGuire & Bavoil's equations
  bool interlock = true;  // mlab / mlabdb: use fragment shader interlock when the device has it
  Shading shading;
};

struct RasterStats {
  double seconds = 0;  // wall time of the frame, re-renders included
  std::vector<std::pair<std::string, double>> pass_ms;  // GPU timestamps of the final render
  uint64_t frame_bytes = 0;   // the technique's per-frame buffers and images
  uint64_t fragments = 0;     // fragments gathered (ll), or counted (dp, fragment counts)
  uint64_t capacity = 0;      // node capacity used for the final render
  uint32_t node_buffers = 0;  // ll: storage buffers the node pool took
  int regrows = 0;            // re-renders after an overflow of the node buffer
  uint32_t max_depth_complexity = 0;
  double mean_depth_complexity = 0;
  int layers = 0;                // dp: layers peeled; mlab / mlabdb: nodes per pixel
  bool layers_capped = false;    // dp: the depth complexity exceeded max_layers
  std::string critical_section;  // mlab / mlabdb: "interlock" or "spin lock"
};

struct RasterFrame {
  Image image;               // linear RGB, background included
  std::vector<float> alpha;  // the technique's total opacity per pixel
  // Fragments per pixel: every front fragment (dp, count_fragments), those stored (ll: opacity >
  // 0).
  std::vector<uint32_t> depth_complexity;
  RasterStats stats;
};

class RasterRenderer {
 public:
  // Uploads the mesh (every chunk its own vertex and index buffers, drawn in chunk order).
  RasterRenderer(Context& context, const TubeMesh& mesh);
  // The same, a chunk at a time: `description` lists the chunks (its arrays may be empty) and
  // `chunk(i)` gives chunk i, which is uploaded and let go before the next is asked for, so the
  // host never holds more than one chunk (cache/tube_store.hpp's load_tube_chunk).
  RasterRenderer(Context& context, const TubeMesh& description,
                 const std::function<TubeChunk(size_t)>& chunk);
  RasterRenderer(const RasterRenderer&) = delete;
  RasterRenderer& operator=(const RasterRenderer&) = delete;
  ~RasterRenderer();

  RasterFrame render(const Camera& camera, const TransferFunction& tf,
                     const RasterOptions& options);

  // Depth complexity only: fragments with opacity > 0 per pixel, counted by one draw (no image).
  RasterFrame count_fragments(const Camera& camera, const TransferFunction& tf, int width,
                              int height);

  uint64_t mesh_bytes() const;
  Bounds bounds() const;  // of the mesh's vertices

  struct State;

 private:
  std::unique_ptr<State> state_;
};

}  // namespace linebake::vk
