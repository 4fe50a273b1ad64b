#include "cache/line_store.hpp"

#include <algorithm>
#include <cstring>
#include <span>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/json_file.hpp"
#include "lines/line_reader.hpp"

namespace linebake {

namespace {
std::vector<std::string> array_names(const LineSet& header) {
  std::vector<std::string> names{"positions", "line_offsets"};
  for (const Attribute& a : header.attributes) names.push_back(a.name);
  for (const Attribute& a : header.line_attributes) names.push_back(a.name);
  return names;
}
}  // namespace

LineContentHash::LineContentHash(const LineSet& header, const LinePiece& piece) {
  names_ = array_names(header);
  vertex_attributes_ = header.attributes.size();
  for (size_t i = 0; i < names_.size(); ++i) {
    // Where this piece's bytes of the array start in the whole array.
    const uint64_t first = i == 0                       ? 12 * piece.first_point
                           : i == 1                     ? 8 * (piece.first_line + !piece.first)
                           : i < 2 + vertex_attributes_ ? 4 * piece.first_point
                                                        : 4 * piece.first_line;
    arrays_.push_back(piece.shared ? std::make_unique<BlockHasher>(BlockHasher::Piece{first})
                                   : std::make_unique<BlockHasher>());
  }
  counts_.assign(names_.size(), 0);
  points_ = piece.first_point;
  if (piece.first) {
    const uint64_t zero = 0;  // the offsets start at 0
    arrays_[1]->update(&zero, sizeof zero);
    counts_[1] = 1;
  }
}

LineContentHash::~LineContentHash() = default;

void LineContentHash::add(const LineSet& batch) {
  const auto put = [&](size_t i, const void* data, size_t count, size_t size) {
    arrays_[i]->update(data, count * size);
    counts_[i] += count;
  };
  put(0, batch.positions.data(), batch.positions.size(), sizeof(float));
  for (size_t l = 1; l < batch.line_offsets.size(); ++l) {
    const uint64_t offset = points_ + batch.line_offsets[l];
    put(1, &offset, 1, sizeof offset);
  }
  points_ += batch.point_count();
  for (size_t a = 0; a < batch.attributes.size(); ++a)
    put(2 + a, batch.attributes[a].values.data(), batch.attributes[a].values.size(), sizeof(float));
  for (size_t a = 0; a < batch.line_attributes.size(); ++a)
    put(2 + vertex_attributes_ + a, batch.line_attributes[a].values.data(),
        batch.line_attributes[a].values.size(), sizeof(float));
}

std::string LineContentHash::hex_of(const std::vector<std::string>& names, size_t vertex_attributes,
                                    const std::vector<uint64_t>& counts,
                                    const std::vector<std::string>& array_hashes) {
  Hasher h;
  h.update(std::string_view("linebake line set 3"));
  h.update(uint64_t{vertex_attributes}).update(uint64_t{names.size() - 2 - vertex_attributes});
  for (size_t i = 0; i < names.size(); ++i)
    h.update(names[i]).update(counts[i]).update(array_hashes[i]);
  return h.hex();
}

std::string LineContentHash::hex() const {
  std::vector<std::string> hashes;
  for (const auto& a : arrays_) hashes.push_back(a->hex());
  return hex_of(names_, vertex_attributes_, counts_, hashes);
}

namespace {

// A piece's arrays: value counts and block hash pieces.
struct ArrayPieces {
  std::vector<uint64_t> counts;
  std::vector<std::string> pieces;
};

ArrayPieces parse_pieces(const std::string& text) {
  ArrayPieces out;
  size_t at = 0;
  const auto get = [&] {
    uint64_t v = 0;
    if (at + sizeof v > text.size()) throw Error("line content hash piece is truncated");
    std::memcpy(&v, text.data() + at, sizeof v);
    at += sizeof v;
    return v;
  };
  const uint64_t arrays = get();
  for (uint64_t i = 0; i < arrays; ++i) {
    out.counts.push_back(get());
    const uint64_t n = get();
    if (n > text.size() - at) throw Error("line content hash piece is truncated");
    out.pieces.push_back(text.substr(at, n));
    at += n;
  }
  return out;
}

std::string serialise_pieces(const ArrayPieces& a) {
  std::string out;
  const auto put = [&](uint64_t v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); };
  put(a.pieces.size());
  for (size_t i = 0; i < a.pieces.size(); ++i) {
    put(a.counts[i]);
    put(a.pieces[i].size());
    out += a.pieces[i];
  }
  return out;
}

}  // namespace

