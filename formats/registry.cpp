#include "formats/registry.hpp"

#include <glob.h>
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <new>
#include <set>

#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/interrupt.hpp"
#include "core/memory_budget.hpp"
#include "core/nearest.hpp"
#include "formats/formats.hpp"
#include "synth/synth.hpp"

namespace linebake {

const std::vector<FormatInfo>& format_table() {
  static const std::vector<FormatInfo> list{
      // format, name, extensions, readable, writable, line attributes, metadata (held by what
      // it reads, and by what it writes where it writes)
      {Format::obj, "obj", {".obj"}, true, true, false, false},
      {Format::binlines, "binlines", {".binlines"}, true, true, false, false},
      {Format::vtk, "vtk", {".vtk"}, true, true, true, true},
      {Format::vtp, "vtp", {".vtp"}, true, true, true, true},
      {Format::netcdf, "netcdf", {".nc", ".ncf", ".nc4", ".cdf"}, true, false, false, true},
      {Format::hdf5, "hdf5", {".h5", ".hdf5", ".hdf"}, true, true, true, true},
      {Format::trk, "trk", {".trk"}, true, false, true, true},
      {Format::tck, "tck", {".tck"}, true, false, false, true},
      {Format::csv, "csv", {".csv"}, true, true, false, false},
  };
  return list;
}

const FormatInfo& format_info(Format format) {
  for (const FormatInfo& f : format_table())
    if (f.format == format) return f;
  throw Error("unknown format");
}

Format parse_format(const std::string& name) {
  for (const FormatInfo& f : format_table())
    if (name == f.name) return f.format;
  std::vector<std::string> names;
  for (const FormatInfo& f : format_table()) names.push_back(f.name);
  throw UsageError("unknown format '" + name + "' (known: " + name_list(names) + ")" +
                   did_you_mean(name, names));
}

std::optional<Format> format_from_extension(const std::string& path) {
  std::string lower = path;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const FormatInfo& f : format_table())
    for (const char* ext : f.extensions) {
      const std::string e(ext);
      if (lower.size() > e.size() && lower.compare(lower.size() - e.size(), e.size(), e) == 0)
        return f.format;
    }
  return std::nullopt;
}

Format resolve_format(const std::string& path, const std::optional<Format>& forced) {
  if (forced) return *forced;
  if (auto f = format_from_extension(path)) return *f;
  std::string known;
  for (const FormatInfo& f : format_table())
    if (f.writable)
      for (const char* ext : f.extensions) known += (known.empty() ? "" : " ") + std::string(ext);
  throw OutputError(path,
                    "cannot tell the format from the extension (" + known + "); name it with --to");
}

Format resolve_input_format(const std::string& path, const std::optional<Format>& forced) {
  if (forced) return *forced;
  if (auto f = format_from_extension(path)) return *f;
  if (h5::is_hdf5_file(path)) return Format::hdf5;
  std::string known;
  for (const FormatInfo& f : format_table())
    for (const char* ext : f.extensions) known += (known.empty() ? "" : " ") + std::string(ext);
  throw InputError(path, "",
                   "not a line file linebake knows by its extension (" + known +
                       ") nor an HDF5 file; name the format with --from");
}

bool keeps_empty_lines(Format format) {
  return format != Format::csv && format != Format::obj;
}

std::string empty_lines_phrase(uint64_t count) {
  return std::to_string(count) + (count == 1 ? " empty line" : " empty lines") +
         " (without points)";
}

