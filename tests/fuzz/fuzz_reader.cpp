// Fuzz target for one line-file reader: the bytes as a file with the format's extension
// (LINEBAKE_FUZZ_EXTENSION), read whole, then streamed in small batches, as bake reads it; then
// again at a far-off origin (`--origin`, lines/origin.hpp), whose readers take the file's numbers
// through double, and at the origin `--origin auto` finds, which reads the file up to its first
// valid point.

#include "formats/registry.hpp"
#include "fuzz_input.hpp"
#include "lines/line_set.hpp"

namespace {

void stream(const std::string& path, const linebake::ReadOptions& options) {
  auto reader = linebake::open_line_reader(path, options);
  linebake::LineSet batch;
  while (reader->next(batch, 7)) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return linebake::fuzz::with_input_file(
      data, size, LINEBAKE_FUZZ_EXTENSION, [](const std::string& path) {
        const linebake::LineSet whole = linebake::read_line_set(path);
        (void)whole;
        stream(path, {});
        // A UTM-like origin (float32 steps by 0.5 there), then the file's own first point.
        linebake::ReadOptions far;
        far.origin = linebake::Origin{500000.0, 5400000.0, -12.5};
        stream(path, far);
        linebake::ReadOptions found;
        found.origin = linebake::auto_origin({path});
        stream(path, found);
      });
}
