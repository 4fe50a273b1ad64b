// linebake.render() and linebake.Renderer: frames of any technique this machine can run, as
// (h, w, 4) float32 arrays with the CLI's --stats fields; linebake.compare(): PSNR and SSIM.

#include <tbb/task_arena.h>

#include <algorithm>
#include <mutex>
#include <optional>
#include <type_traits>
#include <utility>

#include "assets.hpp"
#include "bindings.hpp"
#include "cli_contract.hpp"
#include "core/error.hpp"
#include "core/memory_budget.hpp"
#include "core/nearest.hpp"
#include "flight_plan.hpp"
#include "metrics/image_metrics.hpp"
#include "render_option_ranges.hpp"
#include "techniques/framing.hpp"
#include "techniques/technique.hpp"

namespace linebake::python {

namespace {

// The technique options of `linebake render` as keyword arguments ('_' for '-'); common ones
// (tf, size, frame, ...) are render()'s own parameters.
const std::vector<std::string> kRenderKeywords = {"memory_budget",
                                                  "on",
                                                  "no_early_termination",
                                                  "no_skip",
                                                  "rtx_geometry",
                                                  "tiles_geometry",
                                                  "tiles_sort",
                                                  "tiles_strips",
                                                  "rebuild",
                                                  "rtx_no_compaction",
                                                  "max_iterations",
                                                  "sort",
                                                  "node_bytes",
                                                  "capacity",
                                                  "max_layers",
                                                  "layers",
                                                  "tau_alpha",
                                                  "tau_opaque",
                                                  "beta",
                                                  "moments",
                                                  "moment_basis",
                                                  "moment_bias",
                                                  "wboit_weight",
                                                  "no_interlock",
                                                  "device",
                                                  "validation",
                                                  "embree_geometry",
                                                  "embree_quality",
                                                  "attribute",
                                                  "radius",
                                                  "hits",
                                                  "packets",
                                                  "early_termination"};

// A render option's value: of T's kind (typed_arg: a TypeError naming `function` and the keyword
// otherwise), then, as its text on the command line, through the CLI's check of the option
// (tools/render_option_ranges.hpp): a UsageError with the CLI's message where it refuses it.
template <class T>
T checked(const std::string& function, const char* keyword, const py::handle& value) {
  const std::string what = function + ": " + keyword;
  std::string text;
  if constexpr (std::is_same_v<T, std::string>) {
    text = text_arg(value, what);
  } else if constexpr (std::is_same_v<T, bool>) {
    return typed_arg<bool>(value, what);  // a flag: no value to check
  } else {
    if (!(std::is_integral_v<T> ? is_integer(value) : is_number(value)))
      wrong_kind(value, what, wanted_kind<T>());
    // As it would be written: an integer's digits, a float's shortest repr ("2.0", "nan").
    text =
        is_integer(value)
            ? std::string(py::str(py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()))))
            : std::string(py::repr(py::float_(py::reinterpret_borrow<py::object>(value))));
  }
  if (const std::string problem = cli::render_option_problem("--" + option_name(keyword), text);
      !problem.empty())
    throw UsageError(problem);
  return typed_arg<T>(value, what);
}

template <class T>
void set_from(const std::string& function, const py::kwargs& kw, const char* name, T& target) {
  if (kw.contains(name)) target = checked<T>(function, name, kw[name]);
}

// A memory budget ("40G", "unlimited", or bytes) as --memory-budget's text, checked as the CLI
// checks it; "" for None (half of physical memory).
std::string budget_from(const std::string& function, const py::handle& value) {
  if (value.is_none()) return "";
  // render()'s options are refused in the CLI's words (0 too).
  const std::string text = budget_arg(value, function + ": memory_budget", false);
  if (const std::string problem = cli::render_option_problem("--memory-budget", text);
      !problem.empty())
    throw UsageError(problem);
  return text;
}

