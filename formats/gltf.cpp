#include "formats/gltf.hpp"

#include "core/json_file.hpp"

// The one translation unit with tinygltf's implementation (the tests link it from here).
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <typeinfo>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/interrupt.hpp"
#include "core/progress.hpp"
#include "core/spill_file.hpp"
#include "tubes/mesh_pieces.hpp"

namespace linebake {
namespace {

constexpr int kArrayBuffer = 34962;
constexpr int kElementArrayBuffer = 34963;
constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr uint64_t kGlbLimit = 0xFFFFFFFFull;
// Vertices of a tube chunk converted to glTF's arrays at a time (add_tubes).
constexpr uint64_t kViewPiece = uint64_t{1} << 18;

// Where the binary buffer's bytes go: to a hash while the file is laid out (the first of the two
// passes, write_gltf), to the file and a hash in the second.
using ByteSink = std::function<void(const void* data, size_t bytes)>;

// Lays out the single binary buffer and the views/accessors that point into it, handing each
// view's bytes (after zeros up to its 4-byte alignment) to the sink.
class ModelBuilder {
 public:
  ModelBuilder(tinygltf::Model& model, bool glb, ByteSink sink)
      : model_(model), glb_(glb), sink_(std::move(sink)) {
    model_.buffers.emplace_back();
  }

  // Appends bytes (4-byte aligned) as a new buffer view; returns its index.
  int add_view(const void* data, size_t bytes, int target, size_t stride = 0) {
    return add_view(
        bytes, [&](const ByteSink& sink) { sink(data, bytes); }, target, stride);
  }
  // The same for a view of `bytes` bytes that `write` hands to the sink it is given, in pieces
  // (so that they need not all be in memory at once), exactly that many.
  int add_view(uint64_t bytes, const std::function<void(const ByteSink&)>& write, int target,
               size_t stride = 0) {
    const uint64_t offset = aligned(size_);
    if (glb_ && offset + bytes > kGlbLimit)
      throw Error("the export exceeds GLB's 4 GiB limit (write .gltf, whose .bin has none)");
    if (sink_) {
      static constexpr char kZeros[4] = {};
      sink_(kZeros, size_t(offset - size_));
      uint64_t given = 0;
      write([&](const void* data, size_t n) {
        given += n;
        sink_(data, n);
      });
      if (given != bytes)
        throw Error("internal error: a glTF view of " + std::to_string(bytes) + " bytes got " +
                    std::to_string(given));
    }
    size_ = offset + bytes;
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = offset;
    view.byteLength = bytes;
    view.byteStride = stride;
    view.target = target;
    model_.bufferViews.push_back(std::move(view));
    return int(model_.bufferViews.size() - 1);
  }

  // The buffer's length, padded to 4 bytes (the padding goes to the sink).
  uint64_t finish() {
    static constexpr char kZeros[4] = {};
    if (sink_) sink_(kZeros, size_t(aligned(size_) - size_));
    return size_ = aligned(size_);
  }

  static uint64_t aligned(uint64_t bytes) { return (bytes + 3) & ~uint64_t{3}; }

  int add_accessor(int view, size_t offset, int component, int type, size_t count,
                   bool normalized = false, std::vector<double> min = {},
                   std::vector<double> max = {}) {
    tinygltf::Accessor a;
    a.bufferView = view;
    a.byteOffset = offset;
    a.componentType = component;
    a.type = type;
    a.count = count;
    a.normalized = normalized;
    a.minValues = std::move(min);
    a.maxValues = std::move(max);
    model_.accessors.push_back(std::move(a));
    return int(model_.accessors.size() - 1);
  }

 private:
  tinygltf::Model& model_;
  bool glb_;
  ByteSink sink_;
  uint64_t size_ = 0;
};

void bounds_of(const float* xyz, size_t count, std::vector<double>& min, std::vector<double>& max) {
  std::array<float, 3> lo{std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                          std::numeric_limits<float>::max()};
  std::array<float, 3> hi{-lo[0], -lo[1], -lo[2]};
  for (size_t i = 0; i < count; ++i)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], xyz[3 * i + k]);
      hi[k] = std::max(hi[k], xyz[3 * i + k]);
    }
  min.assign(lo.begin(), lo.end());
  max.assign(hi.begin(), hi.end());
}

// Positions or normals in the output's axes (gltf.hpp): glTF's +y is the data's +z.
std::vector<float> in_axes(const float* xyz, uint64_t count, GltfAxes axes) {
  std::vector<float> out(xyz, xyz + 3 * count);
  if (axes == GltfAxes::ZUp)
    for (uint64_t i = 0; i < count; ++i) {
      out[3 * i + 1] = xyz[3 * i + 2];
      out[3 * i + 2] = -xyz[3 * i + 1];
    }
  return out;
}

