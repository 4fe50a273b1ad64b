#pragma once
// The line set as bake read it, kept in a spill file beside the output so later passes (the
// cache's /lines, the tube plan, the builds) read it again in the same batches without the
// input: an input may not be seekable (synth), slow to parse (text) or not streamable at all.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/spill_file.hpp"
#include "lines/line_reader.hpp"

namespace linebake {

class LineSpool {
 public:
  // The spill file is `<output>.lines-spill.tmp-...`, removed with the spool.
  LineSpool(const std::string& output, const LineSet& header);
  void append(const LineSet& batch);
  // A reader over the batches appended so far, in order; several may be opened one after
  // another.
  std::unique_ptr<LineReader> replay() const;
  uint64_t bytes() const { return file_.size(); }
  size_t batches() const { return index_.size(); }

 private:
  friend class SpoolReader;
  struct Entry {
    uint64_t offset = 0, lines = 0, points = 0;
  };
  LineSet header_;
  SpillFile file_;
  std::vector<Entry> index_;
};

}  // namespace linebake
