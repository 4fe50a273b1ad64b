#pragma once
// A line set read as a sequence of batches of whole lines, so that a stage holds one batch of
// the input at a time: how `bake` reads inputs larger than memory. Every batch is a LineSet of
// its own (offsets from 0) with the header's attribute names, in the header's order; the
// concatenation of the batches is the line set, whatever the batch sizes.

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "lines/line_set.hpp"

namespace linebake {

class LineReader {
 public:
  virtual ~LineReader() = default;

  // Attribute names (values empty) and metadata, known before the first batch.
  const LineSet& header() const { return header_; }
  // Fills `batch` with the next whole lines: together at most `max_points` points, unless the
  // next line alone has more (it then comes alone). False, with `batch` empty, at the end.
  // Throws InputError naming the file and the place on malformed input, and BudgetExceeded
  // where a batch would hold more than ReadOptions::memory_limit (a line alone larger than it).
  virtual bool next(LineSet& batch, uint64_t max_points) = 0;
  // True when lines come from the input piece by piece; false when the format had to be read
  // whole first (lines that jump around a shared point array: OBJ, VTK, VTP).
  virtual bool streams() const { return true; }
  // Points of the largest line this reader can know of before reading it (0: unknown); lets a
  // caller refuse an input whose single line does not fit its memory before doing any work.
  virtual uint64_t largest_line_hint() const { return 0; }
  // The input's line count when its header says it (binlines), before reading the lines.
  virtual std::optional<uint64_t> line_count_hint() const { return std::nullopt; }
  // The whole line set when it is already in memory (non-streaming readers), moved out; the
  // reader is exhausted afterwards.
  virtual std::optional<LineSet> take_whole() { return std::nullopt; }
  // Index of the first line of the next batch.
  uint64_t lines_read() const { return lines_read_; }
  // Where the last batch came from, for messages about its file: the file when the reader reads
  // several ("" otherwise: the reader's one source), and the number of the batch's first line in
  // that file.
  virtual std::string batch_file() const { return ""; }
  virtual uint64_t batch_file_line() const { return 0; }
  // What the reader can count only by reading every line (a NetCDF file's trajectories split at
  // missing positions), by metadata key, once next() has returned false; several files' counts
  // add up. Kept in the line set's metadata as decimal text (add_counts_read).
  virtual std::map<std::string, uint64_t> counts_read() const { return {}; }

 protected:
  LineSet header_;
  uint64_t lines_read_ = 0;
};

// Serves batches out of a line set held in memory: formats read whole, tests, and callers that
// hold a LineSet and want to drive a streamed stage with it.
class MemoryLineReader : public LineReader {
 public:
  explicit MemoryLineReader(LineSet lines, bool streams = false);
  // Reads a line set owned by the caller, which must outlive the reader.
  static std::unique_ptr<MemoryLineReader> view(const LineSet& lines);
  bool next(LineSet& batch, uint64_t max_points) override;
  bool streams() const override { return streams_; }
  uint64_t largest_line_hint() const override;
  std::optional<LineSet> take_whole() override;

 private:
  MemoryLineReader() = default;
  LineSet owned_;
  const LineSet* lines_ = nullptr;
  bool streams_ = false;
};

// a + b, or UINT64_MAX where that overflows (max_points may be "no limit").
inline uint64_t saturating_add(uint64_t a, uint64_t b) {
  return a > UINT64_MAX - b ? UINT64_MAX : a + b;
}

// A copy of the header of `lines`: attribute names and metadata, no values.
LineSet header_of(const LineSet& lines);
// Lines [first, end) of `lines` as a batch (cleared first; offsets from 0).
void copy_lines(const LineSet& lines, size_t first, size_t end, LineSet& batch);
// Appends the lines of `batch` to `lines` (same attribute names, in the same order).
void append_lines(LineSet& lines, const LineSet& batch);
// Reads every batch into one line set.
LineSet read_all(LineReader& reader);
// Adds `counts` to `into` (a reader's counts_read, or several readers', key by key).
void add_counts(std::map<std::string, uint64_t>& into,
                const std::map<std::string, uint64_t>& counts);
// Keeps `counts` in `metadata` as decimal text.
void add_counts_read(std::map<std::string, std::string>& metadata,
                     const std::map<std::string, uint64_t>& counts);
// The points a batch of `header`'s lines may hold when reading may take `limit` bytes (none: no
// limit): a quarter of the limit (the reader's buffers, the batch, the work on it) over a point's
// bytes at most (its position and attributes, and its line's offset and attributes: a line has a
// point at least), from 1,024 to `most`.
uint64_t batch_points_within(const LineSet& header, std::optional<uint64_t> limit, uint64_t most);

}  // namespace linebake
