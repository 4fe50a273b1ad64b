// linebake.LineSet from and to NumPy arrays, read() and write() through the format registry,
// info(), validation and derived attributes.

#include <algorithm>
#include <charconv>
#include <cmath>
#include <optional>

#include "bindings.hpp"
#include "cli_contract.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/memory_budget.hpp"
#include "core/nearest.hpp"
#include "formats/registry.hpp"
#include "lines/derived.hpp"
#include "lines/line_info.hpp"
#include "lines/validate.hpp"
#include "whole_output.hpp"

namespace linebake::python {

namespace {

const char* const kPositions = "an (n, 3) array of positions";

// (n, 3) float32 positions, copied into the line set. A finite value past float32's range is
// refused naming its row, as the file readers refuse one; NaN and infinities given as such are
// data, validated later.
std::vector<float> positions_from(const py::array& points) {
  if (points.ndim() == 2 && points.shape(1) == 3)
    if (const auto beyond = beyond_float32(points, "points", kPositions))
      throw py::value_error("points: row " + std::to_string(beyond->first / 3) + ": " +
                            beyond_float32_text(beyond->second));
  const auto xyz = c_array<float>(points, "points", kPositions);
  if (xyz.ndim() != 2 || xyz.shape(1) != 3)
    throw py::value_error(std::string("points: expected ") + kPositions);
  return {xyz.data(), xyz.data() + xyz.size()};
}

// Offsets: integers, line i spans points [offsets[i], offsets[i + 1]), from 0 to the point count.
std::vector<uint64_t> offsets_from(const py::array& offsets, size_t points) {
  const char kind = offsets.dtype().kind();
  if (offsets.ndim() != 1 || (kind != 'i' && kind != 'u'))
    throw py::value_error("offsets: expected a 1-D integer array (uint64)");
  // Signed input is checked before the cast, which would wrap negative values.
  const char* wanted = "a 1-D integer array (uint64)";
  if (kind == 'i') {
    const auto signed_values = c_array<int64_t>(offsets, "offsets", wanted);
    for (py::ssize_t i = 0; i < signed_values.size(); ++i)
      if (signed_values.data()[i] < 0) throw py::value_error("offsets: negative offset");
  }
  const auto values = c_array<uint64_t>(offsets, "offsets", wanted);
  std::vector<uint64_t> result(values.data(), values.data() + values.size());
  if (result.empty() || result.front() != 0)
    throw py::value_error("offsets: must start at 0 (one more offset than lines)");
  if (!std::is_sorted(result.begin(), result.end()))
    throw py::value_error("offsets: must not decrease");
  if (result.back() != points)
    throw py::value_error("offsets: the last offset (" + std::to_string(result.back()) +
                          ") must be the point count (" + std::to_string(points) + ")");
  return result;
}

// {name: values} with one float32 value per point (or per line), in the dict's order.
std::vector<Attribute> attributes_from(const py::dict& mapping, size_t count, const char* what) {
  std::vector<Attribute> attributes;
  for (const auto& [key, value] : mapping) {
    Attribute attribute;
    attribute.name = text_arg(key, std::string(what) + " name");
    // Every format names its attributes; an empty name had read back as "unnamed" from most and
    // made a CSV linebake cannot read ("header column has no name").
    if (attribute.name.empty())
      throw py::value_error(std::string(what) + " names must not be empty");
    // Lists of Python floats are float64 arrays here, checked as such, and converted once.
    const std::string named = std::string(what) + " '" + attribute.name + "'";
    const char* unit = std::string(what) == "attribute" ? "point" : "line";
    const std::string wanted = std::to_string(count) + " float32 values, one per " + unit;
    const py::array given = number_array(value, named, wanted.c_str());
    if (const auto beyond = beyond_float32(given, named, wanted.c_str()))
      throw py::value_error(named + ": " + unit + " " + std::to_string(beyond->first) + ": " +
                            beyond_float32_text(beyond->second));
    const auto values = c_array<float>(given, named, wanted.c_str());
    if (values.ndim() != 1 || size_t(values.size()) != count)
      throw py::value_error(named + ": expected " + wanted);
    attribute.values.assign(values.data(), values.data() + values.size());
    attributes.push_back(std::move(attribute));
  }
  return attributes;
}

// The bytes copying `value` into a line set's array of `word`-byte values takes: the copy, and a
// conversion before it unless the value is a C-order array of that kind already (a list is
// made a float64 array first).
uint64_t copy_bytes(const py::handle& value, char kind, size_t word) {
  if (!py::isinstance<py::array>(value)) {
    const py::ssize_t n = PyObject_Length(value.ptr());
    if (n < 0) PyErr_Clear();
    return n < 0 ? 0 : uint64_t(n) * (word + word + 8);
  }
  const auto array = py::reinterpret_borrow<py::array>(value);
  const uint64_t copy = uint64_t(array.size()) * word;
  const bool as_is = array.dtype().kind() == kind && size_t(array.dtype().itemsize()) == word &&
                     (array.flags() & py::array::c_style) != 0;
  // Wider floats out of C order are also copied as float64 for the range check.
  const bool wide_copy = array.dtype().kind() == 'f' && array.dtype().itemsize() > 4 &&
                         (array.flags() & py::array::c_style) == 0;
  return (as_is ? copy : 2 * copy) + (wide_copy ? uint64_t(array.size()) * 8 : 0);
}

// What the line set's copies take, checked against what `memory_budget` leaves before any is
// made (the caller's arrays are in the process's resident memory already).
void check_copies(const py::array& points, const py::array& offsets, const py::dict& attributes,
                  const py::dict& line_attributes, const py::object& memory_budget) {
  MemoryBudget budget = budget_of(memory_budget, "LineSet: memory_budget");
  uint64_t bytes = copy_bytes(points, 'f', sizeof(float)) +
                   2 * copy_bytes(offsets, 'u', sizeof(uint64_t));  // signed ones checked first
  size_t count = 0;
  for (const py::dict* mapping : {&attributes, &line_attributes})
    for (const auto& [key, value] : *mapping) {
      bytes += copy_bytes(value, 'f', sizeof(float));
      ++count;
    }
  budget.reserve(bytes, "LineSet: copying " + std::to_string(points.size() / 3) + " points, " +
                            std::to_string(std::max<py::ssize_t>(offsets.size() - 1, 0)) +
                            " lines and " + std::to_string(count) + " attributes");
}

std::shared_ptr<PyLineSet> make_line_set(const py::object& points_like,
                                         const py::object& offsets_like,
                                         const py::object& attributes,
                                         const py::object& line_attributes,
                                         const py::object& metadata,
                                         const py::object& memory_budget) {
  auto result = std::make_shared<PyLineSet>();
  LineSet& lines = result->lines;
  // Booleans are no positions (an attribute of them reads as 0 and 1).
  const py::array points = number_array(points_like, "points", kPositions, "iufO");
  const py::array offsets = number_array(offsets_like, "offsets", "a 1-D integer array (uint64)");
  // Each mapping taken once: an iterator of pairs (zip(names, arrays)) is spent by the first
  // look (its attributes had been counted for the budget and then found empty).
  const auto as_dict = [](const py::object& mapping, const char* what) {
    return mapping.is_none() ? py::dict() : mapping_arg(mapping, what);
  };
  const py::dict point_values = as_dict(attributes, "attribute");
  const py::dict line_values = as_dict(line_attributes, "line attribute");
  check_copies(points, offsets, point_values, line_values, memory_budget);
  lines.positions = positions_from(points);
  lines.line_offsets = offsets_from(offsets, lines.point_count());
  lines.attributes = attributes_from(point_values, lines.point_count(), "attribute");
  lines.line_attributes = attributes_from(line_values, lines.line_count(), "line attribute");
  if (!metadata.is_none())
    for (const auto& [key, value] : mapping_arg(metadata, "metadata")) {
      const std::string pair = repr_of(key) + ": " + repr_of(value);
      if (!py::isinstance<py::str>(key) || !py::isinstance<py::str>(value))
        throw py::type_error("metadata: keys and values are str, got " + pair);
      // Written to files as UTF-8 text: a lone surrogate (os.fsdecode's escape of a byte) is
      // none.
      try {
        lines.metadata[text_arg(key, "metadata")] = text_arg(value, "metadata");
      } catch (const py::type_error&) {
        throw py::type_error(
            "metadata: keys and values are str that UTF-8 can encode (no lone surrogates), got " +
            pair);
      }
    }
  // The frame the points are relative to (LineSet.origin): checked here, not at the first write.
  if (has_origin(lines)) {
    const std::optional<Origin> origin = parse_origin(lines.metadata.at(kOriginKey));
    if (!origin)
      throw py::value_error(
          "metadata: 'origin' is the frame the points are relative to, three "
          "finite numbers 'x y z'; got " +
          repr_of(py::str(lines.metadata.at(kOriginKey))));
    set_origin(lines, *origin);
  }
  return result;
}

nlohmann::json info_json(const PyLineSet& set) {
  return line_set_info(set.lines, set.source, set.format);
}

nlohmann::json validation_json(const ValidationReport& v) {
  return {{"clean", v.clean()},
          {"summary", v.summary()},
          {"invalid_points", v.invalid_points},
          {"repeated_points", v.repeated_points},
          {"short_lines", v.short_lines},
          {"bad_offsets", v.bad_offsets},
          {"attribute_length_mismatches", v.attribute_length_mismatches},
          {"nonfinite_attribute_values", v.nonfinite_attribute_values},
          {"lines_split", v.lines_split},
          {"lines_dropped", v.lines_dropped},
          {"points_dropped", v.points_dropped},
          {"attributes_dropped", v.attributes_dropped},
          {"repaired", v.repaired}};
}

// Attribute views keyed by name, each kept alive by the line set object `self`.
py::dict attribute_views(const std::vector<Attribute>& attributes, py::handle self) {
  py::dict views;
  for (const Attribute& a : attributes)
    views[fs_str(a.name)] = view(a.values.data(), a.values.size(), {}, self);
  return views;
}

std::shared_ptr<PyLineSet> read(const py::object& source_arg, const py::object& format_arg,
                                const py::object& memory_budget, const py::object& origin_arg_) {
  const std::string source = path_arg(source_arg, "read");
  const std::optional<std::string> format =
      format_arg.is_none() ? std::nullopt
                           : std::optional(typed_arg<std::string>(format_arg, "read: format"));
  // "8G", "unlimited" or bytes, as bake takes it; None: the CLI's default.
  const std::string budget_text =
      memory_budget.is_none() ? "" : budget_arg(memory_budget, "read: memory_budget");
  cli::check_input_file(source);  // the CLI's "no such file" / "is a directory"
  ReadOptions options;
  if (format) options.format = parse_format(*format);
  // A format read whole (OBJ, VTK, VTP) is held within the budget (by default the CLI's, half
  // of physical memory) while it is read: past it, BudgetExceeded rather than the kernel's kill.
  const MemoryBudget budget(cli::memory_budget_bytes(budget_text));
  if (!budget.unlimited()) options.memory_limit = budget.available();
  const std::string origin = origin_arg(origin_arg_, "read: origin");
  auto result = std::make_shared<PyLineSet>();
  {
    const LongCall call;
    options.origin = resolve_origin(origin, {source}, options);
    result->lines = read_line_set(source, options);
    result->format = source_format_name(source, options);
  }
  result->source = source;
  return result;
}

// As `linebake convert`: what the format cannot hold is a warning, or an Error when strict.
void write(const PyLineSet& set, const py::object& path_object, const py::object& format_arg,
           const py::object& ascii_arg, const py::object& binlines_version_arg,
           const py::object& vtp_encoding_arg, const py::object& vtp_compress_arg,
           const py::object& strict_arg) {
  const std::string path = path_arg(path_object, "write");
  // Each of its own kind, named when not (a number had been taken as a flag, True as version 1,
  // and a None or a float had been pybind11's "incompatible function arguments").
  const std::optional<std::string> format =
      format_arg.is_none() ? std::nullopt
                           : std::optional(typed_arg<std::string>(format_arg, "write: format"));
  const bool ascii = typed_arg<bool>(ascii_arg, "write: ascii");
  const bool vtp_compress = typed_arg<bool>(vtp_compress_arg, "write: vtp_compress");
  const bool strict = typed_arg<bool>(strict_arg, "write: strict");
  const std::string vtp_encoding = typed_arg<std::string>(vtp_encoding_arg, "write: vtp_encoding");
  const int64_t binlines_version =
      typed_arg<int64_t>(binlines_version_arg, "write: binlines_version");
  // Checked as `linebake convert` checks --binlines-version and --vtp-encoding, before the
  // format's warnings (an unknown name had been a plain Error, after them).
  if (binlines_version < 1 || binlines_version > 2)
    throw UsageError("write: binlines_version: 1 or 2, not " + std::to_string(binlines_version));
  // (binlines_version is 1 or 2 from here)
  std::string encoding = vtp_encoding;
  if (const std::string problem =
          cli::one_of({"appended", "appended-base64", "base64", "ascii"})(encoding);
      !problem.empty())
    throw UsageError("write: vtp_encoding: " + problem);
  if (!set.source.empty()) refuse_input_as_output(path, {set.source});
  WriteOptions options;
  options.format =
      resolve_output_format(path, format ? std::optional(parse_format(*format)) : std::nullopt);
  // Options of other formats refused as `linebake convert` refuses them (only values other
  // than the defaults can tell that they were given).
  const Format f = *options.format;
  if (ascii && f != Format::vtk && f != Format::vtp)
    throw UsageError("write: ascii: only for vtk and vtp outputs");
  if (binlines_version != 2 && f != Format::binlines)
    throw UsageError("write: binlines_version: only for binlines outputs");
  if ((vtp_encoding != "appended" || !vtp_compress) && f != Format::vtp)
    throw UsageError("write: vtp_encoding and vtp_compress: only for vtp outputs");
  options.ascii = ascii;
  options.binlines_version = uint32_t(binlines_version);
  options.vtp_encoding = ascii ? "ascii" : vtp_encoding;
  options.vtp_compress = vtp_compress;
  check_output_location(path);
  const std::vector<std::string> lost = lost_in_format(set.lines, *options.format, options);
  if (!lost.empty()) {
    const std::string message = path + ": " + format_info(*options.format).name + " cannot hold " +
                                name_list(lost) + "; they are not written";
    if (strict) throw Error(message + " (strict)");
    // A warnings filter may turn the warning into an error: then nothing is written. The path
    // as os.fsdecode gives it (PyErr_WarnEx would take only UTF-8).
    py::module_::import("warnings").attr("warn")(fs_str(message), py::handle(PyExc_UserWarning), 1);
  }
  const LongCall call;
  write_line_set(set.lines, path, options);
}

std::shared_ptr<PyLineSet> with_derived(const PyLineSet& set, const py::object& names_arg) {
  const std::vector<std::string> names = text_list(names_arg, "with_derived: names");
  auto result = std::make_shared<PyLineSet>(set);
  LineSet& lines = result->lines;
  for (const std::string& name : names) {
    Attribute derived = derive_attribute(lines, name);
    // A derived attribute replaces an input attribute of its name, as `convert --derive` does.
    for (auto* list : {&lines.attributes, &lines.line_attributes})
      std::erase_if(*list, [&](const Attribute& a) { return a.name == name; });
    (is_line_attribute(name) ? lines.line_attributes : lines.attributes)
        .push_back(std::move(derived));
  }
  return result;
}

py::tuple validated(const PyLineSet& set, const py::object& policy_arg) {
  const std::string policy = typed_arg<std::string>(policy_arg, "validate: policy");
  auto result = std::make_shared<PyLineSet>(set);
  const InvalidPolicy parsed = as_usage_error([&] { return parse_invalid_policy(policy); });
  const std::string source = set.source.empty() ? "<arrays>" : set.source;
  ValidationReport report;
  {
    const LongCall call;
    report = validate(result->lines, parsed, source);
  }
  return py::make_tuple(result, to_python(validation_json(report)));
}

py::list format_list() {
  py::list formats;
  for (const FormatInfo& f : format_table()) {
    py::dict entry;
    entry["name"] = f.name;
    entry["extensions"] = std::vector<std::string>(f.extensions.begin(), f.extensions.end());
    entry["read"] = f.readable;
    entry["write"] = f.writable;
    entry["line_attributes"] = f.line_attributes;
    entry["metadata"] = f.metadata;
    formats.append(entry);
  }
  return formats;
}

py::str repr(const PyLineSet& set) {
  std::string names;
  for (const auto* list : {&set.lines.attributes, &set.lines.line_attributes})
    for (const Attribute& a : *list) names += (names.empty() ? "" : ", ") + a.name;
  return fs_str("<linebake.LineSet " + std::to_string(set.lines.line_count()) + " lines, " +
                std::to_string(set.lines.point_count()) + " points" +
                (names.empty() ? "" : ", attributes " + names) +
                (set.source.empty() ? "" : ", from " + set.source) + ">");
}

}  // namespace

void bind_line_sets(py::module_& module) {
  py::class_<PyLineSet, std::shared_ptr<PyLineSet>>(module, "LineSet", R"doc(
A set of 3D polylines: positions, line offsets and float32 attributes per point or per line.

LineSet(points, offsets, attributes=None, line_attributes=None, metadata=None, *,
        memory_budget=None)

points: (n, 3) positions (converted to float32); offsets: line i spans points
offsets[i]:offsets[i+1], from 0 to n (converted to uint64); attributes: {name: n values};
line_attributes: {name: one value per line}; metadata: {str: str}. The arrays are copied in,
within memory_budget ('8G', 'unlimited' or bytes; None: half of physical memory, or of the
cgroup's or ulimit -v's limit when less): copies past what it leaves beside the process's
resident memory are refused before they are made (linebake.BudgetExceeded).
The properties points, offsets, attributes and line_attributes are read-only NumPy views of
the line set's own memory (no copy); they keep the line set alive.)doc")
      .def(py::init(&make_line_set), py::arg("points"), py::arg("offsets"),
           py::arg("attributes") = py::none(), py::arg("line_attributes") = py::none(),
           py::arg("metadata") = py::none(), py::kw_only(), py::arg("memory_budget") = py::none())
      .def_property_readonly(
          "points",
          [](py::object self) {
            const LineSet& l = self.cast<const PyLineSet&>().lines;
            return view(l.positions.data(), l.point_count(), {3}, self);
          },
          "(n, 3) float32 positions: a read-only view, no copy.")
      .def_property_readonly(
          "offsets",
          [](py::object self) {
            const LineSet& l = self.cast<const PyLineSet&>().lines;
            return view(l.line_offsets.data(), l.line_offsets.size(), {}, self);
          },
          "(lines + 1,) uint64 offsets: line i is points[offsets[i]:offsets[i+1]]. A view.")
      .def_property_readonly(
          "attributes",
          [](py::object self) {
            return attribute_views(self.cast<const PyLineSet&>().lines.attributes, self);
          },
          "{name: (n,) float32 view}: one value per point.")
      .def_property_readonly(
          "line_attributes",
          [](py::object self) {
            return attribute_views(self.cast<const PyLineSet&>().lines.line_attributes, self);
          },
          "{name: (lines,) float32 view}: one value per line.")
      .def_property_readonly(
          "metadata",
          [](const PyLineSet& s) {
            py::dict d;  // read from a file: not UTF-8 there reads as os.fsdecode gives it
            for (const auto& [key, value] : s.lines.metadata) d[fs_str(key)] = fs_str(value);
            return d;
          },
          "{str: str}: provenance, units, source notes (a copy).")
      .def_property_readonly(
          "origin",
          [](const PyLineSet& s) -> py::object {
            const std::optional<Origin> o = optional_origin(s.lines);
            if (!o) return py::none();
            return py::make_tuple((*o)[0], (*o)[1], (*o)[2]);
          },
          "(x, y, z) floats the points are relative to (world = points + origin, in float64), "
          "or None.")
      .def_property_readonly(
          "source",
          [](const PyLineSet& s) {
            return s.source.empty() ? py::object(py::none()) : py::object(fs_str(s.source));
          },
          "The file or synth: source it was read from; None when made from arrays.")
      .def_property_readonly("point_count",
                             [](const PyLineSet& s) { return s.lines.point_count(); })
      .def_property_readonly("line_count", [](const PyLineSet& s) { return s.lines.line_count(); })
      .def_property_readonly(
          "segment_count", [](const PyLineSet& s) { return s.lines.segment_count(); },
          "Consecutive point pairs within a line: the LS column of the paper's Table 1.")
      .def("__len__", [](const PyLineSet& s) { return s.lines.line_count(); })
      .def(
          "line",
          [](py::object self, int64_t at) {
            const LineSet& l = self.cast<const PyLineSet&>().lines;
            // Negative from the end, as Python's sequences count.
            const int64_t count = int64_t(l.line_count());
            if (at < -count || at >= count)
              throw py::index_error("line " + std::to_string(at) + " of " + std::to_string(count));
            const size_t index = size_t(at < 0 ? at + count : at);
            return view(l.positions.data() + 3 * l.line_offsets[index], l.line_size(index), {3},
                        self);
          },
          py::arg("index"), "(m, 3) view of line `index`'s points.")
      .def(
          "info", [](const PyLineSet& s) { return to_python(info_json(s)); },
          "Counts, bounds, attribute ranges, sizes and validation: the fields of `linebake info "
          "--json`.")
      .def("validate", &validated, py::arg("policy") = "repair",
           "(LineSet, report): 'repair' returns a repaired copy (bad points dropped, lines split, "
           "short lines dropped) and what was done; 'reject' raises linebake.Error unless clean.")
      .def("with_derived", &with_derived, py::arg("names"),
           "A copy with derived attributes added: segment_length, arc_length, curvature, "
           "index_along_line (per point), line_length (per line).")
      .def(
          "same_data",
          [](const PyLineSet& a, const PyLineSet& b) { return a.lines.same_data(b.lines); },
          py::arg("other"),
          "Exact equality of every array and name, and of the origin (the same world points); "
          "the rest of the metadata excluded.")
      .def("__repr__", &repr);

  module.def("read", &read, py::arg("source"), py::arg("format") = py::none(), py::kw_only(),
             py::arg("memory_budget") = py::none(), py::arg("origin") = py::none(),
             R"doc(Reads a line set: a file of any readable format (by extension unless
`format` names it) or a synthetic source "synth:<name>?scale=..&seed=..". Raises
linebake.InputError naming the file and place on bad input. Read within `memory_budget` ("8G",
"unlimited" or bytes as an int; default half of physical memory, or of the cgroup's or ulimit
-v's limit when less): OBJ, VTK and VTP files whole, the others gathered batch by batch; past
it, linebake.BudgetExceeded naming the file and place. `origin` (x, y, z), or 'auto' for the
first valid point rounded: the points come relative to it, subtracted in double before they are
rounded to float32 (for UTM or Earth-centred coordinates); `LineSet.origin` says it. Releases
the GIL.)doc");
  module.def("write", &write, py::arg("lines"), py::arg("path"), py::arg("format") = py::none(),
             py::kw_only(), py::arg("ascii") = false, py::arg("binlines_version") = 2,
             py::arg("vtp_encoding") = "appended", py::arg("vtp_compress") = true,
             py::arg("strict") = false,
             R"doc(Writes a line set in the format of the path's extension (or `format`),
through a temporary file renamed at the end. What the format cannot hold is a UserWarning, or
linebake.Error with strict=True. Releases the GIL.)doc");
  module.def("formats", &format_list,
             "Every format: name, extensions, read, write, what it holds.");
  module.def(
      "derived_attributes", [] { return derived_attribute_names(); },
      "Names with_derived() accepts.");
}

}  // namespace linebake::python
