// linebake.bake() with the CLI's options as keyword arguments, and linebake.open_cache(): the
// cached assets as NumPy views (tube chunks, voxel grid arrays) and provenance as dicts.

#include "assets.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <type_traits>
#include <typeinfo>

#include "bindings.hpp"
#include "cache/line_store.hpp"
#include "cache/tube_store.hpp"
#include "cache/voxel_store.hpp"
#include "cli_contract.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/memory_budget.hpp"
#include "core/nearest.hpp"
#include "core/output_lock.hpp"
#include "formats/registry.hpp"
#include "pipeline/bake.hpp"
#include "pipeline/report.hpp"
#include "synth/synth.hpp"

namespace linebake::python {

namespace {

// bake's keyword arguments: the CLI's long options with '_' for '-' ("from" is `format`).
const std::vector<std::string> kBakeKeywords = {"format",
                                                "on_invalid",
                                                "origin",
                                                "tube_sides",
                                                "radius",
                                                "radius_absolute",
                                                "radius_attribute",
                                                "caps",
                                                "normals",
                                                "attribute",
                                                "attribute_range",
                                                "chunk_bytes",
                                                "grid",
                                                "quantization",
                                                "max_chords",
                                                "voxel_attribute",
                                                "embree_geometry",
                                                "embree_quality",
                                                "embree_compact",
                                                "embree_robust",
                                                "embree_max_primitives",
                                                "rtx_geometry",
                                                "rtx_no_compaction",
                                                "device",
                                                "validation",
                                                "compression",
                                                "compression_level",
                                                "memory_budget",
                                                "force",
                                                "no_space_check",
                                                "dry_run"};

// The CLI's rule (tools/cmd_bake.cpp): an option no step of this bake reads is a mistake, not a
// no-op. Same messages, with the options spelled as keywords.
void refuse_unused(const py::kwargs& given, const std::vector<std::string>& assets,
                   const std::string& compression) {
  const auto building = [&](const char* asset) {
    return std::find(assets.begin(), assets.end(), asset) != assets.end();
  };
  const auto refuse_unless = [&](const std::vector<const char*>& names, bool applies,
                                 const std::string& when) {
    if (applies) return;
    std::string list;
    for (const char* name : names)
      if (given.contains(name)) list += (list.empty() ? "" : ", ") + std::string(name);
    if (!list.empty()) throw UsageError(list + ": read only " + when);
  };
  refuse_unless({"grid", "quantization", "max_chords", "voxel_attribute"}, building("voxels"),
                "when voxels are built (assets=['voxels'])");
  refuse_unless({"embree_geometry", "embree_quality", "embree_compact", "embree_robust",
                 "embree_max_primitives"},
                building("embree"), "when the Embree buffers are built (assets=['embree'])");
  refuse_unless({"rtx_geometry", "rtx_no_compaction", "device", "validation"}, building("rtx"),
                "when rtx acceleration structures are built (assets=['rtx'])");
  refuse_unless(
      {"tube_sides", "caps", "normals", "chunk_bytes", "attribute_range", "radius_attribute"},
      building("tubes") || building("rtx"), "when tubes are built (assets=['tubes'])");
  refuse_unless({"radius", "radius_absolute", "attribute"},
                building("tubes") || building("rtx") || building("embree"),
                "when tubes or Embree curves are built");
  refuse_unless({"compression_level"}, compression == "deflate" || compression == "blosc-zstd",
                "with compression='deflate' or 'blosc-zstd' (lz4 and none have no levels)");
}

// 2G, 512M, unlimited, or a number of bytes; 0 (no room for any work) is a UsageError, as on the
// command line (budget_arg).
uint64_t memory_budget_from(const py::handle& value) {
  const std::string text = budget_arg(value, "bake: memory_budget");
  if (text == "unlimited") return BakeOptions::kUnlimited;
  return PyUnicode_Check(value.ptr()) ? parse_size(text) : std::stoull(text);
}

// The voxel grid: "auto", N or "NxNxN" (parse_grid's rule, as --grid), an int N.
void grid_from(const py::handle& value, VoxelOptions& voxels) {
  if (!PyUnicode_Check(value.ptr()) && !is_integer(value))
    wrong_kind(value, "bake: grid", "'auto', an integer N or a str 'NxNxN'");
  const std::string text =
      is_integer(value) ? std::string(py::str(value)) : text_arg(value, "bake: grid");
  as_usage_error([&] { parse_grid(text, voxels); });
}

// Two numbers (lo, hi).
std::array<float, 2> range_from(const py::handle& value, const std::string& what) {
  const char* wanted = "two numbers (lo, hi)";
  if (!PySequence_Check(value.ptr()) || PyUnicode_Check(value.ptr()) ||
      PyBytes_Check(value.ptr()) || PySequence_Size(value.ptr()) != 2) {
    PyErr_Clear();
    wrong_kind(value, what, wanted);
  }
  const py::sequence pair = py::reinterpret_borrow<py::sequence>(value);
  std::array<float, 2> range{};
  for (size_t i = 0; i < 2; ++i) {
    if (!is_number(pair[i])) wrong_kind(value, what, wanted);
    // A number float32 cannot hold is the wrong value, not the wrong kind (the docs' ValueError).
    const double number = typed_arg<double>(pair[i], what);
    range[i] = float(number);
    if (std::isfinite(number) && !std::isfinite(range[i]))
      throw py::value_error(what + ": expected two finite numbers lo < hi, got (" +
                            repr_of(pair[0]) + ", " + repr_of(pair[1]) + "): " + repr_of(pair[i]) +
                            " is outside float32's range");
  }
  return range;
}

// The numbers bake() takes, as their text on the command line, through `linebake bake`'s own
// checks: a value the CLI refuses is a UsageError with its message (they had reached the bake: a
// negative tube_sides as a budget of 16 million TiB, compression_level 100 as a codec failure).
void check_numbers_as_cli(const py::kwargs& kw) {
  static const char* const kNumbers[] = {
      "tube_sides",   "radius",     "compression_level",    "chunk_bytes",
      "quantization", "max_chords", "embree_max_primitives"};
  for (const char* key : kNumbers) {
    if (!kw.contains(key)) continue;
    const py::handle value = kw[key];
    const std::string text =
        is_integer(value)
            ? std::string(py::str(py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()))))
            : std::string(py::repr(py::float_(py::reinterpret_borrow<py::object>(value))));
    if (const std::string problem = cli::bake_number_problem("--" + option_name(key), text);
        !problem.empty())
      throw UsageError("bake: " + problem);
  }
}

