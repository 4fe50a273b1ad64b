#pragma once
// `tiles`: exact order-independent transparency from compute shaders only, for GPUs with little
// or no graphics hardware (datacenter parts: on an H100 only two TPCs rasterise), over capsules
// (the lines) or the tube mesh's triangles. Per frame: binning (each primitive's screen bounds
// to (tile, depth) keys), a GPU radix sort of the keys
// (radix_sort.hpp), the tiles' key ranges, and one workgroup per 16x16 tile compositing its
// primitives front to back through a per-pixel sorted window (shaders/tiles_*.comp).

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "accel/capsule_segments.hpp"
#include "render/camera.hpp"
#include "render/image.hpp"
#include "render/ray_tracer.hpp"
#include "render/transfer_function.hpp"
#include "render/vulkan/context.hpp"
#include "render/vulkan/shaders.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake::vk {

// A tile in strips is composited by four workgroups of 64 invocations, a strip of 16x4 pixels
// each, instead of one of 256 (shaders/tiles_composite.glsl, TILES_STRIPS): a crowded tile is
// shared by four, and a workgroup waiting at a barrier idles a quarter of the invocations. Each
// strip walks all of the tile's keys. none: no tile in strips; crowded: in each walk the crowded
// tiles (more than 8 times the walk's mean keys), and every tile of a walk over fewer than 512
// (walks again: few tiles, the rest of a GPU idle); all: every tile. The image is the same
// either way (bench render's tiles-crowded-strips and tiles-strips, the A/B; on lavapipe all
// tiles in strips take the composite 6 to 33 % longer, paper-small's aneurysm and convection at
// 640x360).
enum class TileStrips { none, crowded, all };

struct TileOptions {
  int width = 1280, height = 720;
  bool early_termination = false;
  double termination_alpha = 0.99;
  // Device memory the frame's (tile, segment) keys may take, sort scratch included (0: as much
  // as one storage buffer allows). A frame with more keys renders in bands of tile rows.
  uint64_t max_key_bytes = 0;
  // Device memory the pixels' states between slices and walks may take (0: one storage buffer):
  // the tiles are composited in groups whose states fit, at least one tile (68 or 116 KiB, 36 or 52
  // shading late) a group.
  uint64_t max_state_bytes = 0;
  // Bits of a (tile, depth) key (0: 24 where the tiles take at most 14, else 32; tests): the
  // depth takes what the tile index leaves. Fewer bits tie more keys, in an order the sort
  // leaves as binning emitted them; the image is the same for any order.
  uint32_t key_bits = 0;
  // Primitives whose screen bounds hold at most this many pixel centres (at most 4) get a key
  // only where one of those pixels may hit them: capsules where a pixel's ray may cross the
  // surface they own (shaders/tiles_bin.comp), triangles where a pixel centre lies inside them
  // on the screen (shaders/tiles_bin_triangles.comp); 0: every primitive is binned by its bounds.
  // The image is the same either way, with fewer keys to sort and walk (tests compare).
  uint32_t tested_pixels = 4;
  // The composite's workgroups take the crowded tiles (more than 8 times the mean keys to walk)
  // first, the most keys first (longest processing time first), so that one does not start last
  // while the rest of the GPU runs out of tiles; the others follow in raster order, neighbours
  // together. false: all in raster order (bench render's tiles-raster-order, the A/B), except
  // that TileStrips::crowded still dispatches the crowded tiles first, in raster order. The image
  // is the same either way: each workgroup writes its own pixels.
  bool most_keys_first = true;
  // Which tiles get four composite workgroups of 64 invocations, a strip of 16x4 pixels each,
  // instead of one of 256 (TileStrips).
  TileStrips strips = TileStrips::none;
  // Each pixel computes its own hits instead of the workgroup's rounds of (pixel, primitive)
  // pairs (shaders/tiles_composite.glsl, TILES_PIXEL_HITS): the composite before the rounds, kept
  // as the A/B for GPUs (bench render's tiles-pixel-hits). The same bytes. Not with strips.
  bool pixel_hits = false;
  // The composite's window holds each pending hit's t and primitive, not its colour: a hit is
  // shaded when it is composited, its primitive tested again (shaders/tiles_composite.glsl,
  // TILES_LATE_SHADING): fewer registers a pixel, for GPUs, where they bound how many workgroups
  // run at once (bench render's tiles-late-shading). The same bytes. Not with strips.
  bool late_shading = false;
  // TileStrips::crowded takes every tile of a walk over fewer tiles than this in strips (tests
  // lower it to 0: then only the crowded).
  uint32_t few_tiles = 512;
  // The passes' workgroups go in rows of this many (vk::dispatch_workgroups: Vulkan promises
  // 65,535 a dimension, which binning 10^8 segments exceeds; tests lower it). The same image.
  uint32_t dispatch_row = vk::kDispatchRow;
  Shading shading;
};

