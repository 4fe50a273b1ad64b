#include "lines/line_reader.hpp"

#include <algorithm>

#include "core/error.hpp"
#include "core/interrupt.hpp"

namespace linebake {

LineSet header_of(const LineSet& lines) {
  LineSet header;
  header.metadata = lines.metadata;
  for (const Attribute& a : lines.attributes) header.attributes.push_back({a.name, {}});
  for (const Attribute& a : lines.line_attributes) header.line_attributes.push_back({a.name, {}});
  return header;
}

void copy_lines(const LineSet& lines, size_t first, size_t end, LineSet& batch) {
  const uint64_t p0 = lines.line_offsets[first], p1 = lines.line_offsets[end];
  batch.positions.assign(lines.positions.begin() + std::ptrdiff_t(3 * p0),
                         lines.positions.begin() + std::ptrdiff_t(3 * p1));
  batch.line_offsets.resize(end - first + 1);
  for (size_t l = first; l <= end; ++l) batch.line_offsets[l - first] = lines.line_offsets[l] - p0;
  batch.attributes.resize(lines.attributes.size());
  for (size_t a = 0; a < lines.attributes.size(); ++a) {
    batch.attributes[a].name = lines.attributes[a].name;
    const auto& v = lines.attributes[a].values;
    batch.attributes[a].values.assign(v.begin() + std::ptrdiff_t(p0),
                                      v.begin() + std::ptrdiff_t(p1));
  }
  batch.line_attributes.resize(lines.line_attributes.size());
  for (size_t a = 0; a < lines.line_attributes.size(); ++a) {
    batch.line_attributes[a].name = lines.line_attributes[a].name;
    const auto& v = lines.line_attributes[a].values;
    batch.line_attributes[a].values.assign(v.begin() + std::ptrdiff_t(first),
                                           v.begin() + std::ptrdiff_t(end));
  }
  batch.metadata.clear();
}

void append_lines(LineSet& lines, const LineSet& batch) {
  if (batch.attributes.size() != lines.attributes.size() ||
      batch.line_attributes.size() != lines.line_attributes.size())
    throw Error("append_lines: batches with different attributes");
  const uint64_t base = lines.point_count();
  lines.positions.insert(lines.positions.end(), batch.positions.begin(), batch.positions.end());
  for (size_t l = 1; l < batch.line_offsets.size(); ++l)
    lines.line_offsets.push_back(base + batch.line_offsets[l]);
  for (size_t a = 0; a < batch.attributes.size(); ++a)
    lines.attributes[a].values.insert(lines.attributes[a].values.end(),
                                      batch.attributes[a].values.begin(),
                                      batch.attributes[a].values.end());
  for (size_t a = 0; a < batch.line_attributes.size(); ++a)
    lines.line_attributes[a].values.insert(lines.line_attributes[a].values.end(),
                                           batch.line_attributes[a].values.begin(),
                                           batch.line_attributes[a].values.end());
}

LineSet read_all(LineReader& reader) {
  if (std::optional<LineSet> whole = reader.take_whole()) return std::move(*whole);
  LineSet lines = header_of(reader.header());
  LineSet batch;
  while (reader.next(batch, uint64_t{1} << 22)) {
    throw_if_interrupted();  // reading a large file whole stops between batches on Ctrl-C
    append_lines(lines, batch);
  }
  add_counts_read(lines.metadata, reader.counts_read());
  return lines;
}

void add_counts(std::map<std::string, uint64_t>& into,
                const std::map<std::string, uint64_t>& counts) {
  for (const auto& [key, n] : counts) into[key] += n;
}

void add_counts_read(std::map<std::string, std::string>& metadata,
                     const std::map<std::string, uint64_t>& counts) {
  for (const auto& [key, n] : counts) metadata[key] = std::to_string(n);
}

uint64_t batch_points_within(const LineSet& header, std::optional<uint64_t> limit, uint64_t most) {
  if (!limit) return most;
  const uint64_t point_bytes =
      12 + 4 * header.attributes.size() + 8 + 4 * header.line_attributes.size();
  return std::clamp<uint64_t>(*limit / 4 / point_bytes, 1024, std::max<uint64_t>(most, 1024));
}

MemoryLineReader::MemoryLineReader(LineSet lines, bool streams)
    : owned_(std::move(lines)), lines_(&owned_), streams_(streams) {
  header_ = header_of(owned_);
}

std::unique_ptr<MemoryLineReader> MemoryLineReader::view(const LineSet& lines) {
  std::unique_ptr<MemoryLineReader> reader(new MemoryLineReader());
  reader->lines_ = &lines;
  reader->streams_ = true;
  reader->header_ = header_of(lines);
  return reader;
}

bool MemoryLineReader::next(LineSet& batch, uint64_t max_points) {
  const size_t count = lines_->line_count();
  if (lines_read_ >= count) {
    copy_lines(*lines_, count, count, batch);
    return false;
  }
  const uint64_t first_point = lines_->line_offsets[lines_read_];
  // The last line whose end stays within max_points of the batch's first point (at least one).
  const auto begin = lines_->line_offsets.begin() + std::ptrdiff_t(lines_read_ + 1);
  const auto end = lines_->line_offsets.begin() + std::ptrdiff_t(count + 1);
  size_t last = size_t(std::upper_bound(begin, end, saturating_add(first_point, max_points)) -
                       lines_->line_offsets.begin()) -
                1;
  last = std::max<size_t>(last, lines_read_ + 1);
  copy_lines(*lines_, lines_read_, last, batch);
  lines_read_ = last;
  return true;
}

uint64_t MemoryLineReader::largest_line_hint() const {
  uint64_t largest = 0;
  for (size_t l = 0; l < lines_->line_count(); ++l)
    largest = std::max(largest, lines_->line_size(l));
  return largest;
}

std::optional<LineSet> MemoryLineReader::take_whole() {
  if (lines_ != &owned_ || lines_read_ > 0) return std::nullopt;
  lines_read_ = owned_.line_count();
  return std::move(owned_);
}

}  // namespace linebake