// Float normals of `count` vertices of a chunk from `first`, whatever its encoding (glTF NORMAL
// is FLOAT VEC3).
std::vector<float> float_normals(const TubeChunk& chunk, uint64_t first, uint64_t count) {
  if (!chunk.normals.empty())
    return {chunk.normals.begin() + ptrdiff_t(3 * first),
            chunk.normals.begin() + ptrdiff_t(3 * (first + count))};
  std::vector<float> out(3 * count);
  for (uint64_t v = 0; v < count; ++v) {
    const auto n = decode_octahedral(chunk.normals_oct[2 * (first + v)],
                                     chunk.normals_oct[2 * (first + v) + 1]);
    std::copy(n.begin(), n.end(), out.begin() + ptrdiff_t(3 * v));
  }
  return out;
}

// The attribute normalised to [0, 1] as unorm16, what the tube chunks store.
std::vector<uint16_t> unorm16_of(const std::vector<float>& values, std::array<float, 2> range) {
  const double span = double(range[1]) - double(range[0]);
  std::vector<uint16_t> out(values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    const double t = span > 0 ? (double(values[i]) - range[0]) / span : 0.5;
    // Infinities clamp to the range's ends; NaN (glTF stores no NaN) is its low end.
    out[i] = std::isnan(t) ? 0 : uint16_t(std::lround(std::clamp(t, 0.0, 1.0) * 65535.0));
  }
  return out;
}

// Per-vertex arrays derived from the normalised attribute. glTF wants every vertex attribute
// element 4-byte aligned, hence the padding of `_ATTRIBUTE` to a stride of 4.
struct AttributeArrays {
  std::vector<uint16_t> padded;     // _ATTRIBUTE: value, 0
  std::vector<uint16_t> texcoords;  // TEXCOORD_0: value, 0.5
  std::vector<uint8_t> colours;     // COLOR_0: linear RGB from the colour map, A = 255
};
// Each of them from the attribute as unorm16 (`unorm` spans `range`, data units).
std::vector<uint16_t> padded_attribute(const uint16_t* unorm, uint64_t count) {
  std::vector<uint16_t> out(2 * count, 0);
  for (uint64_t i = 0; i < count; ++i) out[2 * i] = unorm[i];
  return out;
}
std::vector<uint16_t> attribute_texcoords(const uint16_t* unorm, uint64_t count) {
  std::vector<uint16_t> out(2 * count);
  for (uint64_t i = 0; i < count; ++i) out[2 * i] = unorm[i], out[2 * i + 1] = 32768;
  return out;
}
// Empty without a colour map of 256 entries.
std::vector<uint8_t> attribute_colours(const uint16_t* unorm, uint64_t count,
                                       std::array<float, 2> range, const GltfOptions& options) {
  if (options.colour_map.size() != 256) return {};
  const bool own = !(options.colour_range[1] > options.colour_range[0]);
  const double lo = range[0], span = double(range[1]) - range[0];
  const double c0 = own ? lo : options.colour_range[0];
  const double c_span = own ? span : double(options.colour_range[1]) - c0;
  std::vector<uint8_t> out(4 * count);
  for (uint64_t i = 0; i < count; ++i) {
    const double value = lo + span * (unorm[i] / 65535.0);
    const double t = c_span > 0 ? std::clamp((value - c0) / c_span, 0.0, 1.0) : 0.5;
    const auto& c = options.colour_map[size_t(std::lround(t * 255.0))];
    std::copy(c.begin(), c.end(), out.begin() + ptrdiff_t(4 * i));
    out[4 * i + 3] = 255;
  }
  return out;
}
AttributeArrays attribute_arrays(const uint16_t* unorm, uint64_t count, std::array<float, 2> range,
                                 const GltfOptions& options) {
  return {padded_attribute(unorm, count), attribute_texcoords(unorm, count),
          attribute_colours(unorm, count, range, options)};
}

// TEXCOORD_0 and COLOR_0 accessors over plain arrays (the tubes' _ATTRIBUTE is added apart).
void add_mapped_attributes(ModelBuilder& builder, tinygltf::Primitive& primitive,
                           const AttributeArrays& a, uint64_t count) {
  primitive.attributes["TEXCOORD_0"] = builder.add_accessor(
      builder.add_view(a.texcoords.data(), a.texcoords.size() * 2, kArrayBuffer), 0,
      TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC2, count, true);
  if (!a.colours.empty())
    primitive.attributes["COLOR_0"] = builder.add_accessor(
        builder.add_view(a.colours.data(), a.colours.size(), kArrayBuffer), 0,
        TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC4, count, true);
}

template <class T>
int add_draco_attribute(draco::Mesh& mesh, draco::GeometryAttribute::Type type, int components,
                        draco::DataType data_type, bool normalized, const T* values,
                        uint64_t count) {
  draco::GeometryAttribute attribute;
  attribute.Init(type, nullptr, int8_t(components), data_type, normalized,
                 int64_t(sizeof(T) * components), 0);
  const int id = mesh.AddAttribute(attribute, true, uint32_t(count));
  mesh.attribute(id)->buffer()->Write(0, values, sizeof(T) * components * count);
  return id;
}