BakeOptions bake_options(const py::kwargs& kw, const std::vector<std::string>& assets,
                         bool progress) {
  check_keywords("bake", kw, kBakeKeywords);
  BakeOptions o;
  o.assets = assets;
  const std::vector<std::string> known = {"tubes", "voxels", "embree", "rtx"};
  for (const std::string& asset : assets)
    if (std::find(known.begin(), known.end(), asset) == known.end())
      throw UsageError("assets: unknown asset '" + asset +
                       "' (bake builds: tubes, voxels, embree, rtx)");
  const std::string compression = keyword<std::string>("bake", kw, "compression").value_or("lz4");
  refuse_unused(kw, assets, compression);
  if (auto v = keyword<std::string>("bake", kw, "format")) o.format = parse_format(*v);
  // A name none of the known: UsageError, as the CLI's checks of these options say.
  const auto parsed = [&](const char* name, const char* fallback, auto parse) {
    const std::string value = keyword<std::string>("bake", kw, name).value_or(fallback);
    return as_usage_error([&] { return parse(value); });
  };
  o.on_invalid = parsed("on_invalid", "repair", parse_invalid_policy);
  if (kw.contains("origin")) o.origin = origin_arg(kw["origin"], "bake: origin");
  o.compression = as_usage_error([&] { return parse_compression(compression); });
  // Not given: a bake into an existing cache keeps its codec, as the CLI's does.
  o.compression_given = kw.contains("compression");
  if (auto v = keyword<int>("bake", kw, "compression_level")) o.compression_level = *v;
  if (auto v = keyword<int>("bake", kw, "tube_sides")) o.tubes.sides = *v;
  if (auto v = keyword<float>("bake", kw, "radius")) o.tubes.radius = *v;
  if (auto v = keyword<bool>("bake", kw, "radius_absolute")) o.tubes.radius_absolute = *v;
  if (auto v = keyword<std::string>("bake", kw, "radius_attribute")) o.tubes.radius_attribute = *v;
  if (auto v = keyword<bool>("bake", kw, "caps")) o.tubes.caps = *v;
  o.tubes.normals = parsed("normals", "float32", parse_normal_encoding);
  if (auto v = keyword<std::string>("bake", kw, "attribute")) o.tubes.attribute = *v;
  if (kw.contains("attribute_range")) {
    const std::array<float, 2> v = range_from(kw["attribute_range"], "bake: attribute_range");
    if (!(std::isfinite(v[0]) && std::isfinite(v[1]) && v[0] < v[1]))
      throw py::value_error("bake: attribute_range: expected two finite numbers lo < hi, got (" +
                            std::to_string(v[0]) + ", " + std::to_string(v[1]) + ")");
    o.tubes.attribute_range = v;
  }
  if (auto v = keyword<uint64_t>("bake", kw, "chunk_bytes")) o.tubes.max_chunk_bytes = *v;
  if (kw.contains("grid")) grid_from(kw["grid"], o.voxels);
  if (auto v = keyword<uint32_t>("bake", kw, "quantization")) o.voxels.quantization = *v;
  if (auto v = keyword<uint32_t>("bake", kw, "max_chords")) o.voxels.max_chords_per_voxel = *v;
  if (auto v = keyword<std::string>("bake", kw, "voxel_attribute")) o.voxels.attribute = *v;
  o.embree.geometry = parsed("embree_geometry", "linear", parse_embree_geometry);
  o.embree.quality = parsed("embree_quality", "medium", parse_build_quality);
  if (auto v = keyword<bool>("bake", kw, "embree_compact")) o.embree.compact = *v;
  if (auto v = keyword<bool>("bake", kw, "embree_robust")) o.embree.robust = *v;
  if (auto v = keyword<uint64_t>("bake", kw, "embree_max_primitives"))
    o.embree.max_primitives_per_scene = *v;
  if (auto v = keyword<std::string>("bake", kw, "rtx_geometry")) o.rtx.geometry = *v;
  if (auto v = keyword<bool>("bake", kw, "rtx_no_compaction")) o.rtx.compaction = !*v;
  if (auto v = keyword<std::string>("bake", kw, "device")) o.rtx.device = *v;
  if (auto v = keyword<bool>("bake", kw, "validation")) o.rtx.validation = *v;
  if (kw.contains("memory_budget")) o.memory_budget = memory_budget_from(kw["memory_budget"]);
  if (auto v = keyword<bool>("bake", kw, "force")) o.force = *v;
  if (auto v = keyword<bool>("bake", kw, "no_space_check")) o.space_check = !*v;
  if (auto v = keyword<bool>("bake", kw, "dry_run")) o.dry_run = *v;
  check_numbers_as_cli(kw);  // once each is of its kind (a TypeError first)
  o.progress = progress;
  return o;
}