// A piece: per array, its value count and its BlockHasher piece, each length-prefixed.
std::string LineContentHash::piece() const {
  ArrayPieces a;
  a.counts = counts_;
  for (const auto& array : arrays_) a.pieces.push_back(array->piece());
  return serialise_pieces(a);
}

std::string LineContentHash::join(const std::string& first, const std::string& second) {
  ArrayPieces a = parse_pieces(first);
  const ArrayPieces b = parse_pieces(second);
  if (a.pieces.size() != b.pieces.size())
    throw Error("line content hash pieces of different line sets");
  for (size_t i = 0; i < a.pieces.size(); ++i) {
    a.counts[i] += b.counts[i];
    a.pieces[i] = join_block_hash_pieces({a.pieces[i], b.pieces[i]});
  }
  return serialise_pieces(a);
}

std::string LineContentHash::finish(const LineSet& header, const std::string& whole) {
  const std::vector<std::string> names = array_names(header);
  const ArrayPieces a = parse_pieces(whole);
  if (a.pieces.size() != names.size())
    throw Error("line content hash pieces of different line sets");
  std::vector<std::string> hashes;
  for (const std::string& p : a.pieces) hashes.push_back(finish_block_hash(p));
  return hex_of(names, header.attributes.size(), a.counts, hashes);
}

std::string content_hash(const LineSet& lines) {
  LineContentHash h(lines);
  h.add(lines);
  return h.hex();
}

uint64_t line_set_bytes(const LineSet& lines) {
  return compute_stats(lines).total_bytes();
}

nlohmann::json to_json(const LineSetStats& s) {
  const auto ranges = [](const std::vector<std::pair<std::string, ValueRange>>& list) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& [name, r] : list)
      j.push_back({{"name", name},
                   {"min", r.min},
                   {"max", r.max},
                   {"finite", r.finite},
                   {"nonfinite", r.nonfinite}});
    return j;
  };
  nlohmann::json j = {{"lines", s.lines},
                      {"points", s.points},
                      {"segments", s.segments},
                      {"largest_line", s.largest_line},
                      {"attribute_ranges", ranges(s.attribute_ranges)},
                      {"line_attribute_ranges", ranges(s.line_attribute_ranges)}};
  j["bounds"] = s.bounds.empty ? nlohmann::json(nullptr)
                               : nlohmann::json{{"min", s.bounds.min}, {"max", s.bounds.max}};
  return j;
}

LineSetStats line_stats_from_json(const nlohmann::json& j, const std::string& cache) {
  LineSetStats s;
  try {
    s.lines = j.at("lines");
    s.points = j.at("points");
    s.segments = j.at("segments");
    s.largest_line = j.at("largest_line");
    if (!j.at("bounds").is_null()) {
      s.bounds.min = j.at("bounds").at("min");
      s.bounds.max = j.at("bounds").at("max");
      s.bounds.empty = false;
    }
    const auto ranges = [](const nlohmann::json& list) {
      std::vector<std::pair<std::string, ValueRange>> out;
      for (const auto& r : list)
        out.emplace_back(r.at("name"),
                         ValueRange{r.at("min"), r.at("max"), r.at("nonfinite"), r.at("finite")});
      return out;
    };
    s.attribute_ranges = ranges(j.at("attribute_ranges"));
    s.line_attribute_ranges = ranges(j.at("line_attribute_ranges"));
  } catch (const std::exception& e) {
    throw InputError(cache, "group /lines",
                     std::string("provenance lacks line statistics: ") + e.what());
  }
  s.position_bytes = 12 * s.points;
  s.offset_bytes = 8 * (s.lines + 1);
  s.attribute_bytes =
      4 * (s.points * s.attribute_ranges.size() + s.lines * s.line_attribute_ranges.size());
  return s;
}

LineStoreWriter::LineStoreWriter(CacheWriter& cache, const LineSet& header,
                                 const LineSetStats& stats, const LinePiece& piece)
    : cache_(cache),
      stats_(stats),
      points_(cache.stream<float>("/lines/points", stats.points, 3)),
      offsets_(cache.stream<uint64_t>("/lines/line_offsets", stats.lines + 1)) {
  cache.create_group("/lines");
  for (const Attribute& a : header.attributes)
    attributes_.push_back(
        cache.stream<float>("/lines/attributes/" + encode_link_name(a.name), stats.points));
  for (const Attribute& a : header.line_attributes)
    line_attributes_.push_back(
        cache.stream<float>("/lines/line_attributes/" + encode_link_name(a.name), stats.lines));
  if (cache.parallel()) {
    points_.start_at(piece.first_point);
    offsets_.start_at(piece.first ? 0 : piece.first_line + 1);
    for (DatasetStream& a : attributes_) a.start_at(piece.first_point);
    for (DatasetStream& a : line_attributes_) a.start_at(piece.first_line);
    points_written_ = piece.first_point;
  }
  if (piece.first) {
    const uint64_t zero = 0;
    offsets_.append(&zero, 1);
  }
}

