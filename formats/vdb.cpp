#include "formats/vdb.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/memory_budget.hpp"
#include "formats/vdb_module.h"

namespace linebake {
namespace {

float chord_length(const DecodedChord& c) {
  const float dx = c.end[0] - c.start[0], dy = c.end[1] - c.start[1], dz = c.end[2] - c.start[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// The 99th percentile of the non-zero values: one dense knot of lines should not make the
// rest of the volume invisible, as the maximum would.
float percentile_99(std::vector<float> values) {
  std::erase_if(values, [](float v) { return !(v > 0); });
  if (values.empty()) return 1;
  const size_t at = std::min(values.size() - 1, size_t(0.99 * double(values.size())));
  std::nth_element(values.begin(), values.begin() + ptrdiff_t(at), values.end());
  return values[at];
}

// liblinebake_vdb.so beside the executable, else in the build tree it was built in.
LinebakeVdbWrite load_vdb_module(const std::string& output) {
  static std::once_flag once;
  static LinebakeVdbWrite write = nullptr;
  static std::string failure;
  std::call_once(once, [] {
    std::vector<std::string> tried;
    std::error_code ec;
    const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    std::vector<std::filesystem::path> dirs;
    if (!ec) dirs.push_back(exe.parent_path());
    dirs.emplace_back(LINEBAKE_MODULE_DIR);
    for (const auto& dir : dirs) {
      const std::string path = (dir / "liblinebake_vdb.so").string();
      if (void* module = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
        write = reinterpret_cast<LinebakeVdbWrite>(dlsym(module, LINEBAKE_VDB_WRITE_SYMBOL));
        if (write) return;
        tried.push_back(path + ": no " LINEBAKE_VDB_WRITE_SYMBOL);
      } else {
        tried.push_back(dlerror());
      }
    }
    for (const std::string& t : tried) failure += (failure.empty() ? "" : "; ") + t;
  });
  if (!write)
    throw OutputError(output,
                      "VDB export needs linebake's OpenVDB module, liblinebake_vdb.so, "
                      "which was not found or did not load (" +
                          failure + ")");
  return write;
}

// A VDB file starts with the magic number (8 bytes), the file format version and the library's
// major and minor version (4 bytes each), a flag for grid offsets (1 byte) and the file's UUID,
// 36 characters that OpenVDB's writer draws at random (io::File has no way to set them). So that
// the same grid gives the same file, they are replaced by a UUID made from the bytes after them:
// version 8 (RFC 9562: custom), the rest from their XXH3-128. A header laid out otherwise (an
// OpenVDB of another format version) is left as it is.
constexpr std::streamoff kVdbUuidOffset = 21;
constexpr size_t kVdbUuidChars = 36;

bool looks_like_uuid(const char* text) {
  for (size_t i = 0; i < kVdbUuidChars; ++i) {
    const bool dash = i == 8 || i == 13 || i == 18 || i == 23;
    if (dash ? text[i] != '-' : !std::isxdigit(static_cast<unsigned char>(text[i]))) return false;
  }
  return true;
}

void stamp_content_uuid(const std::string& file, const std::string& output) {
  std::fstream io(file, std::ios::binary | std::ios::in | std::ios::out);
  char header[kVdbUuidOffset + kVdbUuidChars];
  if (!io.read(header, sizeof header))
    throw OutputError(output, "cannot read back the VDB header (" + file + ")");
  uint32_t format_version = 0;
  std::memcpy(&format_version, header + 8, 4);
  if (std::memcmp(header, " BDV\0\0\0\0", 8) != 0 || format_version < 220 ||
      !looks_like_uuid(header + kVdbUuidOffset))
    return;
  Hasher hasher;
  std::vector<char> block(size_t{1} << 20);
  while (io.read(block.data(), std::streamsize(block.size())) || io.gcount() > 0)
    hasher.update(block.data(), size_t(io.gcount()));
  const std::string h = hasher.hex();  // 32 hex digits
  const char variant = "89ab"[std::stoi(h.substr(16, 1), nullptr, 16) & 3];
  const std::string uuid = h.substr(0, 8) + "-" + h.substr(8, 4) + "-8" + h.substr(13, 3) + "-" +
                           variant + h.substr(17, 3) + "-" + h.substr(20, 12);
  io.clear();
  io.seekp(kVdbUuidOffset);
  if (!io.write(uuid.data(), std::streamsize(uuid.size())) || !io.flush())
    throw OutputError(output, "cannot write the VDB header (" + file + ")");
}

}  // namespace

VdbGrids vdb_grids(const VoxelGrid& g) {
  VdbGrids out;
  const double h = g.voxel_size;
  out.voxel_size = h;
  // OpenVDB index (i, j, k) is the centre of a voxel; ours spans [origin + i h, origin + (i+1) h].
  for (int a = 0; a < 3; ++a) out.first_centre[a] = double(g.origin[a]) + 0.5 * h;
  const bool has_attribute = !g.attribute.empty();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> length, attribute_density, count, attribute_max;
  const float lo = g.attribute_range[0], span = g.attribute_range[1] - g.attribute_range[0];
  for (uint32_t z = 0; z < g.resolution[2]; ++z)
    for (uint32_t y = 0; y < g.resolution[1]; ++y)
      for (uint32_t x = 0; x < g.resolution[0]; ++x) {
        const uint64_t v = g.index(x, y, z);
        if (g.line_counts[v] == 0) continue;
        out.active.push_back({int32_t(x), int32_t(y), int32_t(z)});
        float sum = 0;
        uint8_t most = 0;
        for (uint32_t c = g.offsets[v]; c < g.offsets[v + 1]; ++c) {
          const DecodedChord chord =
              unpack_chord(g.chords[2 * c], g.chords[2 * c + 1], g.quantization);
          sum += chord_length(chord);
          most = std::max({most, chord.attribute_start, chord.attribute_end});
        }
        length.push_back(sum);
        count.push_back(float(g.line_counts[v]));
        if (!has_attribute) continue;
        attribute_density.push_back(g.density[0][v]);
        attribute_max.push_back(g.offsets[v + 1] > g.offsets[v] ? lo + span * float(most) / 255.0f
                                                                : nan);
      }
  out.density_scale = percentile_99(length);
  for (float& l : length) l = std::min(1.0f, l / out.density_scale);
  out.grids.push_back({"density",
                       "chord length in the voxel (voxel units) / linebake_density_scale, "
                       "clamped to [0, 1]",
                       true, std::move(length)});
  if (has_attribute)
    out.grids.push_back({"attribute_density",
                         "polyline length in the voxel (voxel units) x mean " + g.attribute +
                             " normalised to [0, 1]",
                         true, std::move(attribute_density)});
  out.grids.push_back(
      {"line_count", "distinct lines in the voxel (saturating at 255)", false, std::move(count)});
  if (has_attribute)
    out.grids.push_back({"attribute_chord_max",
                         "largest " + g.attribute + " at the voxel's chord ends (data units)",
                         false, std::move(attribute_max)});
  return out;
}

void write_vdb(const std::string& path, const VoxelGrid& grid) {
  const LinebakeVdbWrite write = load_vdb_module(path);
  const VdbGrids grids = vdb_grids(grid);
  std::vector<LinebakeVdbGrid> specs;
  for (const VdbGrids::Grid& g : grids.grids)
    specs.push_back({g.name.c_str(), g.description.c_str(), g.fog_volume, g.values.data()});
  const std::string creator = "linebake " LINEBAKE_VERSION;
  const std::vector<LinebakeVdbMeta> meta{
      {"creator", creator.c_str(), 0, 0},
      {"linebake_attribute", grid.attribute.c_str(), 0, 0},
      {"linebake_quantization", nullptr, double(grid.quantization), 1},
      {"linebake_density_scale", nullptr, double(grids.density_scale), 0},
      {"linebake_axes", "data: x, y, z as stored", 0, 0}};
  const LinebakeVdbFile file{
      grids.voxel_size,    {grids.first_centre[0], grids.first_centre[1], grids.first_centre[2]},
      grids.active.size(), reinterpret_cast<const int32_t*>(grids.active.data()),
      specs.data(),        uint32_t(specs.size()),
      meta.data(),         uint32_t(meta.size())};
  AtomicFile out(path);
  uint64_t expected = 0;
  char error[1024] = "";
  if (write(out.temp_path().c_str(), &file, &expected, error, sizeof error) != 0)
    throw OutputError(path, std::string(error) + " (" + out.temp_path() + ")");
  std::error_code ec;
  const uint64_t written = std::filesystem::file_size(out.temp_path(), ec);
  if (ec || written != expected)
    throw OutputError(path, "write failed: " + std::to_string(ec ? 0 : written) + " of " +
                                std::to_string(expected) + " bytes reached the file (" +
                                format_bytes(free_bytes_for(path)) + " free there) (" +
                                out.temp_path() + ")");
  stamp_content_uuid(out.temp_path(), path);
  out.commit();
}

}  // namespace linebake