nlohmann::json estimate_json(const BakeEstimate& e) {
  return {{"lines", e.lines},   {"tubes", e.tubes}, {"voxels", e.voxels},
          {"embree", e.embree}, {"spill", e.spill}, {"total", e.total()}};
}

nlohmann::json result_json(const BakeResult& r) {
  nlohmann::json j;
  j["cache"] = r.cache;
  j["written"] = r.written;
  j["steps"] = nlohmann::json::array();
  for (const BakeStep& s : r.steps)
    j["steps"].push_back(
        {{"step", s.step}, {"built", s.built}, {"provenance", to_json(s.provenance)}});
  j["notes"] = r.notes;
  j["stages"] = nlohmann::json::array();
  for (const BakeStage& s : r.stages)
    j["stages"].push_back({{"name", s.name},
                           {"wall_s", s.wall_s},
                           {"cpu_s", s.cpu_s},
                           {"peak_rss_bytes", s.peak_rss_bytes}});
  j["memory_budget_bytes"] = r.memory_budget_bytes;
  j["peak_rss_bytes"] = r.peak_rss_bytes;
  j["batch_points"] = r.batch_points;
  j["spill_peak_bytes"] = r.spill_peak_bytes;
  j["bytes_written"] = r.bytes_written;
  j["wall_s"] = r.wall_s;
  j["estimate"] = estimate_json(r.estimate);
  // None where the file system could not be asked (a directory that does not exist yet).
  j["free_bytes"] =
      r.free_bytes == UINT64_MAX ? nlohmann::json(nullptr) : nlohmann::json(r.free_bytes);
  return j;
}