struct DracoChunk {
  std::vector<char> bytes;
  uint64_t points = 0, faces = 0;
  std::vector<double> min, max;  // of the decoded positions (quantised), as the accessor states
  int position = -1, normal = -1, attribute = -1, texcoord = -1, colour = -1;
};

// One piece of a chunk (MeshPiece), in the output's axes: its vertices' arrays and its
// triangles' indices, rebased to its first vertex.
struct DracoInput {
  const std::vector<float>& positions;
  const std::vector<float>& normals;
  const uint16_t* attribute = nullptr;      // unorm16 a vertex; null without attribute
  const AttributeArrays* mapped = nullptr;  // with an attribute
  const std::vector<uint32_t>& indices;
};

DracoChunk encode_draco(const DracoInput& piece, const GltfOptions& options) {
  draco::Mesh mesh;
  const uint64_t v = piece.positions.size() / 3;
  const std::vector<float>& positions = piece.positions;
  const std::vector<float>& normals = piece.normals;
  const AttributeArrays* attribute = piece.attribute ? piece.mapped : nullptr;
  mesh.set_num_points(uint32_t(v));
  DracoChunk out;
  out.position = add_draco_attribute(mesh, draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32,
                                     false, positions.data(), v);
  out.normal = add_draco_attribute(mesh, draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32,
                                   false, normals.data(), v);
  if (attribute) {
    out.attribute = add_draco_attribute(mesh, draco::GeometryAttribute::GENERIC, 1,
                                        draco::DT_UINT16, true, piece.attribute, v);
    out.texcoord = add_draco_attribute(mesh, draco::GeometryAttribute::TEX_COORD, 2,
                                       draco::DT_UINT16, true, attribute->texcoords.data(), v);
    if (!attribute->colours.empty())
      out.colour = add_draco_attribute(mesh, draco::GeometryAttribute::COLOR, 4, draco::DT_UINT8,
                                       true, attribute->colours.data(), v);
  }
  const uint64_t triangles = piece.indices.size() / 3;
  mesh.SetNumFaces(triangles);
  for (uint64_t t = 0; t < triangles; ++t)
    mesh.SetFace(draco::FaceIndex(uint32_t(t)), {draco::PointIndex(piece.indices[3 * t]),
                                                 draco::PointIndex(piece.indices[3 * t + 1]),
                                                 draco::PointIndex(piece.indices[3 * t + 2])});
  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, options.draco_position_bits);
  encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, options.draco_normal_bits);
  encoder.SetSpeedOptions(options.draco_speed, options.draco_speed);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeMeshToBuffer(mesh, &buffer);
  if (!status.ok()) throw Error(std::string("Draco encoding failed: ") + status.error_msg());
  out.bytes.assign(buffer.data(), buffer.data() + buffer.size());
  // The accessors must state the counts a decoder produces, which Edgebreaker may change
  // (it splits non-manifold vertices): decode once and take them from there.
  draco::DecoderBuffer in;
  in.Init(out.bytes.data(), out.bytes.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&in);
  if (!decoded.ok()) throw Error("Draco round trip failed: " + decoded.status().error_msg_string());
  out.points = decoded.value()->num_points();
  out.faces = decoded.value()->num_faces();
  // KHR_draco_mesh_compression: the accessors' min and max are the decompressed data's. The
  // quantised positions reach past the input's box (by up to a step of the grid: 2.8e-4 at 14
  // bits, a third of the box at 4), which viewers cull and frame by.
  const draco::PointAttribute* position =
      decoded.value()->GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (!position) throw Error("Draco round trip failed: no positions decoded");
  out.min.assign(3, std::numeric_limits<double>::infinity());
  out.max.assign(3, -std::numeric_limits<double>::infinity());
  for (uint32_t p = 0; p < out.points; ++p) {
    float xyz[3];
    position->GetMappedValue(draco::PointIndex(p), xyz);
    for (int k = 0; k < 3; ++k) {
      out.min[size_t(k)] = std::min(out.min[size_t(k)], double(xyz[k]));
      out.max[size_t(k)] = std::max(out.max[size_t(k)], double(xyz[k]));
    }
  }
  return out;
}

