#include "formats/vdb.hpp"

#include <dlfcn.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/interrupt.hpp"
#include "core/memory_budget.hpp"
#include "core/progress.hpp"
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
const LinebakeVdbModule& load_vdb_module(const std::string& output) {
  static std::once_flag once;
  static const LinebakeVdbModule* module = nullptr;
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
      if (void* library = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
        if (const auto get =
                reinterpret_cast<LinebakeVdbModuleFn>(dlsym(library, LINEBAKE_VDB_MODULE_SYMBOL)))
          module = get();
        if (module) return;
        tried.push_back(path + ": no " LINEBAKE_VDB_MODULE_SYMBOL);
      } else {
        tried.push_back(dlerror());
      }
    }
    for (const std::string& t : tried) failure += (failure.empty() ? "" : "; ") + t;
  });
  if (!module)
    throw OutputError(output,
                      "VDB export needs linebake's OpenVDB module, liblinebake_vdb.so, "
                      "which was not found or did not load (" +
                          failure + ")");
  return *module;
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

// The module's grids being built, let go however the export ends.
struct VdbBuild {
  const LinebakeVdbModule& module;
  std::string output;
  LinebakeVdbBuild* grids = nullptr;
  char error[1024] = "";

  VdbBuild(const LinebakeVdbModule& m, const std::string& path) : module(m), output(path) {}
  ~VdbBuild() {
    if (grids) module.end(grids);
  }
  VdbBuild(const VdbBuild&) = delete;
  VdbBuild& operator=(const VdbBuild&) = delete;
  // Throws OutputError with the module's message where a call failed (BudgetExceeded where
  // memory ran out).
  void check(int failed) const {
    if (failed == 2) throw BudgetExceeded(output + ": " + error);
    if (failed) throw OutputError(output, error);
  }
};

}  // namespace

void load_vdb(const std::string& output) {
  char error[1024] = "";
  if (load_vdb_module(output).initialize(error, sizeof error) != 0)
    throw OutputError(output, error);
}

uint64_t vdb_build_bytes(const VoxelGrid& g) {
  const auto nodes = [&](uint32_t size) {
    uint64_t n = 1;
    for (uint32_t axis = 0; axis < 3; ++axis) n *= (g.resolution[axis] + size - 1) / size;
    return n;
  };
  // OpenVDB's FloatGrid: a leaf of 8^3 values (2 KiB, its masks and header) wherever a voxel is
  // active, at most every leaf of the grid and one per active voxel; 16^3 of them under an
  // internal node (32 KiB of tables and masks), 32^3 of those under the next (256 KiB).
  const uint64_t leaves = std::min<uint64_t>(nodes(8), g.voxels_occupied);
  const uint64_t per_grid = leaves * 2200 + nodes(128) * 34000 + nodes(4096) * 270000;
  const uint64_t grids = g.attribute.empty() ? 2 : 4;
  // The lengths kept for the scale (twice, as the percentile is taken), the pieces and the
  // cache's chunk decoding (8 MiB), and a tenth and 16 MiB more. (The module itself, about 30
  // MiB, is loaded before the process's memory is measured: load_vdb.)
  const uint64_t bytes =
      grids * per_grid + 8 * g.voxels_occupied + VdbPieces{}.bytes() + (uint64_t{8} << 20);
  return bytes + bytes / 10 + (uint64_t{16} << 20);
}