// `text` with every `from` replaced by `to`.
std::string renamed(std::string text, const std::string& from, const std::string& to) {
  if (from.empty()) return text;
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return text;
}

// f(), its errors naming `set` ("<arrays>", or the file the set was read from) where the bake's
// messages name its temporary input `temporary`, and the cache where one names it as an output
// (it could not be written): the user never named that file.
template <class F>
auto naming_the_set(const std::string& temporary, const std::string& set, const std::string& cache,
                    F f) -> decltype(f()) {
  const auto name = [&](const std::string& text) { return renamed(text, temporary, set); };
  try {
    return f();
  } catch (const Interrupted&) {
    throw;
  } catch (const InputError& e) {
    const size_t prefix = e.file().size() + (e.where().empty() ? 0 : e.where().size() + 2) + 2;
    const std::string what = e.what();
    throw InputError(name(e.file()), name(e.where()),
                     name(what.substr(std::min(prefix, what.size()))));
  } catch (const OutputError& e) {
    throw OutputError(renamed(e.file(), temporary, cache), renamed(e.detail(), temporary, cache));
  } catch (const UsageError& e) {
    throw UsageError(name(e.what()));
  } catch (const BudgetExceeded& e) {
    throw BudgetExceeded(name(e.what()));
  } catch (const Error& e) {
    if (typeid(e) != typeid(Error)) throw;
    throw Error(name(e.what()));
  }
}

// A line set given as arrays is baked from a temporary HDF5 line file (the format that keeps line
// attributes and metadata): bake reads its input in batches from a file, and its /lines
// provenance is that file's content hash. Beside the cache (its provenance names it), or for a
// dry run, which reads it and writes nothing, in the system's temporary directory. Named as
// temporary_name names a temporary (host, process, a counter): each call its own file, so threads
// baking into one cache path at once each bake their own lines, and a file a crashed process left
// is removed by the next bake of that cache (remove_stale_temporaries). Removed when the bake
// ends.
class TemporaryInput {
 public:
  // `name`: how messages name the set.
  TemporaryInput(const PyLineSet& set, const std::string& name, const std::string& cache,
                 bool dry_run) {
    namespace fs = std::filesystem;
    const fs::path dir =
        dry_run ? fs::temp_directory_path() : fs::absolute(fs::path(cache)).parent_path();
    path_ = temporary_name((dir / fs::path(cache).filename()).string(), "input") + ".h5";
    WriteOptions options;
    options.format = Format::hdf5;
    try {
      naming_the_set(path_, name, cache, [&] { write_line_set(set.lines, path_, options); });
    } catch (...) {
      remove();
      throw;
    }
  }
  ~TemporaryInput() { remove(); }
  TemporaryInput(const TemporaryInput&) = delete;
  TemporaryInput& operator=(const TemporaryInput&) = delete;
  const std::string& path() const { return path_; }

