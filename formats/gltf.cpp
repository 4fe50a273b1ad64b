#include "formats/gltf.hpp"

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
#include <cstring>
#include <fstream>
#include <limits>

#include "core/atomic_file.hpp"
#include "core/error.hpp"

namespace linebake {
namespace {

constexpr int kArrayBuffer = 34962;
constexpr int kElementArrayBuffer = 34963;
constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr uint64_t kGlbLimit = 0xFFFFFFFFull;

// Builds the single binary buffer and the views/accessors that point into it.
class ModelBuilder {
 public:
  explicit ModelBuilder(tinygltf::Model& model) : model_(model) { model_.buffers.emplace_back(); }

  // Appends bytes (4-byte aligned) as a new buffer view; returns its index.
  int add_view(const void* data, size_t bytes, int target, size_t stride = 0) {
    auto& buffer = model_.buffers[0].data;
    buffer.resize((buffer.size() + 3) & ~size_t{3});
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = buffer.size();
    view.byteLength = bytes;
    view.byteStride = stride;
    view.target = target;
    const auto* p = static_cast<const unsigned char*>(data);
    buffer.insert(buffer.end(), p, p + bytes);
    if (buffer.size() > kGlbLimit) throw Error("the export exceeds GLB's 4 GiB limit");
    model_.bufferViews.push_back(std::move(view));
    return int(model_.bufferViews.size() - 1);
  }

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

// Float normals of a chunk whatever its encoding (glTF NORMAL is FLOAT VEC3).
std::vector<float> float_normals(const TubeChunk& chunk) {
  if (!chunk.normals.empty()) return {chunk.normals.begin(), chunk.normals.end()};
  std::vector<float> out(3 * chunk.vertex_count());
  for (uint64_t v = 0; v < chunk.vertex_count(); ++v) {
    const auto n = decode_octahedral(chunk.normals_oct[2 * v], chunk.normals_oct[2 * v + 1]);
    std::copy(n.begin(), n.end(), out.begin() + 3 * v);
  }
  return out;
}

// glTF wants every vertex attribute element 4-byte aligned: pad uint16 values to a stride of 4.
std::vector<uint16_t> padded_attribute(const TubeChunk& chunk) {
  std::vector<uint16_t> out(2 * chunk.attribute.size(), 0);
  for (size_t i = 0; i < chunk.attribute.size(); ++i) out[2 * i] = chunk.attribute[i];
  return out;
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
  int position = -1, normal = -1, attribute = -1;
};

DracoChunk encode_draco(const TubeChunk& chunk, const std::vector<float>& normals,
                        const GltfOptions& options) {
  draco::Mesh mesh;
  const uint64_t v = chunk.vertex_count();
  mesh.set_num_points(uint32_t(v));
  DracoChunk out;
  out.position = add_draco_attribute(mesh, draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32,
                                     false, chunk.positions.data(), v);
  out.normal = add_draco_attribute(mesh, draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32,
                                   false, normals.data(), v);
  if (!chunk.attribute.empty())
    out.attribute = add_draco_attribute(mesh, draco::GeometryAttribute::GENERIC, 1,
                                        draco::DT_UINT16, true, chunk.attribute.data(), v);
  mesh.SetNumFaces(chunk.triangle_count());
  for (uint64_t t = 0; t < chunk.triangle_count(); ++t)
    mesh.SetFace(draco::FaceIndex(uint32_t(t)), {draco::PointIndex(chunk.indices[3 * t]),
                                                 draco::PointIndex(chunk.indices[3 * t + 1]),
                                                 draco::PointIndex(chunk.indices[3 * t + 2])});
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
  return out;
}

void add_tubes(tinygltf::Model& model, ModelBuilder& builder, const TubeMesh& tubes,
               const GltfOptions& options) {
  tinygltf::Mesh mesh;
  mesh.name = "tubes";
  const bool has_attribute = !tubes.attribute.empty();
  for (const TubeChunk& chunk : tubes.chunks) {
    if (chunk.vertex_count() == 0) continue;
    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;
    primitive.material = 0;
    std::vector<double> min, max;
    bounds_of(chunk.positions.data(), chunk.vertex_count(), min, max);
    const std::vector<float> normals = float_normals(chunk);
    if (options.draco) {
      const DracoChunk d = encode_draco(chunk, normals, options);
      const int view = builder.add_view(d.bytes.data(), d.bytes.size(), 0);
      primitive.attributes["POSITION"] = builder.add_accessor(
          -1, 0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, d.points, false, min, max);
      primitive.attributes["NORMAL"] =
          builder.add_accessor(-1, 0, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, d.points);
      tinygltf::Value::Object attributes{{"POSITION", tinygltf::Value(d.position)},
                                         {"NORMAL", tinygltf::Value(d.normal)}};
      if (has_attribute) {
        primitive.attributes["_ATTRIBUTE"] = builder.add_accessor(
            -1, 0, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR, d.points, true);
        attributes["_ATTRIBUTE"] = tinygltf::Value(d.attribute);
      }
      primitive.indices = builder.add_accessor(-1, 0, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                               TINYGLTF_TYPE_SCALAR, 3 * d.faces);
      primitive.extensions[kDraco] = tinygltf::Value(
          tinygltf::Value::Object{{"bufferView", tinygltf::Value(view)},
                                  {"attributes", tinygltf::Value(std::move(attributes))}});
    } else {
      const uint64_t v = chunk.vertex_count();
      primitive.attributes["POSITION"] = builder.add_accessor(
          builder.add_view(chunk.positions.data(), chunk.positions.bytes(), kArrayBuffer), 0,
          TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, v, false, min, max);
      primitive.attributes["NORMAL"] = builder.add_accessor(
          builder.add_view(normals.data(), normals.size() * sizeof(float), kArrayBuffer), 0,
          TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, v);
      if (has_attribute) {
        const std::vector<uint16_t> padded = padded_attribute(chunk);
        primitive.attributes["_ATTRIBUTE"] = builder.add_accessor(
            builder.add_view(padded.data(), padded.size() * 2, kArrayBuffer, 4), 0,
            TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR, v, true);
      }
      primitive.indices = builder.add_accessor(
          builder.add_view(chunk.indices.data(), chunk.indices.bytes(), kElementArrayBuffer), 0,
          TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, chunk.indices.size());
    }
    mesh.primitives.push_back(std::move(primitive));
  }
  // What a renderer needs to map _ATTRIBUTE back to data values.
  mesh.extras = tinygltf::Value(tinygltf::Value::Object{
      {"linebake_attribute", tinygltf::Value(tubes.attribute)},
      {"linebake_attribute_range",
       tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(double(tubes.attribute_range[0])),
                                              tinygltf::Value(double(tubes.attribute_range[1]))})},
      {"linebake_tube_radius", tinygltf::Value(double(tubes.radius))},
      {"linebake_tube_sides", tinygltf::Value(tubes.sides)}});
  model.meshes.push_back(std::move(mesh));
}

// One LINE_STRIP primitive per polyline, all reading one shared position view.
void add_lines(tinygltf::Model& model, ModelBuilder& builder, const LineSet& lines) {
  tinygltf::Mesh mesh;
  mesh.name = "lines";
  if (lines.positions.size() * sizeof(float) > 0x7FFFFFFFull)
    throw Error("--lines: more than 2 GiB of positions (glTF accessor offsets are 31-bit here)");
  const int positions =
      builder.add_view(lines.positions.data(), lines.positions.size() * sizeof(float), kArrayBuffer,
                       12);  // shared by many accessors: glTF then requires an explicit stride
  const Attribute* attribute = lines.attributes.empty() ? nullptr : &lines.attributes[0];
  const int values =
      attribute ? builder.add_view(attribute->values.data(),
                                   attribute->values.size() * sizeof(float), kArrayBuffer, 4)
                : -1;
  for (size_t l = 0; l < lines.line_count(); ++l) {
    const uint64_t first = lines.line_offsets[l], count = lines.line_size(l);
    if (count < 2) continue;
    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_LINE_STRIP;
    std::vector<double> min, max;
    bounds_of(lines.positions.data() + 3 * first, count, min, max);
    primitive.attributes["POSITION"] =
        builder.add_accessor(positions, 12 * first, TINYGLTF_COMPONENT_TYPE_FLOAT,
                             TINYGLTF_TYPE_VEC3, count, false, min, max);
    if (attribute)
      primitive.attributes["_ATTRIBUTE"] = builder.add_accessor(
          values, 4 * first, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, count);
    mesh.primitives.push_back(std::move(primitive));
  }
  if (attribute)
    mesh.extras = tinygltf::Value(
        tinygltf::Value::Object{{"linebake_attribute", tinygltf::Value(attribute->name)}});
  if (mesh.primitives.empty()) throw Error("--lines: no line has two points");
  model.meshes.push_back(std::move(mesh));
}

}  // namespace