TechniqueOptions technique_options(const std::string& function, const py::kwargs& kw, int width,
                                   int height) {
  TechniqueOptions o;
  o.width = width, o.height = height;
  // early_termination=True/False says for every technique what --early-termination or
  // --no-early-termination says (vrc stops early unless told not to; the rest do not unless
  // told to); the two keywords exclude each other as the flags do.
  if (kw.contains("early_termination") && kw.contains("no_early_termination"))
    throw UsageError(function +
                     ": early_termination and no_early_termination exclude each other (as "
                     "--early-termination and --no-early-termination); give one");
  if (kw.contains("early_termination")) {
    set_from(function, kw, "early_termination", o.early_termination);
    o.vrc_early_termination = o.early_termination;
  }
  set_from(function, kw, "device", o.device);
  set_from(function, kw, "validation", o.validation);
  set_from(function, kw, "hits", o.hits);
  set_from(function, kw, "embree_geometry", o.geometry);
  set_from(function, kw, "embree_quality", o.quality);
  set_from(function, kw, "packets", o.packets);
  set_from(function, kw, "radius", o.radius);
  set_from(function, kw, "attribute", o.attribute);
  set_from(function, kw, "sort", o.sort);
  set_from(function, kw, "capacity", o.capacity);
  set_from(function, kw, "node_bytes", o.node_bytes);
  set_from(function, kw, "max_layers", o.max_layers);
  set_from(function, kw, "layers", o.layers);
  set_from(function, kw, "wboit_weight", o.wboit_weight);
  set_from(function, kw, "moments", o.moments);
  set_from(function, kw, "tau_alpha", o.tau_alpha);
  set_from(function, kw, "tau_opaque", o.tau_opaque);
  set_from(function, kw, "beta", o.beta);
  set_from(function, kw, "moment_bias", o.moment_bias);
  set_from(function, kw, "moment_basis", o.moment_basis);
  set_from(function, kw, "on", o.on);
  set_from(function, kw, "rtx_geometry", o.rt_geometry);
  set_from(function, kw, "tiles_geometry", o.tiles_geometry);
  set_from(function, kw, "tiles_sort", o.tiles_sort);
  set_from(function, kw, "tiles_strips", o.tiles_strips);
  set_from(function, kw, "rebuild", o.rebuild);
  set_from(function, kw, "max_iterations", o.max_iterations);
  // The CLI's negative flags.
  const auto negated = [&](const char* name, bool& target) {
    if (kw.contains(name)) target = !checked<bool>(function, name, kw[name]);
  };
  negated("no_interlock", o.interlock);
  negated("no_early_termination", o.vrc_early_termination);
  negated("no_skip", o.skip_empty_space);
  negated("rtx_no_compaction", o.compaction);
  // What the scene may take (embree, reference: the BVH) and tiles' bands: '40G', 'unlimited'.
  if (kw.contains("memory_budget"))
    set_memory_budget(o, budget_from(function, kw["memory_budget"]));
  return o;
}

// (w, h) integers or "WxH", by the CLI's rule and message for --size.
std::array<int, 2> size_from(const std::string& function, const py::handle& size) {
  const std::string what = function + ": size";
  const char* wanted = "(width, height) integers or a str 'WxH'";
  std::string text;
  if (PyUnicode_Check(size.ptr())) {
    text = text_arg(size, what);
  } else {
    if (!PySequence_Check(size.ptr()) || PyBytes_Check(size.ptr()) ||
        PySequence_Size(size.ptr()) != 2) {
      PyErr_Clear();
      wrong_kind(size, what, wanted);
    }
    const auto pair = py::reinterpret_borrow<py::sequence>(size);
    for (size_t i = 0; i < 2; ++i) {
      if (!is_integer(pair[i])) wrong_kind(size, what, wanted);
      text += (i ? "x" : "") + std::string(py::str(py::reinterpret_steal<py::object>(
                                   PyNumber_Index(py::object(pair[i]).ptr()))));
    }
  }
  if (const std::string problem = cli::render_option_problem("--size", text); !problem.empty())
    throw UsageError(problem);
  return cli::parse_image_size(text);
}

