// Fuzz target for the pipeline parser (LINEBAKE_FUZZ_EXTENSION json or yaml): load and check a
// pipeline file, as `linebake run --dry-run` does before any work.

#include "fuzz_input.hpp"
#include "pipeline/pipeline.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return linebake::fuzz::with_input_file(
      data, size, LINEBAKE_FUZZ_EXTENSION,
      [](const std::string& path) { (void)linebake::load_pipeline(path); });
}