void write_glb(const std::string& path, const TubeMesh* tubes, const LineSet* lines,
               const GltfOptions& options) {
  if (!tubes && !lines) throw Error("glb export: nothing to export");
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "linebake " LINEBAKE_VERSION;
  ModelBuilder builder(model);
  tinygltf::Material material;
  material.name = "tubes";
  material.pbrMetallicRoughness.metallicFactor = 0.0;
  material.pbrMetallicRoughness.roughnessFactor = 0.6;
  model.materials.push_back(material);
  tinygltf::Scene scene;
  try {
    if (tubes) add_tubes(model, builder, *tubes, options);
    if (lines) add_lines(model, builder, *lines);
  } catch (const Error& e) {
    throw OutputError(path, e.what());
  }
  for (size_t m = 0; m < model.meshes.size(); ++m) {
    tinygltf::Node node;
    node.mesh = int(m);
    node.name = model.meshes[m].name;
    model.nodes.push_back(node);
    scene.nodes.push_back(int(m));
  }
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  if (options.draco && tubes) {
    model.extensionsUsed.push_back(kDraco);
    model.extensionsRequired.push_back(kDraco);
  }
  model.buffers[0].data.resize((model.buffers[0].data.size() + 3) & ~size_t{3});

  AtomicFile file(path);
  {
    const auto failed = [&](const char* what) {
      return OutputError(path, std::string(what) +
                                   (errno ? std::string(": ") + std::strerror(errno) : "") + " (" +
                                   file.temp_path() + ")");
    };
    errno = 0;
    std::ofstream out(file.temp_path(), std::ios::binary);
    if (!out) throw failed("cannot create");
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToStream(&model, out, false, true) || !out.flush())
      throw failed("write failed");
    out.close();
    if (!out) throw failed("write failed");
  }
  file.commit();
}

}  // namespace linebake