// Three numbers.
glm::dvec3 xyz_from(const py::handle& value, const std::string& what) {
  const char* wanted = "three numbers";
  if (!PySequence_Check(value.ptr()) || PyUnicode_Check(value.ptr()) ||
      PyBytes_Check(value.ptr()) || PySequence_Size(value.ptr()) != 3) {
    PyErr_Clear();
    wrong_kind(value, what, wanted);
  }
  const auto xyz = py::reinterpret_borrow<py::sequence>(value);
  std::array<double, 3> v{};
  for (size_t i = 0; i < 3; ++i) {
    if (!is_number(xyz[i])) wrong_kind(value, what, wanted);
    v[i] = typed_arg<double>(xyz[i], what);
  }
  return {v[0], v[1], v[2]};
}

Camera camera_from(const py::dict& d) {
  const std::vector<std::string> known = {"eye", "target", "up", "fov"};
  for (const auto& [key, value] : d) {
    if (!PyUnicode_Check(key.ptr())) wrong_kind(key, "camera: a key", "a str");
    const std::string name = text_arg(key, "camera: a key");
    if (std::find(known.begin(), known.end(), name) == known.end())
      throw py::value_error("camera: unknown key " + repr_of(key) + " (" + name_list(known) + ")" +
                            did_you_mean(name, known));
  }
  if (!d.contains("eye") || !d.contains("target"))
    throw py::value_error("camera: needs 'eye' and 'target' (and optionally 'up', 'fov')");
  Camera c;
  c.eye = xyz_from(d["eye"], "camera: eye");
  c.target = xyz_from(d["target"], "camera: target");
  if (d.contains("up")) c.up = xyz_from(d["up"], "camera: up");
  if (d.contains("fov")) c.fov_y_degrees = typed_arg<double>(d["fov"], "camera: fov");
  if (const std::string problem = camera_problem(c); !problem.empty())
    throw py::value_error("camera: " + problem);
  return c;
}

// Linear RGB with the background, as the renderers give it, with alpha 1: the techniques
// composite over the background themselves.
py::array rgba_of(const Image& image) {
  py::array_t<float> rgba({py::ssize_t(image.height), py::ssize_t(image.width), py::ssize_t(4)});
  float* out = rgba.mutable_data();
  const size_t pixels = size_t(image.width) * size_t(image.height);
  for (size_t i = 0; i < pixels; ++i) {
    for (int c = 0; c < 3; ++c)
      out[4 * i + size_t(c)] =
          image.pixels[i * size_t(image.channels) + size_t(image.channels == 1 ? 0 : c)];
    out[4 * i + 3] = 1.0f;
  }
  return rgba;
}

// A technique prepared over one cache: frames rendered one after the other reuse its scene (the
// BVH, the Vulkan buffers).
class PyRenderer {
 public:
  // `function` names the call in messages: "Renderer", "render".
  PyRenderer(const std::string& function, const py::object& cache, const py::handle& technique,
             const py::handle& size, const py::kwargs& options) {
    // As the CLI checks its command line: the names, each value, then what the technique reads.
    check_keywords(function.c_str(), options, kRenderKeywords);
    name_ = checked<std::string>(function, "technique", technique);
    technique_ = &find_technique(name_);
    const auto [width, height] = size_from(function, size);
    options_ = technique_options(function, options, width, height);
    if (options.contains("memory_budget"))
      memory_budget_ = budget_from(function, options["memory_budget"]);
    check_technique_options(technique_->info, option_names(options));
    cache_ = py::isinstance<PyCache>(cache)
                 ? cache.cast<std::shared_ptr<PyCache>>()
                 : std::make_shared<PyCache>(path_arg(cache, function + ": cache"));
    // The availability check of `linebake techniques`, with the cache's assets.
    if (auto reason = technique_unavailable(*technique_, options_, &cache_->reader()))
      throw Error(name_ + ": cannot run here: " + *reason);
    const LongCall call;
    prepared_ = technique_->prepare(technique_->info, cache_->reader(), cache_->path(), options_);
    bounds_ = flight_bounds(cache_->reader());
  }

