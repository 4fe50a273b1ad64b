// linebake.render() and linebake.Renderer: frames of any technique this machine can run, as
// (h, w, 4) float32 arrays with the CLI's --stats fields; linebake.compare(): PSNR and SSIM.

#include <mutex>
#include <optional>

#include "assets.hpp"
#include "bindings.hpp"
#include "cli_contract.hpp"
#include "core/error.hpp"
#include "core/memory_budget.hpp"
#include "flight_plan.hpp"
#include "metrics/image_metrics.hpp"
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

template <class T>
void set_from(const py::kwargs& kw, const char* name, T& target) {
  if (kw.contains(name)) target = kw[name].cast<T>();
}

TechniqueOptions technique_options(const py::kwargs& kw, int width, int height) {
  TechniqueOptions o;
  o.width = width, o.height = height;
  set_from(kw, "early_termination", o.early_termination);
  set_from(kw, "device", o.device);
  set_from(kw, "validation", o.validation);
  set_from(kw, "hits", o.hits);
  set_from(kw, "embree_geometry", o.geometry);
  set_from(kw, "embree_quality", o.quality);
  set_from(kw, "packets", o.packets);
  set_from(kw, "radius", o.radius);
  set_from(kw, "attribute", o.attribute);
  set_from(kw, "sort", o.sort);
  set_from(kw, "capacity", o.capacity);
  set_from(kw, "node_bytes", o.node_bytes);
  set_from(kw, "max_layers", o.max_layers);
  set_from(kw, "layers", o.layers);
  set_from(kw, "wboit_weight", o.wboit_weight);
  set_from(kw, "moments", o.moments);
  set_from(kw, "tau_alpha", o.tau_alpha);
  set_from(kw, "tau_opaque", o.tau_opaque);
  set_from(kw, "beta", o.beta);
  set_from(kw, "moment_bias", o.moment_bias);
  set_from(kw, "moment_basis", o.moment_basis);
  set_from(kw, "on", o.on);
  set_from(kw, "rtx_geometry", o.rt_geometry);
  set_from(kw, "tiles_geometry", o.tiles_geometry);
  set_from(kw, "tiles_sort", o.tiles_sort);
  set_from(kw, "tiles_strips", o.tiles_strips);
  set_from(kw, "rebuild", o.rebuild);
  set_from(kw, "max_iterations", o.max_iterations);
  // The CLI's negative flags.
  if (kw.contains("no_interlock")) o.interlock = !kw["no_interlock"].cast<bool>();
  if (kw.contains("no_early_termination"))
    o.vrc_early_termination = !kw["no_early_termination"].cast<bool>();
  if (kw.contains("no_skip")) o.skip_empty_space = !kw["no_skip"].cast<bool>();
  if (kw.contains("rtx_no_compaction")) o.compaction = !kw["rtx_no_compaction"].cast<bool>();
  // What the scene may take (embree, reference: the BVH) and tiles' bands: '40G', 'unlimited'.
  if (kw.contains("memory_budget") && !kw["memory_budget"].is_none())
    set_memory_budget(o, kw["memory_budget"].cast<std::string>());
  return o;
}

std::array<int, 2> size_from(const py::object& size) {
  if (py::isinstance<py::str>(size)) return cli::parse_size(size.cast<std::string>());
  const auto [w, h] = size.cast<std::pair<int, int>>();
  // The CLI's rule and message for --size.
  return cli::parse_size(std::to_string(w) + "x" + std::to_string(h));
}