 private:
  void remove() const {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  std::string path_;
};

py::dict bake_lines(const py::object& lines_or_path, const py::object& cache,
                    const py::object& assets, const py::object& progress,
                    const py::kwargs& options) {
  // Named when of another kind (a str of assets and a number as progress had been pybind11's
  // "incompatible function arguments" and taken as a flag).
  BakeOptions o = bake_options(options, text_list(assets, "bake: assets"),
                               typed_arg<bool>(progress, "bake: progress"));
  o.cache = cache.is_none() ? "" : path_arg(cache, "bake: cache");
  std::optional<TemporaryInput> temporary;
  std::string set_name;  // how messages name a LineSet's lines
  if (py::isinstance<PyLineSet>(lines_or_path)) {
    if (o.cache.empty()) throw UsageError("bake: a LineSet needs a cache path");
    if (o.format) throw UsageError("format: read only when baking a file");
    // Before the temporary input: a directory that does not exist is the cache's.
    if (!o.dry_run) check_output_location(o.cache);
    const PyLineSet& set = lines_or_path.cast<const PyLineSet&>();
    set_name = set.source.empty() ? "<arrays>" : set.source;
    // The file the set was read from is its input too: a cache never replaces it.
    if (!set.source.empty() && !synth::is_synth_source(set.source))
      refuse_input_as_output(o.cache, {set.source});
    const LongCall call;
    temporary.emplace(set, set_name, o.cache, o.dry_run);
  } else {
    o.input = path_arg(lines_or_path, "bake");  // a str, bytes or os.PathLike
    cli::check_input_file(o.input);
    if (!o.dry_run) check_output_location(o.cache);
  }
  if (temporary) {
    o.input = temporary->path();
    // The cache records the file the set was read from, or no source for arrays; never the
    // temporary file.
    o.source_name = lines_or_path.cast<const PyLineSet&>().source;
  }
  o.inputs = {o.input};
  nlohmann::json result;
  {
    const LongCall call;
    const std::string input = temporary ? temporary->path() : "";
    naming_the_set(input, set_name, o.cache, [&] {
      // bake() reads the figures it returns back from the cache once it has renamed it there,
      // and so does the report: held around both, so that another bake (of this process or
      // another) renaming its cache there in between does not have this call describe that one.
      // The path bake writes (the input itself for a cache baked in place).
      std::optional<OutputLock> one_at_a_time;
      if (!o.dry_run) one_at_a_time.emplace(bake_output_path(o));
      const BakeResult baked = bake(o);
      result = result_json(baked);
      for (nlohmann::json& note : result["notes"])
        note = renamed(note.get<std::string>(), input, set_name);
      if (!o.dry_run)
        result["report"] = report_json({summarize_cache(CacheReader(baked.cache, false))})[0];
    });
  }
  return to_python(result);
}

// Views of one Array<T>, kept alive by the array's own owner (the file mapping or the
// allocation), not by the Python objects around it.
template <class T>
py::object array_view(const Array<T>& array, size_t columns) {
  const size_t rows = columns ? array.size() / columns : array.size();
  return view(array.data(), rows, columns ? std::vector<size_t>{columns} : std::vector<size_t>{},
              keep_alive(array.owner()));
}

template <class T>
py::object optional_view(const Array<T>& array, size_t columns) {
  if (array.empty()) return py::none();
  return array_view(array, columns);
}

}  // namespace

PyCache::PyCache(const std::string& path) : path_(path) {
  const LongCall call;           // the check walks the file's metadata: a call, without the GIL
  cli::check_cache_input(path);  // the CLI's messages for a line file, a plain HDF5 file
  reader_ = std::make_shared<CacheReader>(path);
}

const TubeMesh& PyCache::tubes() {
  const LongCall call;
  const std::lock_guard<std::mutex> once(*load_);
  // load_tubes says what is missing, as the CLI does
  if (!tubes_) tubes_ = std::make_shared<TubeMesh>(load_tubes(*reader_));
  return *tubes_;
}