  // `function` names the call in messages: "Renderer.render", "render".
  py::tuple render(const std::string& function, const py::handle& tf_arg, const py::object& camera,
                   const py::handle& frame_arg, const py::handle& frame_count_arg,
                   const py::handle& flight_arg, const py::handle& size,
                   const py::handle& memory_budget) {
    const auto [width, height] =
        size.is_none() ? std::array{options_.width, options_.height} : size_from(function, size);
    const int frame_count = checked<int>(function, "frame_count", frame_count_arg);
    const int frame = checked<int>(function, "frame", frame_arg);
    // A name (semi, orbit-zoom) or a JSON file.
    const std::string tf_name = path_arg(tf_arg, function + ": tf");
    const std::string flight = path_arg(flight_arg, function + ": flight");
    if (frame >= frame_count)
      throw UsageError("frame " + std::to_string(frame) + ": the flight has " +
                       std::to_string(frame_count) + " frames, 0 to " +
                       std::to_string(frame_count - 1) + " (frame_count)");
    TechniqueOptions sized = options_;
    sized.width = width, sized.height = height;
    cli::check_frame_memory(
        name_, std::to_string(width) + "x" + std::to_string(height),
        estimate_frame_bytes(*technique_, sized),
        memory_budget.is_none() ? memory_budget_ : budget_from(function, memory_budget));
    const TransferFunction tf = resolve_transfer_function(tf_name);
    Camera c;
    std::string flight_kind = "camera";
    if (!camera.is_none()) {
      c = camera_from(mapping_arg(camera, "camera"));
    } else {
      // The CLI's flight: the same cameras for the same bounds, size and frame count.
      const cli::FlightPlan plan =
          cli::plan_flight(flight, frame_count, frame, "", bounds_, width, height);
      c = plan.cameras[size_t(frame)];
      flight_kind = to_string(plan.kind);
    }
    TechniqueFrame rendered;
    {
      const LongCall call;
      const std::lock_guard<std::mutex> one_at_a_time(mutex_);
      rendered = prepared_->render(c, tf, width, height);
    }
    // The CLI's --stats, for this one frame.
    nlohmann::json stats = prepared_->stats();
    stats["technique"] = name_;
    stats["transfer_function"] = tf.name;
    stats["flight"] = flight_kind;
    nlohmann::json entry = rendered.stats;
    entry["frame"] = frame;
    entry["seconds"] = rendered.seconds;
    entry["size"] = {width, height};
    entry["camera"] = {{"eye", {c.eye.x, c.eye.y, c.eye.z}},
                       {"target", {c.target.x, c.target.y, c.target.z}},
                       {"fov", c.fov_y_degrees}};
    entry["warnings"] = rendered.warnings;
    stats["frames"] = nlohmann::json::array({entry});
    return py::make_tuple(rgba_of(rendered.image), to_python(stats));
  }

  py::dict bounds() const {
    const Bounds& b = bounds_;
    py::dict d;
    d["min"] = b.min;
    d["max"] = b.max;
    return d;
  }
  py::object stats() const { return to_python(prepared_->stats()); }
  std::string device() const { return prepared_->device(); }

 private:
  std::string name_;
  std::string memory_budget_;  // the Renderer's (""; none given): what render() checks by default
  const Technique* technique_ = nullptr;
  std::shared_ptr<PyCache> cache_;
  TechniqueOptions options_;
  Bounds bounds_;  // the cache's flight_bounds, the same for every technique
  std::unique_ptr<PreparedTechnique> prepared_;
  std::mutex mutex_;
};

