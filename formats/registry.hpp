#pragma once
// Reading and writing line sets by file name: the format comes from the extension unless the
// caller names it. "synth:<name>?scale=..&seed=.." sources are readable wherever a file is.

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/progress.hpp"
#include "lines/line_reader.hpp"
#include "lines/line_set.hpp"
#include "lines/origin.hpp"

namespace linebake {

enum class Format { obj, binlines, vtk, vtp, netcdf, hdf5, trk, tck, csv };

struct FormatInfo {
  Format format;
  const char* name;
  std::vector<const char*> extensions;
  bool readable;
  bool writable;
  bool line_attributes;  // writes per-line attributes
  bool metadata;         // writes the line set's metadata (key/value strings)
};
const std::vector<FormatInfo>& format_table();
const FormatInfo& format_info(Format format);
Format parse_format(const std::string& name);  // throws UsageError with a did-you-mean
std::optional<Format> format_from_extension(const std::string& path);
// The forced format, else the one the extension names; throws Error when neither says.
Format resolve_format(const std::string& path, const std::optional<Format>& forced);
// For reading: as resolve_format, and an HDF5 file (a linebake cache, whatever its name) is read
// as hdf5 when its extension names no format.
Format resolve_input_format(const std::string& path, const std::optional<Format>& forced);
// As resolve_format, and throws Error when linebake cannot write that format.
Format resolve_output_format(const std::string& path, const std::optional<Format>& forced);

struct ReadOptions {
  std::optional<Format> format;  // overrides the extension
  ProgressFn progress;
  // Bytes a format read whole (OBJ, VTK, VTP) may hold while it is read, its arrays and the
  // line set gathered from them together; none: no limit (0: nothing, a budget used up). Each
  // reader checks what it will hold before it allocates (from the counts a VTK or VTP header
  // declares; an OBJ's as they grow) and throws BudgetExceeded naming the file past it, so a large
  // file is refused, not the process killed. The formats that stream hold one batch at a time,
  // and check it the same way: a batch holds at most the points its caller asks for unless one
  // line alone has more, and such a line is refused at its place (its byte offset, text line or
  // dataset rows) before it is read (LineReader::next).
  std::optional<uint64_t> memory_limit;
  // Positions relative to this origin (lines/origin.hpp): each reader subtracts it in double
  // where it turns the file's numbers into float32, and the header's metadata "origin" says it.
  // None: the file's own frame (a linebake HDF5 file or cache keeps its origin; any other file's
  // coordinates are taken as they are).
  std::optional<Origin> origin;
};

struct WriteOptions {
  std::optional<Format> format;   // overrides the extension
  bool ascii = false;             // vtk / vtp: text instead of binary
  uint32_t binlines_version = 2;  // 1 drops attribute names (what the public LineVis reads)
  bool vtp_compress = true;       // vtp: zlib-compressed blocks (ParaView's default)
  // vtp data layout: "appended" raw bytes (ParaView's default), "appended-base64", "base64"
  // (inline binary) or "ascii".
  std::string vtp_encoding = "appended";
  bool vtp_header_uint64 = true;  // header_type UInt64 (VTK 9 default) or UInt32
  ProgressFn progress;
};

// Opens a source for reading in batches of whole lines (lines/line_reader.hpp). Formats that
// cannot be read piece by piece (OBJ, VTK, VTP) are read whole here and served from memory.
// The header's metadata does not yet hold "source" (read_line_set adds it).
std::unique_ptr<LineReader> open_line_reader(const std::string& source,
                                             const ReadOptions& options = {});
// Input paths as given on a command line: each a path or a glob(7) pattern ('run/*.vtp'),
// expanded, then all sorted byte-wise: the order in which several files make one line set.
// A pattern that matches nothing, or a file named twice, is an InputError.
std::vector<std::string> expand_inputs(const std::vector<std::string>& patterns);
// Several files read as one line set, one after the other (batches never span two files). Every
// file must carry the first file's attributes, by name and in order: InputError naming the file
// otherwise. Files that cannot stream (OBJ, VTK, VTP) are read whole when their turn comes.
// What a user should hear of a reader's counts_read (a NetCDF file's trajectories split at
// missing positions), each with its metadata key; "" when nothing.
std::string counts_read_note(const std::map<std::string, uint64_t>& counts);
std::unique_ptr<LineReader> open_line_reader(const std::vector<std::string>& sources,
                                             const ReadOptions& options = {});
// One of several files read as one line set, in `frame`, the first file's origin
// (lines/origin.hpp), where no origin is asked for and the file has another (a linebake HDF5 file's
// own): opened again with `frame` as the origin asked for.
std::unique_ptr<LineReader> open_in_frame(const std::string& source, const ReadOptions& options,
                                          const Origin& frame);
// `--origin auto` (lines/origin.hpp): the first valid point of the sources, in world coordinates,
// rounded to integers; the sources' own origin (a linebake HDF5 file's) where no point is valid.
// It reads the sources up to that point (a format read whole: all of it).
Origin auto_origin(const std::vector<std::string>& sources, const ReadOptions& options = {});
// An --origin option's numbers: none for "" and "auto"; UsageError unless it is X,Y,Z.
std::optional<Origin> origin_option_numbers(const std::string& text);
// An --origin option's text: "" none, "auto" (auto_origin) or X,Y,Z; UsageError otherwise.
std::optional<Origin> resolve_origin(const std::string& text,
                                     const std::vector<std::string>& sources,
                                     const ReadOptions& options = {});
// Whether `text` is well-formed UTF-8 (RFC 3629: no overlong forms, surrogates or code points
// past U+10FFFF).
bool valid_utf8(std::string_view text);
// Throws InputError naming `path` when `header`'s attribute names (vertex and line, in order)
// differ from `first`'s, the header of the first file of one line set (at `first_path`).
void check_same_attributes(const LineSet& first, const std::string& first_path,
                           const LineSet& header, const std::string& path);
// The whole line set. Throws InputError (with file and place) on malformed input, Error on
// unsupported requests. With ReadOptions::memory_limit, a format that streams is gathered in
// batches sized to it, and BudgetExceeded names the source where the lines gathered, with their
// arrays' growth (up to three times them: the old and the doubled arrays side by side), would
// pass it.
LineSet read_line_set(const std::string& source, const ReadOptions& options = {});
// Format name of a source, as read_line_set would choose it ("synth" for synthetic sources).
std::string source_format_name(const std::string& source, const ReadOptions& options = {});

// Whether the format keeps a line without points: CSV has a row per point, and OBJ's `l` needs
// a vertex (its writer leaves such lines out).
bool keeps_empty_lines(Format format);
// "3 empty lines (without points)": what a format that does not keep them loses.
std::string empty_lines_phrase(uint64_t count);
// What writing `lines` as `format` would lose, one phrase each ("line attribute line_length",
// "metadata (scale, seed)", "attribute names (binlines version 1)", "2 empty lines (without
// points)"); empty when nothing.
std::vector<std::string> lost_in_format(const LineSet& lines, Format format,
                                        const WriteOptions& options = {});

// Writes through a temporary file renamed at the end: a failed write leaves nothing behind.
void write_line_set(const LineSet& lines, const std::string& path,
                    const WriteOptions& options = {});

// A line set written batch by batch (the batches of a LineReader). .binlines is written as the
// batches come, in bounded memory; the other formats collect the batches and write at close().
// Nothing appears under `path` before close() succeeds.
class LineWriter {
 public:
  virtual ~LineWriter() = default;
  virtual void write(const LineSet& batch) = 0;
  virtual void close() = 0;
  // True when the format is written as the batches come.
  virtual bool streams() const = 0;
};
// `header`: attribute names and metadata (as LineReader::header()).
std::unique_ptr<LineWriter> open_line_writer(const std::string& path, const LineSet& header,
                                             const WriteOptions& options = {});

}  // namespace linebake