std::vector<std::string> lost_in_format(const LineSet& lines, Format format,
                                        const WriteOptions& options) {
  const FormatInfo& info = format_info(format);
  std::vector<std::string> lost;
  if (!info.line_attributes)
    for (const Attribute& a : lines.line_attributes) lost.push_back("line attribute " + a.name);
  if (format == Format::binlines && options.binlines_version == 1 && !lines.attributes.empty())
    lost.push_back("attribute names (binlines version 1)");
  // A float32-only format holds the world coordinates of lines with an origin (lines/origin.hpp)
  // rounded to float32 again.
  if (has_origin(lines) && format == Format::binlines)
    lost.push_back("positions' digits past float32 at world coordinates (origin " +
                   lines.metadata.at(kOriginKey) +
                   "; vtk, vtp, csv and obj keep them as float64, hdf5 keeps the origin)");
  if (!info.metadata) {
    std::string keys;
    for (const auto& [key, value] : lines.metadata)
      // The renames note is the read file's (with_unique_names): not the data's to keep.
      if (key != "source" && key != "linebake.renamed_attributes" && key != kOriginKey)
        keys += (keys.empty() ? "" : ", ") + key;
    if (!keys.empty()) lost.push_back("metadata (" + keys + ")");
  }
  if (!keeps_empty_lines(format)) {
    uint64_t empty = 0;
    for (size_t l = 0; l < lines.line_count(); ++l) empty += lines.line_size(l) == 0;
    if (empty > 0) lost.push_back(empty_lines_phrase(empty));
  }
  return lost;
}

Format resolve_output_format(const std::string& path, const std::optional<Format>& forced) {
  const Format format = resolve_format(path, forced);
  if (!format_info(format).writable) {
    std::string writable;
    for (const FormatInfo& f : format_table())
      if (f.writable) writable += (writable.empty() ? "" : ", ") + std::string(f.name);
    throw OutputError(path, std::string("writing ") + format_info(format).name +
                                " is not supported (writable: " + writable + ")");
  }
  return format;
}

std::string source_format_name(const std::string& source, const ReadOptions& options) {
  if (synth::is_synth_source(source)) return "synth";
  return format_info(resolve_input_format(source, options.format)).name;
}

namespace {

// A reader that passes another's lines on with a header of its own, each batch (and the set taken
// whole, which gets the header's metadata) changed by adjust(); the rest is the inner reader's.
class AdjustingReader : public LineReader {
 public:
  AdjustingReader(std::unique_ptr<LineReader> inner, LineSet header) : inner_(std::move(inner)) {
    header_ = std::move(header);
  }
  bool next(LineSet& batch, uint64_t max_points) override {
    const bool more = inner_->next(batch, max_points);
    adjust(batch);
    lines_read_ = inner_->lines_read();
    return more;
  }
  bool streams() const override { return inner_->streams(); }
  uint64_t largest_line_hint() const override { return inner_->largest_line_hint(); }
  std::optional<uint64_t> line_count_hint() const override { return inner_->line_count_hint(); }
  std::optional<LineSet> take_whole() override {
    std::optional<LineSet> whole = inner_->take_whole();
    if (whole) {
      adjust(*whole);
      whole->metadata = header_.metadata;
    }
    return whole;
  }
  std::string batch_file() const override { return inner_->batch_file(); }
  uint64_t batch_file_line() const override { return inner_->batch_file_line(); }
  std::map<std::string, uint64_t> counts_read() const override { return inner_->counts_read(); }

 private:
  virtual void adjust(LineSet& lines) const = 0;
  std::unique_ptr<LineReader> inner_;
};

// Attributes are found by name (--attribute, HDF5 datasets, JSON), so each list's names must be
// one each and not empty. Files do repeat them (VTK's writer names every unnamed FIELD array
// "unknown"; a reader's own "unnamed" or "scalar_k" can meet a name in the file): the later ones
// are renamed name_2, name_3, ... (an empty name "unnamed"), and the renames are kept in the
// metadata as linebake.renamed_attributes, which `info --json` shows. A reader of the same file in
// the same order gives the same names.
class UniqueNames : public AdjustingReader {
 public:
  using AdjustingReader::AdjustingReader;

