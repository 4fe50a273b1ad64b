// Fuzz target for the image readers (LINEBAKE_FUZZ_EXTENSION png or pfm), as `compare` reads.

#include "fuzz_input.hpp"
#include "render/image.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return linebake::fuzz::with_input_file(
      data, size, LINEBAKE_FUZZ_EXTENSION,
      [](const std::string& path) { (void)linebake::read_image(path); });
}
