#include "lines/line_spool.hpp"

namespace linebake {

// Each batch: its line offsets (lines + 1 uint64), positions, then every vertex attribute and
// every line attribute, raw.
LineSpool::LineSpool(const std::string& output, const LineSet& header)
    : header_(header_of(header)), file_(output, "lines-spill") {}

void LineSpool::append(const LineSet& batch) {
  Entry e{file_.size(), batch.line_count(), batch.point_count()};
  file_.append(batch.line_offsets.data(), batch.line_offsets.size() * sizeof(uint64_t));
  file_.append(batch.positions.data(), batch.positions.size() * sizeof(float));
  for (const Attribute& a : batch.attributes) file_.append(a.values.data(), a.values.size() * 4);
  for (const Attribute& a : batch.line_attributes)
    file_.append(a.values.data(), a.values.size() * 4);
  index_.push_back(e);
}

class SpoolReader : public LineReader {
 public:
  explicit SpoolReader(const LineSpool& spool) : spool_(spool) { header_ = spool.header_; }
  // Serves the batches as they were appended, whatever max_points.
  bool next(LineSet& batch, uint64_t) override {
    copy_lines(header_, 0, 0, batch);
    if (next_ == spool_.index_.size()) return false;
    const LineSpool::Entry& e = spool_.index_[next_++];
    uint64_t at = e.offset;
    const auto read = [&](void* out, uint64_t bytes) {
      spool_.file_.read(at, out, bytes);
      at += bytes;
    };
    batch.line_offsets.resize(e.lines + 1);
    read(batch.line_offsets.data(), (e.lines + 1) * sizeof(uint64_t));
    batch.positions.resize(3 * e.points);
    read(batch.positions.data(), 12 * e.points);
    for (Attribute& a : batch.attributes) {
      a.values.resize(e.points);
      read(a.values.data(), 4 * e.points);
    }
    for (Attribute& a : batch.line_attributes) {
      a.values.resize(e.lines);
      read(a.values.data(), 4 * e.lines);
    }
    lines_read_ += e.lines;
    return true;
  }

 private:
  const LineSpool& spool_;
  size_t next_ = 0;
};

std::unique_ptr<LineReader> LineSpool::replay() const {
  return std::make_unique<SpoolReader>(*this);
}

}  // namespace linebake