 private:
  void adjust(LineSet& lines) const override {
    for (size_t a = 0; a < lines.attributes.size() && a < header_.attributes.size(); ++a)
      lines.attributes[a].name = header_.attributes[a].name;
    for (size_t a = 0; a < lines.line_attributes.size() && a < header_.line_attributes.size(); ++a)
      lines.line_attributes[a].name = header_.line_attributes[a].name;
  }
};

// Renames within one list; what was renamed, for the note.
void make_unique(std::vector<Attribute>& list, const std::string& kind,
                 std::vector<std::string>& renamed) {
  std::set<std::string> taken;
  for (const Attribute& a : list) taken.insert(a.name);
  std::set<std::string> seen;
  // Per name, the suffix its next search starts at: a name given n times costs n searches, not
  // n^2 (the fuzzer's OBJ of 20,000 names "x" took 16 s).
  std::map<std::string, uint64_t> next_suffix;
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string base = list[i].name.empty() ? "unnamed" : list[i].name;
    if (!list[i].name.empty() && seen.insert(base).second) continue;
    std::string name = base;
    uint64_t& k = next_suffix.try_emplace(base, 2).first->second;
    while (taken.count(name) || seen.count(name)) name = base + "_" + std::to_string(k++);
    renamed.push_back(kind + " attribute " + std::to_string(i + 1) + " '" + list[i].name +
                      "' as '" + name + "'");
    list[i].name = name;
    taken.insert(name);
    seen.insert(name);
  }
}

std::unique_ptr<LineReader> with_unique_names(std::unique_ptr<LineReader> reader) {
  LineSet header = reader->header();
  std::vector<std::string> renamed;
  make_unique(header.attributes, "vertex", renamed);
  make_unique(header.line_attributes, "line", renamed);
  // A note the file carries (converted from a file whose names were renamed) is that file's,
  // not this one's: dropped, and this file's own written where it has renames.
  const bool carried = header.metadata.erase("linebake.renamed_attributes") > 0;
  if (renamed.empty() && !carried) return reader;
  if (renamed.empty()) return std::make_unique<UniqueNames>(std::move(reader), std::move(header));
  std::string note;
  for (size_t r = 0; r < std::min<size_t>(renamed.size(), 16); ++r)
    note += (note.empty() ? "" : "; ") + renamed[r];
  if (renamed.size() > 16) note += "; and " + std::to_string(renamed.size() - 16) + " more";
  header.metadata["linebake.renamed_attributes"] = note;
  return std::make_unique<UniqueNames>(std::move(reader), std::move(header));
}

// The lines in the frame ReadOptions::origin asks for (lines/origin.hpp). The readers of text and
// float64 numbers subtract it themselves, before rounding; a float32 source's points (`shift`:
// binlines, TrackVis, synth) are moved here, which is as exact. The header says the frame: the
// origin asked for; else a linebake HDF5 file's own; else none (an "origin" that another format's
// metadata carries is not its points' frame: it is kept as "source_origin").
class InFrame : public AdjustingReader {
 public:
  InFrame(std::unique_ptr<LineReader> inner, LineSet header, std::optional<Origin> shift)
      : AdjustingReader(std::move(inner), std::move(header)), shift_(shift) {}

 private:
  void adjust(LineSet& lines) const override {
    if (shift_) shift_positions(lines.positions, *shift_);
  }
  std::optional<Origin> shift_;
};

std::unique_ptr<LineReader> in_frame(std::unique_ptr<LineReader> reader, bool float32_source,
                                     bool own_frame, const ReadOptions& options) {
  LineSet header = reader->header();
  const bool carried = has_origin(header) && !own_frame;
  if (!options.origin && !carried) return reader;
  if (carried) keep_as_source_origin(header.metadata);
  if (options.origin) set_origin(header, *options.origin);
  std::optional<Origin> shift;
  if (float32_source && options.origin) shift = options.origin;
  return std::make_unique<InFrame>(std::move(reader), std::move(header), shift);
}

}  // namespace

