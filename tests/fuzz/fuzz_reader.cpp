// Fuzz target for one line-file reader: the bytes as a file with the format's extension
// (LINEBAKE_FUZZ_EXTENSION), read whole, then streamed in small batches, as bake reads it.

#include "formats/registry.hpp"
#include "fuzz_input.hpp"
#include "lines/line_set.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return linebake::fuzz::with_input_file(
      data, size, LINEBAKE_FUZZ_EXTENSION, [](const std::string& path) {
        const linebake::LineSet whole = linebake::read_line_set(path);
        (void)whole;
        auto reader = linebake::open_line_reader(path);
        linebake::LineSet batch;
        while (reader->next(batch, 7)) {
        }
      });
}