void write_vdb(const std::string& path, VoxelPieces& pieces, const VdbPieces& sizes,
               const std::array<double, 3>& origin) {
  const VoxelGrid& g = pieces.description();
  // OpenVDB's linear transforms refuse a scale whose determinant is below 3e-15 (ScaleMap, in
  // openvdb/math/Maps.h), so voxels smaller than about 1.45e-5 units cannot be written.
  if (!(g.voxel_size * g.voxel_size * g.voxel_size >= 3e-15)) {
    char size[32];
    std::snprintf(size, sizeof size, "%.3g", g.voxel_size);
    throw OutputError(path, std::string("OpenVDB cannot hold voxels of ") + size +
                                " units: its transforms need voxels of about 1.45e-5 or more "
                                "(a scale whose cube is 3e-15); bake the voxels on a coarser "
                                "--grid, or the lines in smaller units (e.g. mm, not m)");
  }
  const LinebakeVdbModule& module = load_vdb_module(path);
  const bool has_attribute = !g.attribute.empty();
  const std::string attribute_density =
      "polyline length in the voxel (voxel units) x mean " + g.attribute + " normalised to [0, 1]";
  const std::string attribute_max =
      "largest " + g.attribute + " at the voxel's chord ends (data units)";
  std::vector<LinebakeVdbGrid> specs{
      {"density",
       "chord length in the voxel (voxel units) / linebake_density_scale, clamped to [0, 1]", 1}};
  if (has_attribute) specs.push_back({"attribute_density", attribute_density.c_str(), 1});
  specs.push_back({"line_count", "distinct lines in the voxel (saturating at 255)", 0});
  if (has_attribute) specs.push_back({"attribute_chord_max", attribute_max.c_str(), 0});
  // OpenVDB index (i, j, k) is the centre of a voxel; ours spans [origin + i h, origin + (i+1) h].
  const double h = g.voxel_size;
  // The lines' origin (world = origin + position) moves the grid's, in double.
  const double first_centre[3] = {origin[0] + double(g.origin[0]) + 0.5 * h,
                                  origin[1] + double(g.origin[1]) + 0.5 * h,
                                  origin[2] + double(g.origin[2]) + 0.5 * h};
  VdbBuild build(module, path);
  build.check(module.begin(h, first_centre, specs.data(), uint32_t(specs.size()), &build.grids,
                           build.error, sizeof build.error));

  // The voxels a block at a time (its offsets read once), each block in runs whose chords fit
  // sizes.chords; the active voxels of a run go to the module.
  const uint64_t voxels = g.voxel_count();
  const uint64_t row = g.resolution[0], slice = row * g.resolution[1];
  const float lo = g.attribute_range[0], span = g.attribute_range[1] - g.attribute_range[0];
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<uint32_t> offsets, chords;
  std::vector<uint8_t> line_counts;
  std::vector<float> density, lengths;
  std::vector<int32_t> ijk;
  std::vector<std::vector<float>> values(specs.size());
  const uint64_t block_size = std::max<uint64_t>(sizes.voxels, 1);
  TerminalProgress progress("export " + std::filesystem::path(path).filename().string());
  for (uint64_t block = 0; block < voxels; block += block_size) {
    throw_if_interrupted();
    progress.update(block, voxels);
    const uint64_t block_voxels = std::min(block_size, voxels - block);
    offsets.resize(block_voxels + 1);
    pieces.offsets(block, block_voxels + 1, offsets.data());
    for (uint64_t start = 0; start < block_voxels;) {
      // The longest run from `start` whose chords fit, at least one voxel.
      uint64_t end = uint64_t(std::upper_bound(offsets.begin() + ptrdiff_t(start) + 1,
                                               offsets.end(), offsets[start] + sizes.chords) -
                              offsets.begin()) -
                     1;
      end = std::max(end, start + 1);
      const uint64_t first = block + start, count = end - start;
      const uint32_t* offset = offsets.data() + start;
      line_counts.resize(count);
      pieces.line_counts(first, count, line_counts.data());
      if (has_attribute) {
        density.resize(count);
        pieces.density(first, count, density.data());
      }
      chords.resize(2 * uint64_t(offset[count] - offset[0]));
      pieces.chords(offset[0], offset[count] - offset[0], chords.data());
      ijk.clear();
      for (auto& v : values) v.clear();
      for (uint64_t i = 0; i < count; ++i) {
        if (line_counts[i] == 0) continue;
        const uint64_t v = first + i;
        ijk.insert(ijk.end(),
                   {int32_t(v % row), int32_t(v / row % g.resolution[1]), int32_t(v / slice)});
        float sum = 0;
        uint8_t most = 0;
        for (uint32_t c = offset[i]; c < offset[i + 1]; ++c) {
          const uint64_t at = 2 * uint64_t(c - offset[0]);
          const DecodedChord chord = unpack_chord(chords[at], chords[at + 1], g.quantization);
          sum += chord_length(chord);
          most = std::max({most, chord.attribute_start, chord.attribute_end});
        }
        lengths.push_back(sum);
        size_t k = 0;
        values[k++].push_back(sum);
        if (has_attribute) values[k++].push_back(density[i]);
        values[k++].push_back(float(line_counts[i]));
        if (has_attribute)
          values[k++].push_back(offset[i + 1] > offset[i] ? lo + span * float(most) / 255.0f : nan);
      }
      std::vector<const float*> columns;
      for (const auto& v : values) columns.push_back(v.data());
      build.check(module.add(build.grids, ijk.size() / 3, ijk.data(), columns.data(), build.error,
                             sizeof build.error));
      start = end;
    }
  }
  progress.finish();
  pieces.finish();
  const float density_scale = percentile_99(std::move(lengths));
  build.check(module.rescale(build.grids, 0, density_scale, build.error, sizeof build.error));
  throw_if_interrupted();

  const std::string creator = "linebake " LINEBAKE_VERSION;
  const std::vector<LinebakeVdbMeta> meta{
      {"creator", creator.c_str(), 0, 0},
      {"linebake_attribute", g.attribute.c_str(), 0, 0},
      {"linebake_quantization", nullptr, double(g.quantization), 1},
      {"linebake_density_scale", nullptr, double(density_scale), 0},
      {"linebake_axes", "data: x, y, z as stored", 0, 0}};
  AtomicFile out(path);
  // OpenVDB opens its file through std::ofstream, whose failure says no why ("could not open
  // ... for writing"): the temporary is made here first, so that a file system out of inodes,
  // a permission or a read-only file system is said as the system says it.
  const int fd = ::open(out.temp_path().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0)
    throw OutputError(
        path, std::string("cannot create: ") + std::strerror(errno) + " (" + out.temp_path() + ")");
  ::close(fd);
  uint64_t expected = 0;
  if (module.write(build.grids, out.temp_path().c_str(), meta.data(), uint32_t(meta.size()),
                   &expected, build.error, sizeof build.error) != 0)
    throw OutputError(path, std::string(build.error) + " (" + out.temp_path() + ")");
  std::error_code ec;
  const uint64_t written = std::filesystem::file_size(out.temp_path(), ec);
  if (ec || written != expected)
    throw OutputError(path, "write failed: " + std::to_string(ec ? 0 : written) + " of " +
                                std::to_string(expected) + " bytes reached the file (" +
                                format_bytes(free_bytes_for(path)) + " free there) (" +
                                out.temp_path() + ")");
  stamp_content_uuid(out.temp_path(), path);
  throw_if_interrupted();  // OpenVDB's write is not ours to stop: nothing renamed after a Ctrl-C
  out.commit();
}

void write_vdb(const std::string& path, const VoxelGrid& grid,
               const std::array<double, 3>& origin) {
  GridPieces pieces(grid);
  write_vdb(path, pieces, {}, origin);
}

}  // namespace linebake