void add_draco_primitive(ModelBuilder& builder, tinygltf::Primitive& primitive, const DracoChunk& d,
                         const std::vector<double>& min, const std::vector<double>& max) {
  const int view = builder.add_view(d.bytes.data(), d.bytes.size(), 0);
  tinygltf::Value::Object ids;
  const auto add = [&](const char* name, int id, int component, int type, bool normalized,
                       std::vector<double> lo = {}, std::vector<double> hi = {}) {
    if (id < 0) return;
    primitive.attributes[name] = builder.add_accessor(-1, 0, component, type, d.points, normalized,
                                                      std::move(lo), std::move(hi));
    ids[name] = tinygltf::Value(id);
  };
  add("POSITION", d.position, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, false, min, max);
  add("NORMAL", d.normal, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, false);
  add("_ATTRIBUTE", d.attribute, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR,
      true);
  add("TEXCOORD_0", d.texcoord, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC2, true);
  add("COLOR_0", d.colour, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC4, true);
  primitive.indices = builder.add_accessor(-1, 0, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                           TINYGLTF_TYPE_SCALAR, 3 * d.faces);
  primitive.extensions[kDraco] = tinygltf::Value(tinygltf::Value::Object{
      {"bufferView", tinygltf::Value(view)}, {"attributes", tinygltf::Value(std::move(ids))}});
}

tinygltf::Value attribute_extras(const std::string& name, std::array<float, 2> range) {
  return tinygltf::Value(tinygltf::Value::Object{
      {"linebake_attribute", tinygltf::Value(name)},
      {"linebake_attribute_range",
       tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(double(range[0])),
                                              tinygltf::Value(double(range[1]))})}});
}

// Draco's encoded chunks, kept from the pass that lays the file out for the pass that writes
// it (write_gltf): encoding is the slow part, and the bytes, the output's size, go to a spill
// file beside the output instead of memory.
struct DracoChunks {
  struct Entry {
    DracoChunk chunk;  // its bytes in the spill
    uint64_t offset = 0, bytes = 0;
    std::vector<double> min, max;
  };
  std::unique_ptr<SpillFile> spill;
  std::vector<std::vector<Entry>> entries;  // per chunk, a piece each (MeshPiece)
};