const VoxelGrid& PyCache::voxels() {
  const LongCall call;
  const std::lock_guard<std::mutex> once(*load_);
  // load_voxels says what is missing, as the CLI does
  if (!voxels_) voxels_ = std::make_shared<VoxelGrid>(load_voxels(*reader_));
  return *voxels_;
}

namespace {

py::object provenance_of(const PyCache& cache, const py::object& step_arg) {
  const std::string step = typed_arg<std::string>(step_arg, "provenance: step");
  const std::string group = step == "lines" ? "/lines" : "/assets/" + step;
  const std::optional<Provenance> p = cache.reader().provenance(group);
  if (!p) throw InputError(cache.path(), group, "no provenance (no such step in the cache)");
  return to_python(to_json(*p));
}

py::dict tube_chunk(const TubeChunk& chunk) {
  py::dict d;
  d["first_line"] = chunk.first_line;
  d["line_count"] = chunk.line_count;
  d["positions"] = array_view(chunk.positions, 3);
  d["normals"] = optional_view(chunk.normals, 3);
  d["normals_oct"] = optional_view(chunk.normals_oct, 2);
  d["attribute"] = optional_view(chunk.attribute, 0);
  d["indices"] = array_view(chunk.indices, 3);
  return d;
}

py::dict tubes_dict(PyCache& cache) {
  const TubeMesh& mesh = cache.tubes();
  py::dict d;
  d["sides"] = mesh.sides;
  d["radius"] = mesh.radius;
  d["caps"] = mesh.caps;
  d["normals"] = to_string(mesh.normals);
  d["attribute"] = mesh.attribute;
  d["attribute_range"] = py::make_tuple(mesh.attribute_range[0], mesh.attribute_range[1]);
  d["lines_dropped"] = mesh.lines_dropped;
  d["points_skipped"] = mesh.points_skipped;
  d["vertex_count"] = mesh.vertex_count();
  d["triangle_count"] = mesh.triangle_count();
  py::list chunks;
  for (const TubeChunk& chunk : mesh.chunks) chunks.append(tube_chunk(chunk));
  d["chunks"] = chunks;
  return d;
}

// A per-voxel array as (z, y, x): the grid stores x fastest.
template <class T>
py::object grid_view(const Array<T>& array, const std::array<uint32_t, 3>& resolution) {
  if (array.empty()) return py::none();
  return view(array.data(), resolution[2], {resolution[1], resolution[0]},
              keep_alive(array.owner()));
}

py::dict voxels_dict(PyCache& cache) {
  const VoxelGrid& grid = cache.voxels();
  py::dict d;
  d["resolution"] = py::make_tuple(grid.resolution[0], grid.resolution[1], grid.resolution[2]);
  d["origin"] = py::make_tuple(grid.origin[0], grid.origin[1], grid.origin[2]);
  d["voxel_size"] = grid.voxel_size;
  d["quantization"] = grid.quantization;
  d["max_chords_per_voxel"] = grid.max_chords_per_voxel;
  d["attribute"] = grid.attribute;
  d["attribute_range"] = py::make_tuple(grid.attribute_range[0], grid.attribute_range[1]);
  d["offsets"] = array_view(grid.offsets, 0);
  d["chords"] = array_view(grid.chords, 2);
  d["line_counts"] = grid_view(grid.line_counts, grid.resolution);
  py::list density;
  for (size_t level = 0; level < grid.density.size(); ++level)
    density.append(grid_view(grid.density[level], grid.level_resolution(level)));
  d["density"] = density;
  d["voxels_occupied"] = grid.voxels_occupied;
  d["chords_dropped"] = grid.chords_dropped;
  d["voxels_overflowed"] = grid.voxels_overflowed;
  return d;
}

}  // namespace