// An (h, w, 3 or 4) array (alpha dropped) or an image file (str, bytes, os.PathLike), as the
// metrics read it. Float arrays are values as they are; uint8 and uint16 arrays are scaled by
// 1/255 and 1/65535 as read_png reads a PNG of that depth, and like it taken as display
// (sRGB-encoded) values unless `srgb_encoded` says otherwise. A file says itself what its values
// are (.png encoded, .pfm linear).
Image image_from(const py::object& source, const std::optional<bool>& srgb_encoded,
                 const char* which, MemoryBudget& budget) {
  const std::string what = std::string("compare: ") + which;
  if (PyUnicode_Check(source.ptr()) || PyBytes_Check(source.ptr()) ||
      py::hasattr(source, "__fspath__")) {
    const std::string path = path_arg(source, what);
    cli::check_input_file(path);
    return read_image(path, budget);
  }
  const char* wanted = "an (h, w, 3|4) array or a path (str, bytes, os.PathLike)";
  const py::array given = number_array(source, what, wanted, nullptr);  // its kinds below
  const char kind = given.dtype().kind();
  const size_t bytes = size_t(given.dtype().itemsize());
  const double scale = kind == 'u' && bytes == 1 ? 255.0 : kind == 'u' && bytes == 2 ? 65535.0 : 0;
  if (kind != 'f' && scale == 0)
    throw py::type_error(what + ": expected float, uint8 or uint16 values, got " +
                         std::string(py::str(given.dtype())));
  // Colour (h, w, 3|4), or grey as a grey PNG reads: (h, w) or (h, w, 1).
  const bool grey = given.ndim() == 2 || (given.ndim() == 3 && given.shape(2) == 1);
  if (!grey && (given.ndim() != 3 || (given.shape(2) != 3 && given.shape(2) != 4)))
    throw py::value_error(
        "compare: expected an (h, w, 3), (h, w, 4), (h, w) or (h, w, 1) image or a file name");
  const size_t channels = grey ? 1 : 3;
  // The image's floats, and the array converted to float32 or uint16 (C order) where it is not
  // so already, checked before either is allocated.
  const size_t word = scale != 0 ? sizeof(uint16_t) : sizeof(float);
  const bool converted = given.dtype().itemsize() != py::ssize_t(word) ||
                         (scale == 0) != (kind == 'f') || !(given.flags() & py::array::c_style);
  const uint64_t floats = image_bytes(int(given.shape(1)), int(given.shape(0)), int(channels));
  const uint64_t copy = converted ? uint64_t(given.size()) * word : 0;
  const uint64_t wide_copy = wide_copy_bytes(given);  // for the range check below
  budget.reserve(floats + copy + wide_copy, what + "'s " + std::to_string(given.shape(0)) + "x" +
                                                std::to_string(given.shape(1)) + " array (" +
                                                std::to_string(given.size()) + " values)");
  // A finite colour value NumPy's cast would make an infinity, said as such (it had been called
  // "not a finite value"); alpha is dropped, so not checked.
  const size_t stride = given.ndim() == 2 ? 1 : size_t(given.shape(2));
  if (const auto beyond =
          beyond_float32(given, what, wanted, stride, std::min<size_t>(stride, 3))) {
    const size_t pixel = beyond->first / stride;
    const size_t width = size_t(std::max<py::ssize_t>(given.shape(1), 1));
    throw py::value_error(what + ": pixel (" + std::to_string(pixel % width) + ", " +
                          std::to_string(pixel / width) +
                          "): " + beyond_float32_text(beyond->second));
  }
  budget.release(wide_copy);
  Image image(int(given.shape(1)), int(given.shape(0)), int(channels));
  image.srgb_encoded = srgb_encoded.value_or(scale != 0);
  const size_t pixels = size_t(image.width) * size_t(image.height);
  if (scale != 0) {
    // uint8 widened to uint16 exactly; each value as read_png computes it.
    using Words = py::array_t<uint16_t, py::array::c_style | py::array::forcecast>;
    const Words words = c_array<uint16_t>(given, what, wanted);
    const uint16_t* in = words.data();
    for (size_t i = 0; i < pixels; ++i)
      for (size_t c = 0; c < channels; ++c)
        image.pixels[channels * i + c] = float(in[stride * i + c] / scale);
  } else {
    using Floats = py::array_t<float, py::array::c_style | py::array::forcecast>;
    const Floats floats_in = c_array<float>(given, what, wanted);
    const float* in = floats_in.data();
    for (size_t i = 0; i < pixels; ++i)
      for (size_t c = 0; c < channels; ++c) image.pixels[channels * i + c] = in[stride * i + c];
  }
  budget.release(copy);
  return image;
}