// The tube mesh's primitives, one a chunk; with Draco one a piece of a chunk of at most
// options.draco_piece_vertices vertices (cut between lines: tubes/mesh_pieces.hpp), so that
// Draco's encoder holds a piece, not the chunk. With Draco, the first pass (`draco->entries`
// empty) encodes each piece and keeps it; the second writes what was kept, reading no chunk.
// `chunk_done` after each chunk.
void add_tubes(tinygltf::Model& model, ModelBuilder& builder, const TubeChunks& chunks,
               const GltfOptions& options, DracoChunks* draco,
               const std::function<void()>& chunk_done) {
  const TubeMesh& tubes = chunks.description;
  tinygltf::Mesh mesh;
  mesh.name = "tubes";
  const bool has_attribute = !tubes.attribute.empty();
  const bool encoded = options.draco && !draco->entries.empty();
  for (size_t c = 0; c < tubes.chunks.size(); ++c, chunk_done()) {
    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    primitive.material = 0;
    if (encoded) {
      for (const DracoChunks::Entry& e : draco->entries[c]) {
        DracoChunk d = e.chunk;
        d.bytes.resize(e.bytes);
        draco->spill->read(e.offset, d.bytes.data(), e.bytes);
        tinygltf::Primitive piece = primitive;
        add_draco_primitive(builder, piece, d, e.min, e.max);
        mesh.primitives.push_back(std::move(piece));
      }
      continue;
    }
    const TubeChunk chunk = chunks.chunk(c);
    if (options.draco) draco->entries.emplace_back();
    if (chunk.vertex_count() == 0) continue;
    const uint64_t v = chunk.vertex_count();
    if (options.draco) {
      for (const MeshPiece& p :
           independent_pieces({chunk.indices.data(), chunk.indices.size()}, v,
                              std::max<uint64_t>(options.draco_piece_vertices, 1))) {
        throw_if_interrupted();  // a piece's encoding takes seconds: Ctrl-C between pieces
        const uint64_t n = p.vertices;
        if (options.draco_max_piece_vertices > 0 && n > options.draco_max_piece_vertices)
          throw BudgetExceeded("Draco: tube chunk " + std::to_string(c) + " has a piece of " +
                               std::to_string(n) +
                               " vertices without a cut in it (its triangles share vertices "
                               "throughout, as a line's tube does), more than the " +
                               std::to_string(options.draco_max_piece_vertices) +
                               " the memory budget leaves room to encode; raise --memory-budget");
        const std::vector<float> positions =
            in_axes(chunk.positions.data() + 3 * p.first_vertex, n, options.axes);
        const std::vector<float> raw_normals = float_normals(chunk, p.first_vertex, n);
        const std::vector<float> normals = in_axes(raw_normals.data(), n, options.axes);
        const uint16_t* unorm = has_attribute ? chunk.attribute.data() + p.first_vertex : nullptr;
        const AttributeArrays attribute =
            has_attribute ? attribute_arrays(unorm, n, tubes.attribute_range, options)
                          : AttributeArrays{};
        std::vector<uint32_t> indices(chunk.indices.data() + 3 * p.first_triangle,
                                      chunk.indices.data() + 3 * (p.first_triangle + p.triangles));
        for (uint32_t& i : indices) i -= uint32_t(p.first_vertex);
        DracoChunk d = encode_draco({positions, normals, unorm, &attribute, indices}, options);
        DracoChunks::Entry& e = draco->entries.back().emplace_back();
        e.min = d.min, e.max = d.max;
        tinygltf::Primitive piece = primitive;
        add_draco_primitive(builder, piece, d, e.min, e.max);
        mesh.primitives.push_back(std::move(piece));
        e.bytes = d.bytes.size();
        e.offset = draco->spill->append(d.bytes.data(), d.bytes.size());
        d.bytes = {};
        e.chunk = std::move(d);
      }
      continue;
    }
    // The chunk's arrays in the output's form a piece of kViewPiece vertices at a time, straight
    // to the sink: what the chunk holds, not again that much in glTF arrays.
    const auto in_pieces = [&](const auto& each) {
      for (uint64_t first = 0; first < v; first += kViewPiece) {
        throw_if_interrupted();
        each(first, std::min(kViewPiece, v - first));
      }
    };
    const auto positions = [&](uint64_t first, uint64_t n) {
      return in_axes(chunk.positions.data() + 3 * first, n, options.axes);
    };
    std::vector<double> min, max;
    bounds_of(chunk.positions.data(), v, min, max);
    if (options.axes == GltfAxes::ZUp) {  // (x, y, z) written as (x, z, -y): in_axes
      const double y_min = min[1], y_max = max[1];
      min[1] = min[2], max[1] = max[2];
      min[2] = -y_max, max[2] = -y_min;
    }
    const auto floats = [&](const auto& make) {
      return [&, make](const ByteSink& sink) {
        in_pieces([&](uint64_t first, uint64_t n) {
          const std::vector<float> piece = make(first, n);
          sink(piece.data(), piece.size() * sizeof(float));
        });
      };
    };
    primitive.attributes["POSITION"] =
        builder.add_accessor(builder.add_view(12 * v, floats(positions), kArrayBuffer), 0,
                             TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, v, false, min, max);
    const auto normals = [&](uint64_t first, uint64_t n) {
      const std::vector<float> raw = float_normals(chunk, first, n);
      return in_axes(raw.data(), n, options.axes);
    };
    primitive.attributes["NORMAL"] =
        builder.add_accessor(builder.add_view(12 * v, floats(normals), kArrayBuffer), 0,
                             TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, v);
    if (has_attribute) {
      // One of the attribute's arrays a piece at a time, `make(unorm, count)` making it.
      const auto mapped = [&](const auto& make) {
        return [&, make](const ByteSink& sink) {
          in_pieces([&](uint64_t first, uint64_t n) {
            const auto piece = make(chunk.attribute.data() + first, n);
            sink(piece.data(), piece.size() * sizeof(piece[0]));
          });
        };
      };
      primitive.attributes["_ATTRIBUTE"] = builder.add_accessor(
          builder.add_view(4 * v, mapped(padded_attribute), kArrayBuffer, 4), 0,
          TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR, v, true);
      primitive.attributes["TEXCOORD_0"] = builder.add_accessor(
          builder.add_view(4 * v, mapped(attribute_texcoords), kArrayBuffer), 0,
          TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC2, v, true);
      const auto colours = [&](const uint16_t* unorm, uint64_t n) {
        return attribute_colours(unorm, n, tubes.attribute_range, options);
      };
      if (options.colour_map.size() == 256)
        primitive.attributes["COLOR_0"] = builder.add_accessor(
            builder.add_view(4 * v, mapped(colours), kArrayBuffer), 0,
            TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_TYPE_VEC4, v, true);
    }
    primitive.indices = builder.add_accessor(
        builder.add_view(chunk.indices.data(), chunk.indices.bytes(), kElementArrayBuffer), 0,
        TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, chunk.indices.size());
    mesh.primitives.push_back(std::move(primitive));
  }
  // What a renderer needs to map _ATTRIBUTE back to data values.
  mesh.extras = attribute_extras(tubes.attribute, tubes.attribute_range);
  auto& extras = mesh.extras.Get<tinygltf::Value::Object>();
  extras["linebake_tube_radius"] = tinygltf::Value(double(tubes.radius));
  extras["linebake_tube_sides"] = tinygltf::Value(tubes.sides);
  model.meshes.push_back(std::move(mesh));
}

std::array<float, 2> value_range(const std::vector<float>& values) {
  std::array<float, 2> r{std::numeric_limits<float>::max(), std::numeric_limits<float>::lowest()};
  for (float x : values)
    if (std::isfinite(x)) r = {std::min(r[0], x), std::max(r[1], x)};
  return r[0] <= r[1] ? r : std::array<float, 2>{0, 0};
}