Camera camera_from(const py::dict& d) {
  Camera c;
  const auto vec = [&](const char* key) {
    try {
      const auto xyz = d[key].cast<std::array<double, 3>>();
      return glm::dvec3(xyz[0], xyz[1], xyz[2]);
    } catch (const py::cast_error&) {
      throw py::type_error(std::string("camera: ") + key + ": expected three numbers, got " +
                           std::string(py::repr(d[key])));
    }
  };
  if (!d.contains("eye") || !d.contains("target"))
    throw py::value_error("camera: needs 'eye' and 'target' (and optionally 'up', 'fov')");
  c.eye = vec("eye");
  c.target = vec("target");
  if (d.contains("up")) c.up = vec("up");
  if (d.contains("fov")) {
    if (!py::isinstance<py::float_>(d["fov"]) && !py::isinstance<py::int_>(d["fov"]))
      throw py::type_error("camera: fov: expected a number, got " +
                           std::string(py::repr(d["fov"])));
    c.fov_y_degrees = d["fov"].cast<double>();
  }
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
  PyRenderer(const py::object& cache, const std::string& technique, const py::object& size,
             const py::kwargs& options)
      : name_(technique) {
    check_keywords("Renderer", options, kRenderKeywords);
    technique_ = &find_technique(technique);
    check_technique_options(technique_->info, option_names(options));
    cache_ = py::isinstance<PyCache>(cache) ? cache.cast<std::shared_ptr<PyCache>>()
                                            : std::make_shared<PyCache>(py::str(cache));
    const auto [width, height] = size_from(size);
    options_ = technique_options(options, width, height);
    if (options.contains("memory_budget") && !options["memory_budget"].is_none())
      memory_budget_ = options["memory_budget"].cast<std::string>();
    // The availability check of `linebake techniques`, with the cache's assets.
    if (auto reason = technique_unavailable(*technique_, options_, &cache_->reader()))
      throw Error(technique + ": cannot run here: " + *reason);
    const LongCall call;
    prepared_ = technique_->prepare(technique_->info, cache_->reader(), cache_->path(), options_);
  }

  py::tuple render(const std::string& tf_name, const py::object& camera, int frame, int frame_count,
                   const std::string& flight, const py::object& size,
                   const std::optional<std::string>& memory_budget) {
    const auto [width, height] =
        size.is_none() ? std::array{options_.width, options_.height} : size_from(size);
    if (frame < 0 || frame >= frame_count)
      throw UsageError("frame " + std::to_string(frame) + ": the flight has " +
                       std::to_string(frame_count) + " frames, 0 to " +
                       std::to_string(frame_count - 1) + " (frame_count)");
    TechniqueOptions sized = options_;
    sized.width = width, sized.height = height;
    cli::check_frame_memory(name_, std::to_string(width) + "x" + std::to_string(height),
                            estimate_frame_bytes(*technique_, sized),
                            memory_budget.value_or(memory_budget_));
    const TransferFunction tf = resolve_transfer_function(tf_name);
    Camera c;
    std::string flight_kind = "camera";
    if (!camera.is_none()) {
      c = camera_from(mapping_arg(camera, "camera"));
    } else {
      // The CLI's flight: the same cameras for the same bounds, size and frame count.
      const cli::FlightPlan plan =
          cli::plan_flight(flight, frame_count, frame, "", prepared_->bounds(), width, height);
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
    const Bounds b = prepared_->bounds();
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
  std::unique_ptr<PreparedTechnique> prepared_;
  std::mutex mutex_;
};

// An (h, w, 3 or 4) array (alpha dropped) or an image file, as the metrics read it.
Image image_from(const py::object& source, bool srgb_encoded) {
  if (py::isinstance<py::str>(source) || py::hasattr(source, "__fspath__")) {
    const std::string path = py::str(source);
    cli::check_input_file(path);
    return read_image(path);
  }
  const auto array = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(source);
  if (!array || array.ndim() != 3 || (array.shape(2) != 3 && array.shape(2) != 4))
    throw py::value_error("compare: expected an (h, w, 3) or (h, w, 4) image or a file name");
  Image image(int(array.shape(1)), int(array.shape(0)), 3);
  image.srgb_encoded = srgb_encoded;
  const size_t stride = size_t(array.shape(2));
  const float* in = array.data();
  for (size_t i = 0; i < size_t(image.width) * size_t(image.height); ++i)
    for (size_t c = 0; c < 3; ++c) image.pixels[3 * i + c] = in[stride * i + c];
  return image;
}

py::dict compare(const py::object& a, const py::object& b, bool srgb_encoded) {
  // Checked as given: the display encoding clamps an infinity to 0 or 1 (a NaN stays).
  const Image raw_first = image_from(a, srgb_encoded), raw_second = image_from(b, srgb_encoded);
  for (const auto& [image, which] :
       {std::pair(&raw_first, "image"), std::pair(&raw_second, "reference")})
    if (const std::string place = first_nonfinite_pixel(*image); !place.empty())
      throw py::value_error(std::string("compare: the ") + which + "'s " + place +
                            " is not a finite value (NaN or infinity): PSNR and SSIM need "
                            "finite values");
  const Image first = display_encoded(raw_first), second = display_encoded(raw_second);
  if (first.width != second.width || first.height != second.height)
    throw Error(std::to_string(first.width) + "x" + std::to_string(first.height) +
                ", but the reference is " + std::to_string(second.width) + "x" +
                std::to_string(second.height) + ": images of one size compare");
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

py::list technique_list(const std::string& device) {
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
linebake.UsageError, a technique this machine cannot run linebake.Error with the reason.
memory_budget ('40G', 'unlimited'; default half of physical memory): embree's and reference's
BVH is built within what it leaves, or refused with linebake.BudgetExceeded; render() checks
its frames against it unless given another.)doc")
      .def(py::init<const py::object&, const std::string&, const py::object&, const py::kwargs&>(),
           py::arg("cache"), py::arg("technique") = "embree",
           py::arg("size") = py::make_tuple(1280, 720))
      .def("render", &PyRenderer::render, py::arg("tf") = "semi", py::arg("camera") = py::none(),
           py::arg("frame") = 0, py::arg("frame_count") = 64, py::arg("flight") = "orbit-zoom",
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
      [](const py::object& cache, const std::string& technique, const std::string& tf,
         const py::object& size, int frame, int frame_count, const std::string& flight,
         const py::object& camera, const std::optional<std::string>& memory_budget,
         const py::kwargs& options) {
        // The budget bounds the scene (the Renderer's option) and checks the frame.
        auto all = py::reinterpret_steal<py::kwargs>(PyDict_Copy(options.ptr()));
        if (memory_budget) all["memory_budget"] = *memory_budget;
        PyRenderer renderer(cache, technique, size, all);
        return renderer.render(tf, camera, frame, frame_count, flight, py::none(), memory_budget);
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
for Renderer. Releases the GIL.)doc");
  module.def("compare", &compare, py::arg("image"), py::arg("reference"), py::kw_only(),
             py::arg("srgb_encoded") = false, R"doc(
PSNR (dB, capped at 60) and SSIM of an image against a reference, as `linebake compare`: both
display-encoded first. Each is an (h, w, 3|4) array (alpha ignored; linear values unless
srgb_encoded=True) or a .png/.pfm file. Returns {'psnr_db', 'ssim', 'ssim_mode'}.)doc");
  module.def("techniques", &technique_list, py::arg("device") = "",
             "Every technique: what it reads and needs, and whether it runs here (as `linebake "
             "techniques --json`).");
}

}  // namespace linebake::python