std::unique_ptr<LineReader> open_line_reader(const std::string& source,
                                             const ReadOptions& options) {
  if (synth::is_synth_source(source))
    return in_frame(synth::open_generator(synth::parse_synth_source(source), options.progress),
                    true, false, options);
  const Format format = resolve_input_format(source, options.format);
  std::unique_ptr<LineReader> reader;
  const auto whole = [](LineSet lines) {
    return std::make_unique<MemoryLineReader>(std::move(lines));
  };
  // Sizes read from a file are checked before they size anything; what is left (a header whose
  // sizes are plausible but more than this machine has) is an error naming the file, not a bare
  // std::bad_alloc.
  try {
    switch (format) {
      case Format::obj:
        reader = whole(formats::read_obj(source, options));
        break;
      case Format::binlines:
        reader = formats::open_binlines(source, options);
        break;
      case Format::vtk:
        reader = whole(formats::read_vtk_legacy(source, options));
        break;
      case Format::vtp:
        reader = whole(formats::read_vtp(source, options));
        break;
      case Format::netcdf:
        reader = formats::open_netcdf(source, options);
        break;
      case Format::hdf5:
        reader = formats::open_hdf5(source, options);
        break;
      case Format::trk:
        reader = formats::open_trk(source, options);
        break;
      case Format::tck:
        reader = formats::open_tck(source, options);
        break;
      case Format::csv:
        reader = formats::open_csv(source, options);
        break;
    }
  } catch (const std::bad_alloc&) {
    throw InputError(source, "",
                     "opening it needs more memory than this machine can give (is a size in its "
                     "header damaged?)");
  }
  // Attribute names are looked up by name (options, caches' statistics and keys, which are
  // JSON): a name that is not UTF-8 could not be stored as itself.
  const LineSet& header = reader->header();
  for (const auto* list : {&header.attributes, &header.line_attributes})
    for (const Attribute& a : *list)
      if (!valid_utf8(a.name))
        throw InputError(source, "attribute " + a.name,
                         "its name is not UTF-8 text; rename it (linebake keeps names in JSON, "
                         "which holds UTF-8 only)");
  // MRtrix's reader subtracts the origin itself (its points may be Float64).
  const bool float32_source = format == Format::binlines || format == Format::trk;
  return in_frame(with_unique_names(std::move(reader)), float32_source, format == Format::hdf5,
                  options);
}