py::dict compare(const py::object& a, const py::object& b, const py::object& srgb_encoded_arg,
                 const py::object& memory_budget) {
  const std::optional<bool> srgb_encoded =
      srgb_encoded_arg.is_none()
          ? std::nullopt
          : std::optional(typed_arg<bool>(srgb_encoded_arg, "compare: srgb_encoded"));
  MemoryBudget budget = budget_of(memory_budget, "compare: memory_budget");
  // Each checked as given (the display encoding clamps an infinity to 0 or 1; a NaN stays) and
  // encoded in place: two images and SSIM's rows, no more.
  const auto read = [&](const py::object& source, const char* which) {
    Image image = image_from(source, srgb_encoded, which, budget);
    if (const std::string place = first_nonfinite_pixel(image); !place.empty())
      throw py::value_error(std::string("compare: the ") + which + "'s " + place +
                            " is not a finite value (NaN or infinity): PSNR and SSIM need "
                            "finite values");
    return display_encoded(std::move(image));
  };
  const Image first = read(a, "image"), second = read(b, "reference");
  // As `linebake compare` says it.
  if (const std::string problem = comparison_problem(first, second, ""); !problem.empty())
    throw Error(problem);
  budget.reserve(
      ssim_scratch_bytes(first.width, first.height, tbb::this_task_arena::max_concurrency()),
      "compare: SSIM's rows");
  double p = 0, s = 0;
  {
    const LongCall call;
    p = psnr(first, second);
    s = ssim(first, second);
  }
  py::dict result;
  result["psnr_db"] = p;
  result["ssim"] = s;
  result["ssim_mode"] = "per-channel mean";
  return result;
}

py::list technique_list(const py::object& device_arg) {
  const std::string device = typed_arg<std::string>(device_arg, "techniques: device");
  py::list rows;
  for (const Technique& t : techniques()) {
    TechniqueOptions options;
    options.device = device;
    const std::optional<std::string> why = technique_unavailable(t, options);
    py::dict row;
    row["name"] = t.info.name;
    row["summary"] = t.info.summary;
    row["reads"] = t.info.assets;
    row["vulkan"] = t.info.vulkan;
    row["ray_tracing"] = t.info.ray_tracing;
    row["exact"] = t.info.exact;
    row["options"] = t.info.options;
    row["available"] = !why;
    row["unavailable_reason"] = why.value_or("");
    rows.append(row);
  }
  return rows;
}

}  // namespace