// The lines' attribute, a value per point: the tubes' (a line attribute repeated along its
// line) over the tubes' range, so that both meshes carry one quantity alike (or the one the
// options name); else the first point attribute over its own range. The lines had taken the first
// point attribute whatever the tubes showed (bake --attribute curvature: tubes of curvature, lines
// of vorticity).
struct LinesAttribute {
  std::string name;
  const Attribute* per_point = nullptr;  // the line set's own values, not copied
  std::vector<float> expanded;           // else a line attribute's, a value per point
  std::array<float, 2> range{};
  const std::vector<float>& values() const { return per_point ? per_point->values : expanded; }
};
std::optional<LinesAttribute> lines_attribute(const LineSet& lines, const TubeMesh* tubes,
                                              const GltfOptions& options) {
  const std::string& name = tubes ? tubes->attribute : options.lines_attribute;
  const std::array<float, 2> range = tubes ? tubes->attribute_range : options.lines_attribute_range;
  if (!name.empty()) {
    if (const Attribute* a = lines.find_attribute(name)) return LinesAttribute{name, a, {}, range};
    if (const Attribute* a = lines.find_line_attribute(name)) {
      LinesAttribute expanded{name, nullptr, {}, range};
      expanded.expanded.reserve(lines.point_count());
      for (size_t l = 0; l < lines.line_count(); ++l)
        expanded.expanded.insert(expanded.expanded.end(), lines.line_size(l), a->values[l]);
      return expanded;
    }
  }
  if (lines.attributes.empty()) return std::nullopt;
  const Attribute& first = lines.attributes[0];
  return LinesAttribute{first.name, &first, {}, value_range(first.values)};
}

// The lines: one indexed LINES primitive (a segment per pair of consecutive points), or one
// LINE_STRIP per polyline over a shared position view.
void add_lines(tinygltf::Model& model, ModelBuilder& builder, const LineSet& lines,
               const TubeMesh* tubes, const GltfOptions& options) {
  tinygltf::Mesh mesh;
  mesh.name = "lines";
  const uint64_t points = lines.point_count();
  if (options.line_strips && points * 12 > 0x7FFFFFFFull)
    throw Error(
        "--line-strips: more than 2 GiB of positions (glTF accessor offsets are 31-bit "
        "here); leave --line-strips out");
  if (points > 0xFFFFFFFFull) throw Error("--lines: more than 2^32 points");
  const std::vector<float> positions = in_axes(lines.positions.data(), points, options.axes);
  const int position_view = builder.add_view(positions.data(), positions.size() * sizeof(float),
                                             kArrayBuffer, 12);  // shared: explicit stride
  const std::optional<LinesAttribute> attribute = lines_attribute(lines, tubes, options);
  std::array<float, 2> range{};
  AttributeArrays arrays;
  int values = -1;  // _ATTRIBUTE as the tubes store it: normalised UNSIGNED_SHORT, padded to 4
  if (attribute) {
    range = attribute->range;
    const std::vector<uint16_t> unorm = unorm16_of(attribute->values(), range);
    arrays = attribute_arrays(unorm.data(), points, range, options);
    values = builder.add_view(arrays.padded.data(), arrays.padded.size() * sizeof(uint16_t),
                              kArrayBuffer, 4);
  }
  if (!options.line_strips) {
    std::vector<uint32_t> indices;
    for (size_t l = 0; l < lines.line_count(); ++l)
      for (uint64_t p = lines.line_offsets[l]; p + 1 < lines.line_offsets[l + 1]; ++p)
        indices.insert(indices.end(), {uint32_t(p), uint32_t(p + 1)});
    if (indices.empty()) throw Error("--lines: no line has two points");
    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_LINE;
    std::vector<double> min, max;
    bounds_of(positions.data(), points, min, max);
    primitive.attributes["POSITION"] =
        builder.add_accessor(position_view, 0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3,
                             points, false, min, max);
    if (attribute) {
      primitive.attributes["_ATTRIBUTE"] = builder.add_accessor(
          values, 0, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR, points, true);
      add_mapped_attributes(builder, primitive, arrays, points);
    }
    primitive.indices = builder.add_accessor(
        builder.add_view(indices.data(), indices.size() * 4, kElementArrayBuffer), 0,
        TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, indices.size());
    mesh.primitives.push_back(std::move(primitive));
  } else {
    int texcoord_view = -1, colour_view = -1;
    if (attribute) {
      texcoord_view =
          builder.add_view(arrays.texcoords.data(), arrays.texcoords.size() * 2, kArrayBuffer, 4);
      if (!arrays.colours.empty())
        colour_view =
            builder.add_view(arrays.colours.data(), arrays.colours.size(), kArrayBuffer, 4);
    }
    for (size_t l = 0; l < lines.line_count(); ++l) {
      const uint64_t first = lines.line_offsets[l], count = lines.line_size(l);
      if (count < 2) continue;
      tinygltf::Primitive primitive;
      primitive.mode = TINYGLTF_MODE_LINE_STRIP;
      std::vector<double> min, max;
      bounds_of(positions.data() + 3 * first, count, min, max);
      primitive.attributes["POSITION"] =
          builder.add_accessor(position_view, 12 * first, TINYGLTF_COMPONENT_TYPE_FLOAT,
                               TINYGLTF_TYPE_VEC3, count, false, min, max);
      if (attribute) {
        primitive.attributes["_ATTRIBUTE"] =
            builder.add_accessor(values, 4 * first, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                 TINYGLTF_TYPE_SCALAR, count, true);
        primitive.attributes["TEXCOORD_0"] =
            builder.add_accessor(texcoord_view, 4 * first, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                 TINYGLTF_TYPE_VEC2, count, true);
        if (colour_view >= 0)
          primitive.attributes["COLOR_0"] =
              builder.add_accessor(colour_view, 4 * first, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                   TINYGLTF_TYPE_VEC4, count, true);
      }
      mesh.primitives.push_back(std::move(primitive));
    }
    if (mesh.primitives.empty()) throw Error("--lines: no line has two points");
  }
  if (attribute) mesh.extras = attribute_extras(attribute->name, range);
  model.meshes.push_back(std::move(mesh));
}

