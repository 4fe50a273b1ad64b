#include "formats/vdb.hpp"

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <filesystem>
#include <ostream>
#include <streambuf>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/memory_budget.hpp"

namespace linebake {

void write_vdb(const std::string& path, const VoxelGrid& g) {
  openvdb::initialize();
  const double h = g.voxel_size;
  auto transform = openvdb::math::Transform::createLinearTransform(h);
  // OpenVDB index (i, j, k) is the centre of a voxel; ours spans [origin + i h, origin + (i+1) h].
  transform->postTranslate(
      openvdb::Vec3d(g.origin[0] + 0.5 * h, g.origin[1] + 0.5 * h, g.origin[2] + 0.5 * h));
  auto density = openvdb::FloatGrid::create(0.0f);
  auto line_count = openvdb::Int32Grid::create(0);
  const bool has_attribute = !g.attribute.empty();
  auto attribute_max = openvdb::FloatGrid::create(0.0f);
  density->setName("density");
  density->setGridClass(openvdb::GRID_FOG_VOLUME);
  line_count->setName("line_count");
  attribute_max->setName("attribute_max");
  for (openvdb::GridBase::Ptr grid :
       std::initializer_list<openvdb::GridBase::Ptr>{density, line_count, attribute_max})
    grid->setTransform(transform);
  auto d = density->getAccessor();
  auto n = line_count->getAccessor();
  auto a = attribute_max->getAccessor();
  const float lo = g.attribute_range[0], span = g.attribute_range[1] - g.attribute_range[0];
  for (uint32_t z = 0; z < g.resolution[2]; ++z)
    for (uint32_t y = 0; y < g.resolution[1]; ++y)
      for (uint32_t x = 0; x < g.resolution[0]; ++x) {
        const uint64_t v = g.index(x, y, z);
        if (g.line_counts[v] == 0) continue;
        const openvdb::Coord ijk{static_cast<int>(x), static_cast<int>(y), static_cast<int>(z)};
        d.setValue(ijk, g.density[0][v]);
        n.setValue(ijk, g.line_counts[v]);
        if (has_attribute && g.offsets[v + 1] > g.offsets[v]) {
          uint8_t most = 0;
          for (uint32_t c = g.offsets[v]; c < g.offsets[v + 1]; ++c) {
            const DecodedChord chord =
                unpack_chord(g.chords[2 * c], g.chords[2 * c + 1], g.quantization);
            most = std::max({most, chord.attribute_start, chord.attribute_end});
          }
          a.setValue(ijk, lo + span * float(most) / 255.0f);
        }
      }
  openvdb::GridPtrVec grids{density, line_count};
  if (has_attribute) grids.push_back(attribute_max);
  openvdb::MetaMap meta;
  meta.insertMeta("creator", openvdb::StringMetadata("linebake " LINEBAKE_VERSION));
  meta.insertMeta("linebake_attribute", openvdb::StringMetadata(g.attribute));
  meta.insertMeta("linebake_quantization", openvdb::Int32Metadata(int(g.quantization)));

  AtomicFile file(path);
  try {
    openvdb::io::File out(file.temp_path());
    out.setCompression(openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
    out.write(grids, meta);
    out.close();
  } catch (const std::exception& e) {
    throw OutputError(path, std::string("OpenVDB: ") + e.what() + " (" + file.temp_path() + ")");
  }
  // OpenVDB does not check its stream after writing: a full disk leaves a short file without an
  // error. The same grids serialised into a counting stream give the size the file must have
  // (a non-seekable archive writes the same bytes, only its offsets are left unpatched).
  struct Counter : std::streambuf {
    uint64_t bytes = 0;
    int_type overflow(int_type c) override {
      ++bytes;
      return traits_type::not_eof(c);
    }
    std::streamsize xsputn(const char*, std::streamsize n) override {
      bytes += uint64_t(n);
      return n;
    }
  } counter;
  {
    std::ostream sink(&counter);
    openvdb::io::Stream stream(sink);
    stream.setCompression(openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
    stream.write(grids, meta);
  }
  std::error_code ec;
  const uint64_t written = std::filesystem::file_size(file.temp_path(), ec);
  if (ec || written != counter.bytes)
    throw OutputError(path, "write failed: " + std::to_string(ec ? 0 : written) + " of " +
                                std::to_string(counter.bytes) + " bytes reached the file (" +
                                format_bytes(free_bytes_for(path)) + " free there) (" +
                                file.temp_path() + ")");
  file.commit();
}

}  // namespace linebake
