#pragma once
// An asset cache opened from Python, shared by the asset and the rendering bindings.

#include <memory>
#include <mutex>
#include <string>

#include "cache/cache.hpp"
#include "tubes/tube_mesh.hpp"
#include "voxels/voxel_grid.hpp"

namespace linebake::python {

// The reader, and the assets loaded so far: a second call returns the same memory, so NumPy
// views of it stay what they were.
class PyCache {
 public:
  explicit PyCache(const std::string& path);
  const std::string& path() const { return path_; }
  const CacheReader& reader() const { return *reader_; }
  const TubeMesh& tubes();
  const VoxelGrid& voxels();

 private:
  std::string path_;
  std::shared_ptr<CacheReader> reader_;
  std::shared_ptr<TubeMesh> tubes_;
  std::shared_ptr<VoxelGrid> voxels_;
  // The first tubes() or voxels() loads (with the GIL released); threads that ask at once wait
  // for that load and get the same memory (a shared_ptr assigned from two threads crashed).
  std::shared_ptr<std::mutex> load_ = std::make_shared<std::mutex>();
};

}  // namespace linebake::python