// Writes one output file through `write`, under a temporary name until complete.
void write_output(const std::string& path, const std::function<bool(std::ostream&)>& write) {
  AtomicFile file(path);
  const auto failed = [&](const char* what) {
    return OutputError(path, std::string(what) +
                                 (errno ? std::string(": ") + std::strerror(errno) : "") + " (" +
                                 file.temp_path() + ")");
  };
  errno = 0;
  std::ofstream out(file.temp_path(), std::ios::binary);
  if (!out) throw failed("cannot create");
  if (!write(out) || !out.flush()) throw failed("write failed");
  out.close();
  if (!out) throw failed("write failed");
  file.commit();
}

// A relative URI reference for a file name (RFC 3986: unreserved characters stay).
std::string uri_of(const std::string& name) {
  std::string out;
  for (unsigned char c : name) {
    if (std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~') {
      out += char(c);
    } else {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", c);
      out += hex;
    }
  }
  return out;
}

// The model's JSON with the one buffer of `bytes` (`uri`: in a file of that name; empty: the
// GLB's BIN chunk).
nlohmann::json model_json(const tinygltf::Model& model, uint64_t bytes, const std::string& uri) {
  std::ostringstream text;
  tinygltf::TinyGLTF writer;
  writer.WriteGltfSceneToStream(&model, text, false, false);
  nlohmann::json doc = nlohmann::json::parse(text.str());
  doc["buffers"][0] = {{"byteLength", bytes}};
  if (!uri.empty()) doc["buffers"][0]["uri"] = uri;
  return doc;
}

void put_u32(std::ostream& out, uint32_t value) {
  const char bytes[4] = {char(value & 0xFF), char((value >> 8) & 0xFF), char((value >> 16) & 0xFF),
                         char(value >> 24)};
  out.write(bytes, 4);
}

// The model of an export, built by one pass over the data (write_gltf).
struct Pass {
  tinygltf::Model model;
  uint64_t buffer_bytes = 0;
};

Pass run_pass(const TubeChunks* tubes, const LineSet* lines, const GltfOptions& options, bool glb,
              DracoChunks* draco, ByteSink sink, const std::function<void()>& chunk_done) {
  Pass pass;
  tinygltf::Model& model = pass.model;
  model.asset.version = "2.0";
  model.asset.generator = "linebake " LINEBAKE_VERSION;
  model.asset.extras = tinygltf::Value(tinygltf::Value::Object{
      {"linebake_axes", tinygltf::Value(std::string(options.axes == GltfAxes::ZUp
                                                        ? "z-up: glTF (x, y, z) = data (x, z, -y)"
                                                        : "raw: data coordinates as stored"))}});
  ModelBuilder builder(model, glb, std::move(sink));
  tinygltf::Material material;
  material.name = "tubes";
  material.pbrMetallicRoughness.metallicFactor = 0.0;
  material.pbrMetallicRoughness.roughnessFactor = 0.6;
  model.materials.push_back(material);
  if (tubes) add_tubes(model, builder, *tubes, options, draco, chunk_done);
  if (lines) add_lines(model, builder, *lines, tubes ? &tubes->description : nullptr, options);
  tinygltf::Scene scene;
  const std::array<double, 3>& o = options.origin;
  for (size_t m = 0; m < model.meshes.size(); ++m) {
    tinygltf::Node node;
    node.mesh = int(m);
    node.name = model.meshes[m].name;
    if (o != std::array<double, 3>{0, 0, 0})  // in glTF's axes, as the vertices
      node.translation = options.axes == GltfAxes::ZUp ? std::vector<double>{o[0], o[2], -o[1]}
                                                       : std::vector<double>{o[0], o[1], o[2]};
    model.nodes.push_back(node);
    scene.nodes.push_back(int(m));
  }
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  if (options.draco && tubes) {
    model.extensionsUsed.push_back(kDraco);
    model.extensionsRequired.push_back(kDraco);
  }
  pass.buffer_bytes = builder.finish();
  return pass;
}

}  // namespace

