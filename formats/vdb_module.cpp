// liblinebake_vdb.so: the OpenVDB side of the VDB export (formats/vdb_module.h says why it is
// a module). It knows nothing of linebake: plain grids in, a .vdb file out.

#include "formats/vdb_module.h"

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdio>
#include <ostream>
#include <streambuf>

namespace {

openvdb::GridPtrVec make_grids(const LinebakeVdbFile& f) {
  const double h = f.voxel_size;
  auto transform = openvdb::math::Transform::createLinearTransform(h);
  transform->postTranslate(openvdb::Vec3d(f.first_centre[0], f.first_centre[1], f.first_centre[2]));
  openvdb::GridPtrVec grids;
  for (uint32_t g = 0; g < f.grid_count; ++g) {
    const LinebakeVdbGrid& spec = f.grids[g];
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName(spec.name);
    grid->setGridClass(spec.fog_volume ? openvdb::GRID_FOG_VOLUME : openvdb::GRID_UNKNOWN);
    grid->insertMeta("description", openvdb::StringMetadata(spec.description));
    grid->setTransform(transform);
    auto values = grid->getAccessor();
    for (uint64_t i = 0; i < f.active_count; ++i)
      if (!std::isnan(spec.values[i]))
        values.setValue(openvdb::Coord(f.ijk[3 * i], f.ijk[3 * i + 1], f.ijk[3 * i + 2]),
                        spec.values[i]);
    grids.push_back(grid);
  }
  return grids;
}

openvdb::MetaMap make_meta(const LinebakeVdbFile& f) {
  openvdb::MetaMap meta;
  for (uint32_t m = 0; m < f.meta_count; ++m) {
    const LinebakeVdbMeta& e = f.meta[m];
    if (e.string_value)
      meta.insertMeta(e.key, openvdb::StringMetadata(e.string_value));
    else if (e.integer)
      meta.insertMeta(e.key, openvdb::Int64Metadata(int64_t(e.number)));
    else
      meta.insertMeta(e.key, openvdb::DoubleMetadata(e.number));
  }
  return meta;
}

constexpr uint32_t kCompression = openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK;

uint64_t serialised_bytes(const openvdb::GridPtrVec& grids, const openvdb::MetaMap& meta) {
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
  std::ostream sink(&counter);
  // A non-seekable archive writes the same bytes as the file, only its offsets unpatched.
  openvdb::io::Stream stream(sink);
  stream.setCompression(kCompression);
  stream.write(grids, meta);
  return counter.bytes;
}

}  // namespace

extern "C" __attribute__((visibility("default"))) int linebake_vdb_write_v1(
    const char* path, const LinebakeVdbFile* file, uint64_t* expected_bytes, char* error,
    size_t error_size) {
  try {
    openvdb::initialize();
    const openvdb::GridPtrVec grids = make_grids(*file);
    const openvdb::MetaMap meta = make_meta(*file);
    openvdb::io::File out(path);
    out.setCompression(kCompression);
    out.write(grids, meta);
    out.close();
    *expected_bytes = serialised_bytes(grids, meta);
    return 0;
  } catch (const std::exception& e) {
    std::snprintf(error, error_size, "OpenVDB: %s", e.what());
  } catch (...) {
    std::snprintf(error, error_size, "OpenVDB: unknown exception");
  }
  return 1;
}
