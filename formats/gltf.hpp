#pragma once
// glTF 2.0 export of the tube mesh, optionally Draco-compressed (KHR_draco_mesh_compression,
// encoded with libdraco), and of the raw lines. Written as .glb (one binary file, at most
// 4 GiB) or as .gltf (JSON) with its buffer in a .bin file beside it, which has no size limit.
//
// Axes: glTF's +y is up and importers convert from it (Blender turns it into its own +z). With
// GltfAxes::ZUp (the default) the data's +z is taken as up and written as glTF's +y, position
// (x, y, z) as (x, z, -y), so Blender shows the tubes in the data's own axes, where the VDB
// export (formats/vdb.hpp) puts its volume. GltfAxes::Raw writes the coordinates as stored.
//
// Per vertex, with an attribute: `_ATTRIBUTE` (UNSIGNED_SHORT normalised; the data range is in
// the mesh's extras), `TEXCOORD_0` = (attribute normalised to [0, 1], 0.5) for a viewer's own
// colour map, and `COLOR_0` from the given colour map. Tube chunks become one primitive each; the
// lines one indexed LINES primitive (glTF has no primitive restart), or one LINE_STRIP per
// polyline.

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "lines/line_set.hpp"
#include "tubes/tube_mesh.hpp"

namespace linebake {

enum class GltfAxes { ZUp, Raw };

struct GltfOptions {
  bool draco = false;
  int draco_position_bits = 14;  // quantisation of positions (Draco's default is 11)
  int draco_normal_bits = 10;
  int draco_speed = 5;  // 0 (best compression) .. 10 (fastest)
  // Vertices of a tube chunk Draco encodes at most at a time, each piece its own primitive, cut
  // between lines (a line with more is one piece): Draco's encoder holds about 14 times the
  // mesh it is given.
  uint64_t draco_piece_vertices = uint64_t{1} << 19;
  // A piece with more vertices than this (a line longer than draco_piece_vertices) is refused
  // before it is encoded, BudgetExceeded, nothing written; 0: any (what a memory budget allows).
  uint64_t draco_max_piece_vertices = 0;
  GltfAxes axes = GltfAxes::ZUp;
  // COLOR_0: 256 linear RGB colours, entry i for the attribute at i / 255 of colour_range (data
  // units; {0, 0}: the attribute's own range), clamped; empty: no COLOR_0.
  std::vector<std::array<uint8_t, 3>> colour_map;
  std::array<float, 2> colour_range{0, 0};
  bool line_strips = false;  // the lines as one LINE_STRIP per polyline
  // The attribute the lines carry and the range it is normalised over: the tube mesh's when it
  // is exported too, else these when the name is set (export --no-tubes sets the cache's tubes'),
  // else the first point attribute over its finite range.
  std::string lines_attribute;
  std::array<float, 2> lines_attribute_range{0, 0};
  // The lines' origin (lines/origin.hpp), data axes: every node's translation (glTF's numbers are
  // JSON doubles), so that the float32 vertices stay relative to it and a viewer places them in
  // world coordinates.
  std::array<double, 3> origin{0, 0, 0};
};

// The tube mesh a chunk at a time (cache/tube_store.hpp's load_tube_description and
// load_tube_chunk): `description` has every chunk's place (its arrays may be empty) and
// `chunk(i)` gives chunk i whole. The export holds one chunk at a time, and its glTF arrays a
// piece at a time (with Draco, a piece of it and Draco's encoder).
struct TubeChunks {
  TubeMesh description;
  std::function<TubeChunk(size_t index)> chunk;
};

// Either may be null (but not both). The format from the extension: .glb, or .gltf with
// PATH-without-extension.bin. Throws OutputError when a file cannot be written or a GLB would
// exceed 4 GiB (before writing anything).
//
// Written in two passes over the data: the first lays the file out (the JSON, with every
// view's offset and every accessor's bounds, and Draco's compressed sizes), the second writes
// the binary buffer a view at a time behind it. So memory holds the JSON, the lines and one tube
// chunk with a piece of its glTF arrays (with Draco, a piece of the chunk and its encoder),
// never the whole buffer; the price is that
// each chunk is read and converted twice (Draco encodes once, into a spill file beside the
// output). Both passes hash the buffer: a chunk that changed in between (a cache rewritten
// meanwhile) is an Error, and nothing is written.
void write_gltf(const std::string& path, const TubeChunks* tubes, const LineSet* lines,
                const GltfOptions& options = {});
// The same for a mesh in memory.
void write_gltf(const std::string& path, const TubeMesh* tubes, const LineSet* lines,
                const GltfOptions& options = {});

// `path`'s extension in lower case (".GLB" -> ".glb"): export takes either case, as convert and
// render do.
std::string lowercase_extension(const std::string& path);
// Whether `path` is a .gltf (JSON with a .bin beside it), in any case; else it is written as .glb.
inline bool is_gltf_json(const std::string& path) {
  return lowercase_extension(path) == ".gltf";
}

}  // namespace linebake