void LineStoreWriter::append(const LineSet& batch) {
  offsets_buffer_.resize(batch.line_count());
  for (size_t l = 0; l < offsets_buffer_.size(); ++l)
    offsets_buffer_[l] = points_written_ + batch.line_offsets[l + 1];
  points_written_ += batch.point_count();
  std::vector<StreamAppend> appends{rows_of(points_, batch.positions.data(), batch.point_count()),
                                    rows_of(offsets_, offsets_buffer_.data(), batch.line_count())};
  for (size_t a = 0; a < attributes_.size(); ++a)
    appends.push_back(rows_of(attributes_[a], batch.attributes[a].values.data(),
                              batch.attributes[a].values.size()));
  for (size_t a = 0; a < line_attributes_.size(); ++a)
    appends.push_back(rows_of(line_attributes_[a], batch.line_attributes[a].values.data(),
                              batch.line_attributes[a].values.size()));
  append_together(appends);
}

void LineStoreWriter::close(const std::map<std::string, std::string>& metadata,
                            Provenance provenance) {
  uint64_t disk = points_.close() + offsets_.close();
  for (DatasetStream& s : attributes_) disk += s.close();
  for (DatasetStream& s : line_attributes_) disk += s.close();
  cache_.write_attribute("/lines", "metadata", json_text(nlohmann::json(metadata)));
  provenance.disk_bytes = disk;
  provenance.memory_bytes = stats_.total_bytes();
  cache_.write_provenance("/lines", provenance);
}

void store_lines(CacheWriter& cache, const LineSet& lines, Provenance provenance) {
  LineStoreWriter writer(cache, header_of(lines), compute_stats(lines));
  writer.append(lines);
  writer.close(lines.metadata, std::move(provenance));
}

template <class T>
static std::vector<T> to_vector(const Array<T>& a) {
  return std::vector<T>(a.begin(), a.end());
}

LineSet load_lines(const CacheReader& cache) {
  if (!cache.exists("/lines")) throw InputError(cache.path(), "group /lines", "missing");
  LineSet lines;
  lines.line_offsets = to_vector(cache.read<uint64_t>("/lines/line_offsets"));
  if (lines.line_offsets.empty() || lines.line_offsets.front() != 0)
    throw InputError(cache.path(), "dataset /lines/line_offsets", "must start with 0");
  for (size_t i = 1; i < lines.line_offsets.size(); ++i)
    if (lines.line_offsets[i] < lines.line_offsets[i - 1])
      throw InputError(cache.path(), "dataset /lines/line_offsets",
                       "decreasing at index " + std::to_string(i));
  const uint64_t points = lines.line_offsets.back();
  lines.positions = to_vector(cache.read<float>("/lines/points", 3 * points));
  for (const std::string& name : cache.members("/lines/attributes"))
    lines.attributes.push_back({decode_link_name(name),
                                to_vector(cache.read<float>("/lines/attributes/" + name, points))});
  for (const std::string& name : cache.members("/lines/line_attributes"))
    lines.line_attributes.push_back(
        {decode_link_name(name),
         to_vector(cache.read<float>("/lines/line_attributes/" + name, lines.line_count()))});
  lines.metadata = load_line_metadata(cache);
  return lines;
}

std::map<std::string, std::string> load_line_metadata(const CacheReader& cache) {
  const auto text = cache.attribute("/lines", "metadata");
  if (!text) return {};
  try {
    return nlohmann::json::parse(*text).get<std::map<std::string, std::string>>();
  } catch (const std::exception& e) {
    throw InputError(cache.path(), "group /lines", std::string("bad metadata: ") + e.what());
  }
}

void include_dataset_points(Bounds& bounds, const CacheReader& cache, const std::string& dataset,
                            uint64_t rows_per_read) {
  const std::vector<uint64_t> shape = cache.shape(dataset);
  if (shape.size() != 2 || shape[1] != 3)
    throw InputError(cache.path(), "dataset " + dataset, "not 3 floats per point");
  const uint64_t step = std::max<uint64_t>(rows_per_read, 1);
  std::vector<float> piece;
  for (uint64_t first = 0; first < shape[0]; first += step) {
    const uint64_t rows = std::min(step, shape[0] - first);
    piece.resize(3 * rows);
    cache.read_rows(dataset, first, rows, piece.data());
    include_points(bounds, std::span<const float>(piece.data(), piece.size()));
  }
}

}  // namespace linebake