bool valid_utf8(std::string_view text) {
  size_t i = 0;
  while (i < text.size()) {
    const auto byte = static_cast<unsigned char>(text[i]);
    // The length a lead byte announces, and the least code point of that length (no overlong
    // forms), per RFC 3629; surrogates and past U+10FFFF are not UTF-8 either.
    size_t length = 0;
    uint32_t code = 0, least = 0;
    if (byte < 0x80) {
      ++i;
      continue;
    } else if ((byte & 0xE0) == 0xC0) {
      length = 2, code = byte & 0x1F, least = 0x80;
    } else if ((byte & 0xF0) == 0xE0) {
      length = 3, code = byte & 0x0F, least = 0x800;
    } else if ((byte & 0xF8) == 0xF0) {
      length = 4, code = byte & 0x07, least = 0x10000;
    } else {
      return false;
    }
    if (i + length > text.size()) return false;
    for (size_t k = 1; k < length; ++k) {
      const auto next = static_cast<unsigned char>(text[i + k]);
      if ((next & 0xC0) != 0x80) return false;
      code = (code << 6) | (next & 0x3F);
    }
    if (code < least || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return false;
    i += length;
  }
  return true;
}

std::vector<std::string> expand_inputs(const std::vector<std::string>& patterns) {
  std::vector<std::string> paths;
  for (const std::string& pattern : patterns) {
    if (synth::is_synth_source(pattern) ||
        pattern.find_first_of("*?[") == std::string::npos) {  // a plain path, checked on open
      paths.push_back(pattern);
      continue;
    }
    glob_t g{};
    const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
    if (rc == 0)
      for (size_t i = 0; i < g.gl_pathc; ++i) paths.emplace_back(g.gl_pathv[i]);
    globfree(&g);
    if (rc == GLOB_NOMATCH) throw InputError(pattern, "", "no file matches this pattern");
    if (rc != 0) throw InputError(pattern, "", "cannot expand this pattern (out of memory)");
  }
  std::sort(paths.begin(), paths.end());
  for (size_t i = 1; i < paths.size(); ++i)
    if (paths[i] == paths[i - 1]) throw InputError(paths[i], "", "named twice among the inputs");
  // The same file under two spellings (a/b and ./a/b, a link): by its device and inode.
  std::map<std::pair<dev_t, ino_t>, const std::string*> files;
  for (const std::string& p : paths) {
    struct stat st {};
    if (synth::is_synth_source(p) || ::stat(p.c_str(), &st) != 0) continue;  // checked on open
    const auto [first, fresh] = files.emplace(std::pair(st.st_dev, st.st_ino), &p);
    if (!fresh)
      throw InputError(p, "", "named twice among the inputs (also as " + *first->second + ")");
  }
  if (paths.size() > 1)
    for (const std::string& p : paths)
      if (synth::is_synth_source(p))
        throw Error("a synth: source cannot be combined with other inputs");
  return paths;
}

namespace {

std::string attribute_list(const std::vector<Attribute>& attributes) {
  std::string s = "[";
  for (const Attribute& a : attributes) s += (s.size() > 1 ? ", " : "") + a.name;
  return s + "]";
}

}  // namespace

void check_same_attributes(const LineSet& first, const std::string& first_path,
                           const LineSet& header, const std::string& path) {
  const auto names = [](const std::vector<Attribute>& list) {
    std::vector<std::string> n;
    for (const Attribute& a : list) n.push_back(a.name);
    return n;
  };
  if (names(header.attributes) != names(first.attributes) ||
      names(header.line_attributes) != names(first.line_attributes))
    throw InputError(path, "",
                     "its attributes " + attribute_list(header.attributes) + ", line attributes " +
                         attribute_list(header.line_attributes) +
                         " differ from the first input's (" + first_path + ": " +
                         attribute_list(first.attributes) + ", " +
                         attribute_list(first.line_attributes) +
                         "); every file of one line set needs the same attributes");
}

namespace {

// Files one after the other; each opened when the one before it is done.
class MultiFileReader final : public LineReader {
 public:
  MultiFileReader(std::vector<std::string> sources, ReadOptions options)
      : sources_(std::move(sources)), options_(std::move(options)) {
    open(0);
    header_ = header_of(current_->header());
  }
  bool next(LineSet& batch, uint64_t max_points) override {
    while (true) {
      const uint64_t in_file = current_->lines_read();
      if (current_->next(batch, max_points)) {
        lines_read_ += batch.line_count();
        batch_file_line_ = in_file;
        return true;
      }
      if (!counted_) add_counts(counts_read_, current_->counts_read());
      counted_ = true;  // once a file: next() may be called again at the end
      if (file_ + 1 == sources_.size()) return false;
      counted_ = false;
      open(file_ + 1);
    }
  }
  std::string batch_file() const override { return sources_[file_]; }
  uint64_t batch_file_line() const override { return batch_file_line_; }
  uint64_t largest_line_hint() const override { return current_->largest_line_hint(); }
  std::map<std::string, uint64_t> counts_read() const override { return counts_read_; }

 private:
  void open(size_t file) {
    file_ = file;
    current_ = file == 0 ? open_line_reader(sources_[file], options_)
                         : open_in_frame(sources_[file], options_, origin_of(header_, sources_[0]));
    if (!current_->streams()) {
      // Read whole (OBJ, VTK, VTP): batches are cut from it, so its arrays must agree.
      LineSet whole = *current_->take_whole();
      for (const auto* list : {&whole.attributes, &whole.line_attributes})
        for (const Attribute& a : *list) {
          const size_t want = list == &whole.attributes ? whole.point_count() : whole.line_count();
          if (a.values.size() != want)
            throw InputError(sources_[file], "attribute " + a.name,
                             std::to_string(a.values.size()) + " values for " +
                                 std::to_string(want) +
                                 (list == &whole.attributes ? " points" : " lines"));
        }
      current_ = std::make_unique<MemoryLineReader>(std::move(whole), true);
    }
    if (file > 0) check_same_attributes(header_, sources_[0], current_->header(), sources_[file]);
  }
  std::vector<std::string> sources_;
  ReadOptions options_;
  size_t file_ = 0;
  uint64_t batch_file_line_ = 0;
  std::unique_ptr<LineReader> current_;
  std::map<std::string, uint64_t> counts_read_;  // of the files read to their end
  bool counted_ = false;                         // the current file's counts are in counts_read_
};

}  // namespace

std::string counts_read_note(const std::map<std::string, uint64_t>& counts) {
  static const std::pair<const char*, const char*> kSaid[] = {
      {"netcdf.split_trajectories", "trajectories split at missing positions"},
      {"netcdf.lines_from_splits", "lines more from those splits"},
      {"netcdf.trajectories_without_position", "trajectories without a position (no line)"},
  };
  std::string note;
  for (const auto& [key, said] : kSaid)
    if (const auto it = counts.find(key); it != counts.end() && it->second > 0)
      note +=
          (note.empty() ? "" : ", ") + std::to_string(it->second) + " " + said + " (" + key + ")";
  return note;
}

std::unique_ptr<LineReader> open_in_frame(const std::string& source, const ReadOptions& options,
                                          const Origin& frame) {
  std::unique_ptr<LineReader> reader = open_line_reader(source, options);
  if (options.origin || origin_of(reader->header(), source) == frame) return reader;
  ReadOptions in_frame = options;
  in_frame.origin = frame;
  return open_line_reader(source, in_frame);
}

std::unique_ptr<LineReader> open_line_reader(const std::vector<std::string>& sources,
                                             const ReadOptions& options) {
  if (sources.empty()) throw Error("no input");
  if (sources.size() == 1) return open_line_reader(sources[0], options);
  return std::make_unique<MultiFileReader>(sources, options);
}

Origin auto_origin(const std::vector<std::string>& sources, const ReadOptions& options) {
  ReadOptions plain = options;
  plain.origin.reset();
  plain.progress = nullptr;
  const std::unique_ptr<LineReader> reader = open_line_reader(sources, plain);
  const Origin frame = origin_of(reader->header(), sources.front());
  LineSet batch;
  while (reader->next(batch, 4096))
    for (size_t i = 0; i < batch.point_count(); ++i) {
      const float* p = &batch.positions[3 * i];
      if (valid_point(p))
        return rounded_origin(
            {to_world(p[0], frame[0]), to_world(p[1], frame[1]), to_world(p[2], frame[2])});
    }
  return frame;
}

std::optional<Origin> origin_option_numbers(const std::string& text) {
  if (text.empty() || text == "auto") return std::nullopt;
  const std::optional<Origin> origin = parse_origin(text);
  if (!origin) throw UsageError("--origin: '" + text + "' is not auto nor X,Y,Z (three numbers)");
  return origin;
}

std::optional<Origin> resolve_origin(const std::string& text,
                                     const std::vector<std::string>& sources,
                                     const ReadOptions& options) {
  if (text == "auto") return auto_origin(sources, options);
  return origin_option_numbers(text);
}

namespace {

// The bytes of a batch's arrays.
uint64_t held_bytes(const LineSet& batch) {
  uint64_t values = batch.positions.size();
  for (const Attribute& a : batch.attributes) values += a.values.size();
  for (const Attribute& a : batch.line_attributes) values += a.values.size();
  return 4 * values + 8 * batch.line_offsets.size();
}

// read_all within `limit` bytes (read_line_set).
LineSet read_all_within(LineReader& reader, uint64_t limit, const std::string& source) {
  if (std::optional<LineSet> whole = reader.take_whole()) return std::move(*whole);
  LineSet lines = header_of(reader.header());
  const uint64_t max_points = batch_points_within(lines, limit, uint64_t{1} << 22);
  LineSet batch;
  uint64_t held = 0;
  while (reader.next(batch, max_points)) {
    throw_if_interrupted();
    held += held_bytes(batch);
    if (3 * held > limit)
      throw BudgetExceeded(source + ": read whole, its first " +
                           std::to_string(lines.point_count() + batch.point_count()) +
                           " points and their arrays' growth take about " + format_bytes(3 * held) +
                           " in memory, more than the " + format_bytes(limit) +
                           " the memory budget leaves for reading; raise the budget "
                           "(--memory-budget; memory_budget= in Python)");
    append_lines(lines, batch);
  }
  add_counts_read(lines.metadata, reader.counts_read());
  return lines;
}

}  // namespace

LineSet read_line_set(const std::string& source, const ReadOptions& options) {
  const std::unique_ptr<LineReader> reader = open_line_reader(source, options);
  LineSet lines = options.memory_limit ? read_all_within(*reader, *options.memory_limit, source)
                                       : read_all(*reader);
  if (synth::is_synth_source(source)) return lines;
  // A file with no lines is a valid, empty line set (a filter that kept nothing writes one);
  // what needs lines (bake) says so.
  lines.metadata.emplace("source", source);
  return lines;
}

namespace {

// NaN and infinities, which an ASCII legacy VTK file holds as "nan" and "inf": linebake reads
// them back, VTK's legacy reader (ParaView) stops at the first and drops the arrays after it.
uint64_t nonfinite_values(const LineSet& lines) {
  uint64_t count = 0;
  const auto add = [&](const std::vector<float>& values) {
    for (float v : values) count += !std::isfinite(v);
  };
  add(lines.positions);
  for (const auto* list : {&lines.attributes, &lines.line_attributes})
    for (const Attribute& a : *list) add(a.values);
  return count;
}

}  // namespace

void write_line_set(const LineSet& lines, const std::string& path, const WriteOptions& options) {
  const Format format = resolve_output_format(path, options.format);
  if (format == Format::vtk && options.ascii)
    if (const uint64_t count = nonfinite_values(lines); count > 0)
      notify(path + ": " + std::to_string(count) +
             " NaN or infinite value(s) are written as nan or inf in ASCII, which VTK's legacy "
             "reader (ParaView) cannot read: it stops at the first and drops the arrays after "
             "it; leave --ascii out (binary .vtk) or write .vtp (docs/formats.md)");
  AtomicFile file(path);
  file.write_with([&] {
    switch (format) {
      case Format::obj:
        formats::write_obj(lines, file.temp_path(), options);
        break;
      case Format::binlines:
        formats::write_binlines(lines, file.temp_path(), options);
        break;
      case Format::vtk:
        formats::write_vtk_legacy(lines, file.temp_path(), options);
        break;
      case Format::vtp:
        formats::write_vtp(lines, file.temp_path(), options);
        break;
      case Format::hdf5:
        formats::write_hdf5(lines, file.temp_path(), options);
        break;
      case Format::csv:
        formats::write_csv(lines, file.temp_path(), options);
        break;
      default:
        throw Error("unsupported output format");
    }
  });
  // A signal during a write the format does not check often (an HDF5 dataset is one call): the
  // file is not renamed into place. It had been, whole, with Python's KeyboardInterrupt after it,
  // so the caller could not tell whether the file was written.
  throw_if_interrupted();
  file.commit();
}

namespace {

class CollectingWriter : public LineWriter {
 public:
  CollectingWriter(std::string path, const LineSet& header, WriteOptions options)
      : path_(std::move(path)), lines_(header_of(header)), options_(std::move(options)) {
    resolve_output_format(path_, options_.format);  // refuse an unwritable format up front
  }
  void write(const LineSet& batch) override { append_lines(lines_, batch); }
  void close() override { write_line_set(lines_, path_, options_); }
  bool streams() const override { return false; }

 private:
  std::string path_;
  LineSet lines_;
  WriteOptions options_;
};

}  // namespace

std::unique_ptr<LineWriter> open_line_writer(const std::string& path, const LineSet& header,
                                             const WriteOptions& options) {
  if (resolve_output_format(path, options.format) == Format::binlines)
    return formats::open_binlines_writer(path, header, options);
  return std::make_unique<CollectingWriter>(path, header, options);
}

}  // namespace linebake