void bind_assets(py::module_& module) {
  py::class_<PyCache, std::shared_ptr<PyCache>>(module, "Cache", R"doc(
An asset cache (.lbc.h5) opened for reading: linebake.open_cache(path).

Arrays are read-only NumPy views of the cache's memory: of the mapped file where a dataset is
stored uncompressed, else of the decompressed copy, which the Cache keeps (a second call returns
the same memory).)doc")
      .def_property_readonly(
          "path", [](const PyCache& c) { return fs_str(c.path()); },
          "The cache's path (as os.fsdecode gives it).")
      .def_property_readonly(
          "assets", [](const PyCache& c) { return c.reader().assets(); },
          "Assets stored under /assets: tubes, voxels, embree, rtx.")
      .def("provenance", &provenance_of, py::arg("step"),
           "What a step ('lines', 'tubes', 'voxels', ...) was built from, with what, and what it "
           "cost, as a dict (the provenance of `linebake report --json`).")
      .def(
          "report",
          [](const PyCache& c) { return to_python(report_json({summarize_cache(c.reader())})[0]); },
          "This cache's entry of `linebake report --json`: Table 1's figures.")
      .def(
          "lines",
          [](const PyCache& c) {
            auto set = std::make_shared<PyLineSet>();
            {
              const LongCall call;
              set->lines = load_lines(c.reader());
            }
            // Read from the cache: writing or baking it over the cache is refused, as for a
            // set read from any file.
            set->source = c.path();
            set->format = source_format_name(c.path());
            return set;
          },
          "The cached line set (/lines), as a LineSet (a copy).")
      .def("tubes", &tubes_dict,
           "The tube mesh: sides, radius, ..., and chunks, each a dict of first_line, line_count, "
           "positions (v, 3) float32, normals (v, 3) float32 or None, normals_oct (v, 2) int16 or "
           "None, attribute (v,) uint16 (unorm over attribute_range) or None, indices (t, 3) "
           "uint32.")
      .def("voxels", &voxels_dict,
           "The voxel line grid: resolution (x, y, z), origin, voxel_size, quantization, offsets "
           "(voxels + 1,) uint32, chords (c, 2) uint32 packed words, line_counts (z, y, x) "
           "uint8, density: list of (z, y, x) float32 levels.")
      .def("__repr__", [](const PyCache& c) {
        const std::string assets = name_list(c.reader().assets());
        return fs_str("<linebake.Cache " + c.path() + (assets.empty() ? "" : ": " + assets) + ">");
      });

  module.def(
      "open_cache",
      [](const py::object& path) {
        return std::make_shared<PyCache>(path_arg(path, "open_cache"));
      },
      py::arg("path"), "Opens an asset cache; linebake.InputError if it is not one.");
  module.def("bake", &bake_lines, py::arg("lines_or_path"), py::arg("cache") = py::none(),
             py::arg("assets") = std::vector<std::string>{"tubes"}, py::kw_only(),
             py::arg("progress") = false, R"doc(
Builds assets into an asset cache, as `linebake bake`: lines_or_path is a LineSet, a file or a
synth: source; cache defaults to <input name>.lbc.h5 (required for a LineSet, baked from a
temporary file of its own, which messages do not name: they name "<arrays>" or the file the set
was read from); assets from tubes, voxels, embree, rtx. The CLI's options are keyword
arguments with '_' for '-' (format for --from): tube_sides, radius, radius_absolute,
radius_attribute, caps, normals, attribute, attribute_range, chunk_bytes, grid ('auto', N or
'NxNxN'), quantization, max_chords, voxel_attribute, embree_geometry, embree_quality,
embree_compact, embree_robust, embree_max_primitives, rtx_geometry, rtx_no_compaction, device, validation, compression, compression_level, memory_budget ('2G',
'unlimited' or bytes as an int), force, no_space_check, dry_run, on_invalid. A value of the wrong
kind is a TypeError naming the keyword; an unknown name, or an option no step reads, is
linebake.UsageError. Returns the build result with its stages and the cache's report (the
entry of `linebake report --json`). Releases the GIL; no progress bar unless progress=True.)doc");
}

}  // namespace linebake::python
