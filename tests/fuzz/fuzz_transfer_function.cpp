// Fuzz target for transfer-function JSON files (--tf FILE.json).

#include "fuzz_input.hpp"
#include "render/transfer_function.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return linebake::fuzz::with_input_file(data, size, "json", [](const std::string& path) {
    const linebake::TransferFunction tf = linebake::load_transfer_function(path);
    (void)tf.at(0.5);
  });
}