std::string lowercase_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

void write_gltf(const std::string& path, const TubeChunks* tubes, const LineSet* lines,
                const GltfOptions& options) {
  if (!tubes && !lines) throw Error("glTF export: nothing to export");
  const bool glb = !is_gltf_json(path);
  const size_t chunks = tubes ? tubes->description.chunks.size() : 0;
  TerminalProgress progress("export " + std::filesystem::path(path).filename().string());
  size_t chunks_done = 0;
  const auto chunk_done = [&] {
    throw_if_interrupted();  // Ctrl-C between chunks: nothing is written (cmd_export's group)
    progress.update(++chunks_done, 2 * chunks);
  };
  DracoChunks draco;
  if (options.draco && tubes) draco.spill = std::make_unique<SpillFile>(path, "draco");
  // Each pass hashes the buffer's bytes: the second must write what the first laid out (the
  // accessors' bounds come from the first), or the data changed in between.
  Hasher laid_out, wrote;
  Pass layout;
  try {
    layout = run_pass(
        tubes, lines, options, glb, &draco,
        [&](const void* data, size_t bytes) { laid_out.update(data, bytes); }, chunk_done);
  } catch (const BudgetExceeded& e) {
    throw BudgetExceeded(path + ": " + e.what());  // a Draco piece past its limit: still exit 4
  } catch (const Error& e) {
    // What the export itself cannot do (the GLB limit, lines glTF cannot hold, Draco) is about
    // the output; an input's error stays what it is.
    if (typeid(e) != typeid(Error)) throw;
    throw OutputError(path, e.what());
  }
  const auto write_buffer = [&](std::ostream& out) {
    const Pass written = run_pass(
        tubes, lines, options, glb, &draco,
        [&](const void* data, size_t bytes) {
          out.write(static_cast<const char*>(data), std::streamsize(bytes));
          wrote.update(data, bytes);
        },
        chunk_done);
    if (written.buffer_bytes != layout.buffer_bytes || wrote.hex() != laid_out.hex())
      throw Error(path + ": the data changed between the export's two passes (" +
                  std::to_string(layout.buffer_bytes) + " then " +
                  std::to_string(written.buffer_bytes) +
                  " buffer bytes): was the cache rewritten meanwhile? Nothing was written");
    return bool(out);
  };
  if (!glb) {
    // The buffer in a .bin beside the file the JSON goes to (a symbolic link's target:
    // AtomicFile writes through it), so that its relative uri finds it.
    const std::filesystem::path bin =
        std::filesystem::path(output_target(path)).replace_extension(".bin");
    const nlohmann::json doc =
        model_json(layout.model, layout.buffer_bytes, uri_of(bin.filename().string()));
    write_output(bin.string(), write_buffer);
    write_output(path, [&](std::ostream& out) { return bool(out << json_text(doc, 2) << '\n'); });
    return;
  }
  // GLB (glTF 2.0, section 4.4): a 12-byte header, the JSON chunk padded with spaces, the BIN
  // chunk padded with zeros (the buffer is padded already).
  std::string json = json_text(model_json(layout.model, layout.buffer_bytes, ""));
  json.resize(ModelBuilder::aligned(json.size()), ' ');
  const uint64_t length =
      12 + 8 + json.size() + (layout.buffer_bytes ? 8 + layout.buffer_bytes : 0);
  if (length > kGlbLimit)
    throw OutputError(path,
                      "the export exceeds GLB's 4 GiB limit (write .gltf, whose .bin has none)");
  write_output(path, [&](std::ostream& out) {
    out.write("glTF", 4);
    put_u32(out, 2);
    put_u32(out, uint32_t(length));
    put_u32(out, uint32_t(json.size()));
    out.write("JSON", 4);
    out.write(json.data(), std::streamsize(json.size()));
    if (layout.buffer_bytes == 0) return bool(out);
    put_u32(out, uint32_t(layout.buffer_bytes));
    out.write("BIN\0", 4);
    return write_buffer(out);
  });
}

void write_gltf(const std::string& path, const TubeMesh* tubes, const LineSet* lines,
                const GltfOptions& options) {
  if (!tubes) return write_gltf(path, static_cast<const TubeChunks*>(nullptr), lines, options);
  TubeMesh description = *tubes;  // the chunks' arrays are shared views
  const TubeChunks chunks{std::move(description),
                          [tubes](size_t index) { return tubes->chunks[index]; }};
  write_gltf(path, &chunks, lines, options);
}

}  // namespace linebake