void bind_rendering(py::module_& module) {
  py::class_<PyRenderer, std::shared_ptr<PyRenderer>>(module, "Renderer", R"doc(
A technique prepared over a cache, for rendering several frames:
Renderer(cache, technique="embree", size=(1280, 720), **options). cache: a Cache or a path.
options: the technique's options of `linebake render`, '_' for '-' (layers, moments,
moment_basis, sort, on, device, embree_geometry, ...); one the technique does not read is
linebake.UsageError, a technique this machine cannot run linebake.Error with the reason; values
are checked as `linebake render` checks them (linebake.UsageError with the CLI's message).
memory_budget ('40G', 'unlimited' or bytes as an int; default half of physical memory, or of the cgroup's or ulimit -v's limit when less):
embree's and reference's BVH is built within what it leaves, or refused with
linebake.BudgetExceeded; render() checks its frames against it unless given another.)doc")
      .def(py::init([](const py::object& cache, const py::object& technique, const py::object& size,
                       const py::kwargs& options) {
             return std::make_shared<PyRenderer>("Renderer", cache, technique, size, options);
           }),
           py::arg("cache"), py::arg("technique") = "embree",
           py::arg("size") = py::make_tuple(1280, 720))
      .def(
          "render",
          [](PyRenderer& self, const py::object& tf, const py::object& camera,
             const py::object& frame, const py::object& frame_count, const py::object& flight,
             const py::object& size, const py::object& memory_budget) {
            return self.render("Renderer.render", tf, camera, frame, frame_count, flight, size,
                               memory_budget);
          },
          py::arg("tf") = "semi", py::arg("camera") = py::none(), py::arg("frame") = 0,
          py::arg("frame_count") = 64, py::arg("flight") = "orbit-zoom",
          py::arg("size") = py::none(), py::arg("memory_budget") = py::none(),
          R"doc(One frame: (image, stats). image: (h, w, 4) float32, linear RGB over the
background, alpha 1. camera: {'eye': xyz, 'target': xyz, 'up': xyz, 'fov': degrees}, else frame
`frame` of the flight (orbit-zoom, orbit or a keyframes file) of frame_count frames, as the CLI.
stats: the fields of `linebake render --stats`. Releases the GIL.)doc")
      .def_property_readonly("bounds", &PyRenderer::bounds, "The box the flight frames.")
      .def_property_readonly("stats", &PyRenderer::stats, "The technique's --stats header.")
      .def_property_readonly("device", &PyRenderer::device, "The Vulkan device; '' on the CPU.");

  module.def(
      "render",
      [](const py::object& cache, const py::object& technique, const py::object& tf,
         const py::object& size, const py::object& frame, const py::object& frame_count,
         const py::object& flight, const py::object& camera, const py::object& memory_budget,
         const py::kwargs& options) {
        // The budget bounds the scene (the Renderer's option) and checks the frame.
        auto all = py::reinterpret_steal<py::kwargs>(PyDict_Copy(options.ptr()));
        if (!memory_budget.is_none()) all["memory_budget"] = memory_budget;
        PyRenderer renderer("render", cache, technique, size, all);
        return renderer.render("render", tf, camera, frame, frame_count, flight, py::none(),
                               memory_budget);
      },
      py::arg("cache"), py::kw_only(), py::arg("technique") = "embree", py::arg("tf") = "semi",
      py::arg("size") = py::make_tuple(1280, 720), py::arg("frame") = 0,
      py::arg("frame_count") = 64, py::arg("flight") = "orbit-zoom", py::arg("camera") = py::none(),
      py::arg("memory_budget") = py::none(), R"doc(
Renders one frame of a cache as `linebake render` does: returns (image, stats), image an
(h, w, 4) float32 array of linear RGB over the background with alpha 1. technique: embree,
reference, opaque, dp, ll, mlab, mlabdb, mboit, wboit, vrc, rtx, tiles (linebake.techniques()
says which run here); tf: opaque, semi, transparent or a JSON file; size: (w, h); frame of the
flight, or camera={'eye', 'target', 'up', 'fov'}. Technique options are keyword arguments, as
for Renderer, checked against the CLI's ranges (linebake.UsageError with the CLI's message).
memory_budget: '40G', 'unlimited' or bytes (an int); None: half of physical memory, or of the cgroup's or ulimit -v's limit when less. Releases
the GIL.)doc");
  module.def("compare", &compare, py::arg("image"), py::arg("reference"), py::kw_only(),
             py::arg("srgb_encoded") = py::none(), py::arg("memory_budget") = py::none(), R"doc(
PSNR (dB, capped at 60) and SSIM of an image against a reference, as `linebake compare`: both
display-encoded first. Each is an (h, w, 3|4) array (alpha ignored) or a .png/.pfm file (str,
bytes or os.PathLike). Float arrays are linear values, uint8 and uint16 arrays the values of a
PNG of that depth (scaled by 1/255, 1/65535; sRGB-encoded), unless srgb_encoded (True or False)
says what they are; other dtypes are a TypeError. Returns {'psnr_db', 'ssim', 'ssim_mode'}.
memory_budget: '8G', 'unlimited' or bytes (an int); None: half of physical memory, or of the
cgroup's or ulimit -v's limit when less. The two images (float32 copies, 12 bytes a pixel each in
colour) and SSIM's rows are held within it, refused before they are allocated
(linebake.BudgetExceeded naming the array or file). Releases the GIL for PSNR and SSIM.)doc");
  module.def("techniques", &technique_list, py::arg("device") = "",
             "Every technique: what it reads and needs, and whether it runs here (as `linebake "
             "techniques --json`).");
}

}  // namespace linebake::python