struct TileStats {
  double seconds = 0;                                // wall, readback included
  double bin_ms = 0, sort_ms = 0, composite_ms = 0;  // GPU timestamps (0 without them)
  uint64_t primitives = 0, binned_primitives = 0;    // all, and those in front of the eye on screen
  uint64_t keys = 0;                                 // (tile, segment) pairs, all bands
  uint32_t tiles = 0;                                // 16x16 tiles of the image
  uint64_t hits = 0;                                 // front crossings composited
  uint64_t window_overflows = 0;  // pixel walks that left hits for another (a full window)
  // Late shading (TileOptions::late_shading): hits whose second test missed them, composited in
  // a stand-in colour. 0 where the compiler computes the test alike in both places.
  uint64_t late_misses = 0;
  uint32_t max_depth_complexity = 0;
  uint64_t frame_bytes = 0;    // keys, values, sort scratch, ranges, pixels
  uint32_t rebins = 0;         // binning passes repeated for more key room
  uint32_t slices = 1;         // composite dispatches per band (each a slice of every tile's keys)
  uint64_t max_row_keys = 0;   // keys of the fullest row of tiles (the smallest band)
  uint64_t max_tile_keys = 0;  // keys of the fullest tile (one workgroup walks them in turn)
  uint32_t crowded_tiles = 0;  // tiles the first walk took first (TileOptions::most_keys_first)
  uint32_t bands = 1;          // bands of tile rows, each binned, sorted and composited alone
  uint32_t resliced = 0;       // bands composited again in smaller slices (an invocation cut short)
  uint32_t walks = 1;          // the most walks over a tile's keys (more: a full window, exact)
  uint64_t walk_skipped_keys = 0;  // keys the walks again started past (their pixels done there)
  uint32_t groups = 1;             // the most groups of tiles in a band (their states fit a buffer)
  uint64_t composite_workgroups = 0;  // dispatched, all bands, walks and slices (strips: 4 a tile)
  // Per walk (0: the first), summed over bands and groups: composite GPU ms and tiles walked.
  std::vector<double> walk_ms;
  std::vector<uint64_t> walk_tiles;
  // Tiles composited again, and their GPU ms (in composite_ms, not walk_ms): first walks redone
  // where the pixels' states had no room to stay yet (a renderer's first frame that walks
  // again), and the walks a dispatch cut short threw away (resliced).
  uint64_t redone_tiles = 0;
  double redone_ms = 0;
};

struct TileFrame {
  Image image;
  std::vector<uint32_t> depth_complexity;
  TileStats stats;
};

// The composite's window loops: leaving once past the pending hits (exits) or running every
// trip (fixed, lavapipe's faster kind; shaders/tiles_composite.glsl). The same bytes either way.
enum class WindowLoops { by_device, fixed, exits };

class TileRenderer {
 public:
  // The capsules are uploaded once (device-local); `max_buffer_bytes` > 0 lowers the largest
  // storage buffer, `slice_keys` > 0 sets the keys per tile per composite dispatch (tests; by
  // default 2,048 on lavapipe, whose invocations stop after 65535 loop iterations, else all);
  // `sort_subgroups` false keeps the key sort on its shared-memory path (radix_sort.hpp).
  // What the constructor holds on the host besides the capsules while it uploads them (their
  // points and segment words merged over the chunks), for a budget's check before building.
  static uint64_t capsule_upload_bytes(uint64_t points, uint64_t segments) {
    return 16 * points + 4 * segments;
  }
  TileRenderer(Context& context, const CapsuleSegments& capsules, uint64_t max_buffer_bytes = 0,
               uint32_t slice_keys = 0, bool sort_subgroups = true,
               WindowLoops window_loops = WindowLoops::by_device);
  // Triangle mode: the tube mesh's front-facing triangles, comparable with `reference` and the
  // raster techniques to the last bit of coverage.
  TileRenderer(Context& context, const TubeMesh& mesh, uint64_t max_buffer_bytes = 0,
               uint32_t slice_keys = 0, bool sort_subgroups = true,
               WindowLoops window_loops = WindowLoops::by_device);
  // The same, a chunk at a time: `description` lists the chunks (its arrays may be empty),
  // `counts` sizes the device's arrays, and `chunk(i)` gives chunk i, let go once its vertices
  // are copied, so the host never holds the whole mesh beside them (load_tube_chunk).
  TileRenderer(Context& context, const TubeMesh& description, const TubeCounts& counts,
               const std::function<TubeChunk(size_t)>& chunk, uint64_t max_buffer_bytes = 0,
               uint32_t slice_keys = 0, bool sort_subgroups = true,
               WindowLoops window_loops = WindowLoops::by_device);
  ~TileRenderer();
  TileRenderer(const TileRenderer&) = delete;
  TileRenderer& operator=(const TileRenderer&) = delete;

  TileFrame render(const Camera& camera, const TransferFunction& tf, const TileOptions& options);
  // Makes the composites a frame with these options runs, which a frame would make when it first
  // needs them: where the driver's compiler takes the machine's memory (lavapipe), before a
  // budget counts what the process holds.
  void make_pipelines(const TileOptions& options);
  // The subgroup size the key sort runs with (radix_sort.hpp); 0: its shared-memory path.
  uint32_t sort_subgroup_size() const;
  // The device memory one tile's pixels keep between slices and walks (their windows of pending
  // hits: 8 with the window loops of fixed trips, 16 with those that exit; the builds that shade
  // late keep no colours there, TileOptions::late_shading).
  uint64_t tile_state_bytes(bool late_shading = false) const;
  // The storage buffers the primitives take: 2 where the points and the segment words (or the
  // vertices and the indices) fit one each, more where they go in pages.
  size_t primitive_buffers() const;

 private:
  struct State;
  struct Frame;  // one frame's passes over the state
  std::unique_ptr<State> state_;
};

}  // namespace linebake::vk
