// liblinebake_vdb.so: the OpenVDB side of the VDB export (formats/vdb_module.h says why it is
// a module). It knows nothing of linebake: plain grids in, a .vdb file out.

#include "formats/vdb_module.h"

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <new>
#include <ostream>
#include <streambuf>
#include <vector>

namespace {

openvdb::MetaMap make_meta(const LinebakeVdbMeta* entries, uint32_t count) {
  openvdb::MetaMap meta;
  for (uint32_t m = 0; m < count; ++m) {
    const LinebakeVdbMeta& e = entries[m];
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

// Runs `body`, turning an exception into 1 and a message.
template <class Body>
int guarded(char* error, size_t error_size, Body&& body) {
  try {
    body();
    return 0;
  } catch (const std::bad_alloc& e) {
    std::snprintf(error, error_size, "OpenVDB: out of memory (%s)", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::snprintf(error, error_size, "OpenVDB: %s", e.what());
  } catch (...) {
    std::snprintf(error, error_size, "OpenVDB: unknown exception");
  }
  return 1;
}

}  // namespace

struct LinebakeVdbBuild {
  std::vector<openvdb::FloatGrid::Ptr> grids;
  std::vector<openvdb::FloatGrid::Accessor> accessors;
};

namespace {

int initialize(char* error, size_t error_size) {
  return guarded(error, error_size, [] { openvdb::initialize(); });
}

int begin(double voxel_size, const double first_centre[3], const LinebakeVdbGrid* specs,
          uint32_t grid_count, LinebakeVdbBuild** build, char* error, size_t error_size) {
  *build = nullptr;
  return guarded(error, error_size, [&] {
    openvdb::initialize();
    auto transform = openvdb::math::Transform::createLinearTransform(voxel_size);
    transform->postTranslate(openvdb::Vec3d(first_centre[0], first_centre[1], first_centre[2]));
    auto made = std::make_unique<LinebakeVdbBuild>();
    for (uint32_t g = 0; g < grid_count; ++g) {
      const LinebakeVdbGrid& spec = specs[g];
      auto grid = openvdb::FloatGrid::create(0.0f);
      grid->setName(spec.name);
      grid->setGridClass(spec.fog_volume ? openvdb::GRID_FOG_VOLUME : openvdb::GRID_UNKNOWN);
      grid->insertMeta("description", openvdb::StringMetadata(spec.description));
      grid->setTransform(transform);
      made->grids.push_back(grid);
      made->accessors.push_back(grid->getAccessor());
    }
    *build = made.release();
  });
}

int add(LinebakeVdbBuild* build, uint64_t count, const int32_t* ijk, const float* const* values,
        char* error, size_t error_size) {
  return guarded(error, error_size, [&] {
    for (size_t g = 0; g < build->grids.size(); ++g) {
      auto& accessor = build->accessors[g];
      for (uint64_t i = 0; i < count; ++i)
        if (!std::isnan(values[g][i]))
          accessor.setValue(openvdb::Coord(ijk[3 * i], ijk[3 * i + 1], ijk[3 * i + 2]),
                            values[g][i]);
    }
  });
}

int rescale(LinebakeVdbBuild* build, uint32_t grid, float scale, char* error, size_t error_size) {
  return guarded(error, error_size, [&] {
    for (auto value = build->grids.at(grid)->beginValueOn(); value; ++value)
      value.setValue(std::min(1.0f, *value / scale));
  });
}

int write(LinebakeVdbBuild* build, const char* path, const LinebakeVdbMeta* entries,
          uint32_t meta_count, uint64_t* expected_bytes, char* error, size_t error_size) {
  return guarded(error, error_size, [&] {
    const openvdb::GridPtrVec grids(build->grids.begin(), build->grids.end());
    const openvdb::MetaMap meta = make_meta(entries, meta_count);
    openvdb::io::File out(path);
    out.setCompression(kCompression);
    out.write(grids, meta);
    out.close();
    *expected_bytes = serialised_bytes(grids, meta);
  });
}

void end(LinebakeVdbBuild* build) {
  delete build;
}

constexpr LinebakeVdbModule kModule{&initialize, &begin, &add, &rescale, &write, &end};

}  // namespace

extern "C" __attribute__((visibility("default"))) const LinebakeVdbModule*
linebake_vdb_module_v2() {
  return &kModule;
}
