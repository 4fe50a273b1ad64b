// Fuzz target for the asset-cache loader: open a fuzzed cache and load every asset it lists,
// with the checksums on (a damaged cache must be refused, naming the dataset).

#include "cache/cache.hpp"
#include "cache/embree_store.hpp"
#include "cache/line_store.hpp"
#include "cache/rtx_store.hpp"
#include "cache/tube_store.hpp"
#include "cache/voxel_store.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return linebake::fuzz::with_input_file(data, size, "lbc.h5", [](const std::string& path) {
    const linebake::CacheReader cache(path);
    (void)linebake::load_lines(cache);
    for (const std::string& asset : cache.assets()) {
      (void)cache.provenance("/assets/" + asset);
      if (asset == "tubes") (void)linebake::load_tubes(cache);
      if (asset == "voxels") (void)linebake::load_voxels(cache);
      if (asset == "embree") (void)linebake::load_embree(cache);
      if (asset == "rtx") (void)linebake::load_rtx(cache);
    }
  });
}
