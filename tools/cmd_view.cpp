// linebake view <cache>: a window (GLFW + a Vulkan swapchain) showing one technique at a time
// over the cached assets. Orbit with the left mouse button, zoom with the wheel; keys switch the
// technique and the transfer function, take screenshots and compare the view with the ground
// truth. --script drives it without a user (tests, recorded demos).

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include "cache/cache.hpp"
#include "cli_contract.hpp"
#include "commands.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/nearest.hpp"
#include "flight_plan.hpp"
#include "metrics/image_metrics.hpp"
#include "pipeline/report.hpp"
#include "render/overlay_text.hpp"
#include "render/vulkan/presenter.hpp"
#include "techniques/technique.hpp"
#include "view_sources.hpp"

namespace linebake::cli {
namespace {

struct ScriptLine {
  int line = 0;
  std::string command;
  std::vector<std::string> args;
};

// One command per line; '#' starts a comment. See docs/viewer.md.
std::vector<ScriptLine> read_script(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "", "cannot open the script");
  static const std::map<std::string, size_t> arity{
      {"technique", 1}, {"tf", 1},   {"frame", 1},      {"orbit", 2},   {"zoom", 1}, {"key", 1},
      {"wait", 1},      {"hold", 1}, {"screenshot", 1}, {"compare", 0}, {"quit", 0}, {"size", 2}};
  std::vector<ScriptLine> script;
  std::string text;
  for (int number = 1; std::getline(in, text); ++number) {
    if (const size_t hash = text.find('#'); hash != std::string::npos) text.resize(hash);
    std::istringstream words(text);
    ScriptLine line{number, "", {}};
    if (!(words >> line.command)) continue;
    for (std::string w; words >> w;) line.args.push_back(w);
    const auto known = arity.find(line.command);
    if (known == arity.end())
      throw InputError(path, "line " + std::to_string(number),
                       "unknown command '" + line.command + "'");
    if (line.args.size() != known->second)
      throw InputError(
          path, "line " + std::to_string(number),
          "'" + line.command + "' takes " + std::to_string(known->second) + " argument(s)");
    script.push_back(line);
  }
  return script;
}

double number_arg(const std::string& path, const ScriptLine& line, size_t i) {
  try {
    size_t used = 0;
    const double v = std::stod(line.args[i], &used);
    if (used == line.args[i].size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  throw InputError(path, "line " + std::to_string(line.line),
                   "'" + line.args[i] + "' is not a number");
}

// 8-bit display values, as a PNG written and read back: the viewer's comparison then gives the
// numbers `linebake compare` gives for the same two images.
Image as_png_values(const Image& image) {
  Image out = display_encoded(image);
  for (float& v : out.pixels) v = std::round(v * 255.0f) / 255.0f;
  return out;
}

class Viewer {
 public:
  struct Options {
    std::string cache, technique = "ll", tf = "semi", device, script, flight = "orbit-zoom";
    std::string memory_budget;  // --memory-budget, for every technique and frame
    int width = 1280, height = 720, frame_count = 64;
    bool validation = false;
  };

  explicit Viewer(const Options& options) : options_(options), cache_(options.cache) {
    if (!glfwInit())
      throw Error("view: cannot open a window (no display? set DISPLAY, or run under xvfb-run)");
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    window_ = glfwCreateWindow(options.width, options.height, "linebake view", nullptr, nullptr);
    if (!window_) {
      glfwTerminate();
      throw Error("view: GLFW could not create a window");
    }
    try {
      vk::ContextOptions context_options;
      context_options.device = options.device;
      context_options.validation = options.validation;
      context_options.swapchain = true;
      // Ray tracing too where the device has it, so rtx can be viewed.
      TechniqueOptions rtx;
      rtx.device = options.device;
      context_options.ray_tracing = !technique_unavailable(find_technique("rtx"), rtx);
      uint32_t count = 0;
      const char** names = glfwGetRequiredInstanceExtensions(&count);
      if (!names) throw Error("view: GLFW found no Vulkan window support on this display");
      for (uint32_t i = 0; i < count; ++i) context_options.instance_extensions.push_back(names[i]);
      try {
        context_.emplace(context_options);
      } catch (const vk::RayTracingUnsupported&) {  // the extensions, but a feature is off
        context_options.ray_tracing = false;
        context_.emplace(context_options);
      }
      VkSurfaceKHR surface = VK_NULL_HANDLE;
      vk::check(glfwCreateWindowSurface(context_->instance(), window_, nullptr, &surface),
                "glfwCreateWindowSurface");
      presenter_.emplace(*context_, surface);
    } catch (...) {
      close();
      throw;
    }
    glfwSetWindowUserPointer(window_, this);
    glfwSetKeyCallback(window_, [](GLFWwindow* w, int key, int, int action, int) {
      if (action == GLFW_PRESS) static_cast<Viewer*>(glfwGetWindowUserPointer(w))->on_key(key);
    });
    glfwSetScrollCallback(window_, [](GLFWwindow* w, double, double dy) {
      static_cast<Viewer*>(glfwGetWindowUserPointer(w))->zoom(std::pow(0.9, dy));
    });
    tf_ = options.tf;
    width_ = options.width, height_ = options.height;
    switch_technique(options.technique);
    if (!source_) throw Error("view: " + status_);
    set_flight_frame(0);
  }
  ~Viewer() { close(); }

  int run() {
    std::vector<ScriptLine> script;
    if (!options_.script.empty()) script = read_script(options_.script);
    size_t next = 0;
    int wait_frames = 0;
    double last_x = 0, last_y = 0;
    bool dragging = false;
    // Ctrl-C in the terminal closes the window too (the command then ends as interrupted).
    while (!quit_ && !glfwWindowShouldClose(window_) && interrupt_signal() == 0) {
      glfwPollEvents();
      // Mouse orbit: 0.3 degrees per pixel dragged.
      double x, y;
      glfwGetCursorPos(window_, &x, &y);
      const bool down = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
      if (down && dragging) orbit(0.3 * (x - last_x), 0.3 * (y - last_y));
      dragging = down, last_x = x, last_y = y;
      if (!options_.script.empty() && wait_frames == 0) {
        if (next == script.size()) break;  // a script ends the session
        execute(script[next++], wait_frames);
        if (quit_) break;
      }
      draw();
      if (wait_frames > 0) --wait_frames;
    }
    return 0;
  }

 private:
  void close() {
    presenter_.reset();
    source_.reset();
    reference_.reset();
    context_.reset();
    if (window_) glfwDestroyWindow(window_);
    window_ = nullptr;
    glfwTerminate();
  }

  Camera camera() const {
    if (flight_camera_) return *flight_camera_;
    return frame_bounds(source_->bounds(), double(width_) / height_, azimuth_, elevation_,
                        distance_);
  }

  // The flight's camera for `frame`, planned at the window's aspect (as render --size WxH).
  void set_flight_frame(int frame) {
    const FlightPlan plan = plan_flight(options_.flight, options_.frame_count, frame, "",
                                        source_->bounds(), width_, height_);
    flight_camera_ = plan.cameras.at(size_t(frame));
    flight_frame_ = frame;
  }

  void orbit(double degrees_x, double degrees_y) {
    if (degrees_x == 0 && degrees_y == 0) return;
    flight_camera_.reset();
    azimuth_ += degrees_x;
    elevation_ = std::clamp(elevation_ + degrees_y, -89.0, 89.0);
  }
  void zoom(double factor) {
    flight_camera_.reset();
    distance_ = std::clamp(distance_ * factor, 0.05, 20.0);
  }

  // Prepares `name` while the shown technique stays, so that one that cannot be prepared (a
  // missing asset, a device feature, the memory budget with the shown one held) leaves the view
  // as it was. (Letting the shown one go first does not make room reliably: on lavapipe the
  // process stays resident well above what the freed technique held, in LLVM's compiled shaders
  // and the heap, so the shown one could then not come back either.)
  void switch_technique(const std::string& name) {
    tried_ = name;
    try {
      prepare_source(name);
      status_.clear();
    } catch (const Error& e) {
      status_ = name + ": " + e.what();  // shown on screen; the last source stays
      std::cerr << "view: " << status_ << "\n";
    }
  }

  void prepare_source(const std::string& name) {
    source_ = make_view_source(name, cache_, *context_, width_, height_, options_.memory_budget);
    fitted_.reset();
    technique_ = name;
    if (flight_camera_) set_flight_frame(flight_frame_);
  }

  // The technique after the one last tried (a refused one too, so that T walks the list).
  void next_technique() {
    const auto& names = view_techniques();
    auto it = std::find(names.begin(), names.end(), tried_.empty() ? technique_ : tried_);
    const size_t i = it == names.end() ? 0 : size_t(it - names.begin());
    const std::string& next = names[(i + 1) % names.size()];
    if (next == technique_) {  // round the list past the refused ones: the one shown stays
      tried_ = next;
      status_.clear();
      return;
    }
    switch_technique(next);
  }

  void next_tf() {
    static const std::vector<std::string> presets{"opaque", "semi", "transparent"};
    auto it = std::find(presets.begin(), presets.end(), tf_);
    tf_ = presets[it == presets.end() ? 0 : size_t(it - presets.begin() + 1) % presets.size()];
  }

  void on_key(int key) {
    switch (key) {
      case GLFW_KEY_T:
        next_technique();
        break;
      case GLFW_KEY_F:
        next_tf();
        break;
      case GLFW_KEY_S:
        screenshot("");
        break;
      case GLFW_KEY_C:
        compare();
        break;
      case GLFW_KEY_R:
        set_flight_frame(0);
        break;
      case GLFW_KEY_RIGHT:
        set_flight_frame((flight_frame_ + 1) % options_.frame_count);
        break;
      case GLFW_KEY_LEFT:
        set_flight_frame((flight_frame_ + options_.frame_count - 1) % options_.frame_count);
        break;
      case GLFW_KEY_Q:
      case GLFW_KEY_ESCAPE:
        quit_ = true;
        break;
      default:
        break;
    }
  }

  void execute(const ScriptLine& line, int& wait_frames) {
    const std::string& path = options_.script;
    const std::string& c = line.command;
    if (c == "technique") {
      switch_technique(line.args[0]);
      if (!status_.empty()) throw InputError(path, "line " + std::to_string(line.line), status_);
    } else if (c == "tf") {
      resolve_transfer_function(line.args[0]);  // throws on a bad name
      tf_ = line.args[0];
    } else if (c == "frame") {
      const double f = number_arg(path, line, 0);
      if (f < 0 || f >= options_.frame_count || f != std::floor(f))
        throw InputError(path, "line " + std::to_string(line.line),
                         "frame must be 0.." + std::to_string(options_.frame_count - 1));
      set_flight_frame(int(f));
    } else if (c == "orbit") {
      orbit(number_arg(path, line, 0), number_arg(path, line, 1));
    } else if (c == "zoom") {
      zoom(number_arg(path, line, 0));
    } else if (c == "key") {
      static const std::map<std::string, int> keys{
          {"t", GLFW_KEY_T},         {"f", GLFW_KEY_F},       {"s", GLFW_KEY_S},
          {"c", GLFW_KEY_C},         {"r", GLFW_KEY_R},       {"q", GLFW_KEY_Q},
          {"right", GLFW_KEY_RIGHT}, {"left", GLFW_KEY_LEFT}, {"escape", GLFW_KEY_ESCAPE}};
      const auto key = keys.find(line.args[0]);
      if (key == keys.end())
        throw InputError(path, "line " + std::to_string(line.line),
                         "unknown key '" + line.args[0] + "' (t f s c r q left right escape)");
      on_key(key->second);
    } else if (c == "size") {
      const double w = number_arg(path, line, 0), h = number_arg(path, line, 1);
      if (w < 1 || h < 1 || w > 16384 || h > 16384 || w != std::floor(w) || h != std::floor(h))
        throw InputError(path, "line " + std::to_string(line.line),
                         "size takes a width and a height of 1..16384 pixels");
      resize_window(int(w), int(h));
    } else if (c == "wait") {
      wait_frames = int(std::max(0.0, number_arg(path, line, 0)));
    } else if (c == "hold") {
      // Keep the last frame on screen (for a screen grab) without rendering.
      const auto until = std::chrono::steady_clock::now() +
                         std::chrono::duration<double>(number_arg(path, line, 0));
      while (std::chrono::steady_clock::now() < until) {
        glfwPollEvents();
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    } else if (c == "screenshot") {
      screenshot(line.args[0]);
    } else if (c == "compare") {
      compare();
    } else if (c == "quit") {
      quit_ = true;
    }
  }

  // Sets the window's size and waits (up to 2 s) for the window system to apply it.
  void resize_window(int width, int height) {
    glfwSetWindowSize(window_, width, height);
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    int w = 0, h = 0;
    do {
      glfwPollEvents();
      glfwGetWindowSize(window_, &w, &h);
      if (w == width && h == height) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    } while (std::chrono::steady_clock::now() < until);
    std::cerr << "view: the window is " << w << "x" << h << ", not " << width << "x" << height
              << "\n";
  }

  // A refusal goes to standard error once per technique, size and kind, not once per frame (an
  // allocation's figures change from frame to frame); "" clears it.
  void report_refusal(const std::string& key, const std::string& message) {
    if (key == refused_key_) return;
    refused_key_ = key;
    if (!message.empty()) std::cerr << "view: refused: " << message << "\n";
  }

  void draw() {
    int w = 0, h = 0;
    glfwGetFramebufferSize(window_, &w, &h);
    if (w <= 0 || h <= 0) return;
    if (w != width_ || h != height_) {
      width_ = w, height_ = h;
      if (flight_camera_) set_flight_frame(flight_frame_);  // the same frame at the new aspect
    }
    const std::string size = std::to_string(width_) + "x" + std::to_string(height_);
    const TransferFunction tf = resolve_transfer_function(tf_);
    // A frame past the memory budget (a window grown past what it allows, a view whose lists
    // outgrow it) is refused with the figures on the status line; the viewer goes on, and each
    // frame tries again, so it draws once the window, the view or the technique lets it.
    std::string refused;
    try {
      if (fitted_ != std::pair{width_, height_}) {
        source_->fit_frame(width_, height_);
        fitted_ = std::pair{width_, height_};
      }
      frame_ = source_->render(camera(), tf, width_, height_);
    } catch (const BudgetExceeded& e) {
      refused = technique_ + " at " + size + ": " + e.what();
      frame_ = ViewFrame{};
    }
    if (!refused.empty()) report_refusal(technique_ + " " + size, refused);
    refused_ = refused;
    Image shown = refused.empty() ? frame_.image : Image(width_, height_);
    char line[256];
    if (refused.empty())
      std::snprintf(line, sizeof line, "%s | %s | %.1f ms | %s per frame%s%s", technique_.c_str(),
                    tf_.c_str(), frame_.seconds * 1e3, format_bytes(frame_.frame_bytes).c_str(),
                    comparison_.empty() ? "" : " | ", comparison_.c_str());
    else
      std::snprintf(line, sizeof line, "%s | %s | refused: past the memory budget",
                    technique_.c_str(), tf_.c_str());
    const int scale = height_ >= 400 ? 2 : 1;
    draw_status_line(shown, line, 0, scale);
    // At the bottom: the refusal, and above it the last error (a technique that could not be
    // switched to, a comparison that could not be made).
    int bottom = height_ - 9 * scale;
    if (!refused.empty()) {
      draw_status_line(shown, refused, bottom, scale);
      bottom -= 9 * scale;
    }
    if (!status_.empty()) draw_status_line(shown, status_, bottom, scale);
    try {
      // The window's copy (the presenter's staging buffer) of a frame the technique was allowed
      // is part of the frame's reserve (frame_output_bytes): refusing it would leave a rendered
      // frame unshown. A refused frame's blank window is held to the budget.
      std::optional<vk::Context::ReservedAllocations> reserved;
      if (refused.empty()) reserved.emplace(*context_);
      presenter_->present(shown, width_, height_);
    } catch (const BudgetExceeded& e) {  // its staging buffer, on a context held to the budget
      report_refusal("present " + size, "presenting a " + size + " window: " + e.what());
      return;
    }
    if (refused.empty()) report_refusal("", "");  // drawn: a later refusal is news again
    if (context_->validation_errors() > 0)
      throw Error("Vulkan validation: " + std::to_string(context_->validation_errors()) +
                  " error(s); last: " + context_->last_validation_error());
    if (!options_.script.empty() && refused.empty())  // a log for scripts, not a flood at 60 Hz
      std::cout << "frame: " << technique_ << " " << tf_ << " " << size << " " << frame_.seconds
                << " s " << frame_.frame_bytes << " bytes\n";
  }

  // The last frame as the technique drew it (no status line), as `render` would write it.
  void screenshot(std::string path) {
    if (frame_.image.pixels.empty()) {
      std::cerr << "view: no screenshot: "
                << (refused_.empty() ? "no frame drawn yet" : "the frame was refused") << "\n";
      return;
    }
    if (path.empty()) {
      char name[64];
      std::snprintf(name, sizeof name, "linebake-view-%03d.png", screenshots_++);
      path = name;
    }
    write_png(frame_.image, path);
    std::cout << "screenshot: " << path << "\n";
  }

  // PSNR / SSIM of the last frame against the ground truth (the reference) from the same camera.
  void compare() {
    if (frame_.image.pixels.empty()) return;
    const TransferFunction tf = resolve_transfer_function(tf_);
    ViewFrame truth;
    try {
      if (!reference_)
        reference_ = make_view_source("reference", cache_, *context_, width_, height_,
                                      options_.memory_budget);
      reference_->fit_frame(width_, height_);
      truth = reference_->render(camera(), tf, width_, height_);
    } catch (const Error& e) {  // shown on screen, as a technique that cannot be switched to
      status_ = std::string("compare: ") + e.what();
      std::cerr << "view: " << status_ << "\n";
      return;
    }
    const Image a = as_png_values(frame_.image), b = as_png_values(truth.image);
    char text[128];
    std::snprintf(text, sizeof text, "PSNR %.2f dB SSIM %.4f", psnr(a, b), ssim(a, b));
    comparison_ = text;
    std::cout << "compare: " << technique_ << " " << tf_ << " " << comparison_ << "\n";
  }

  Options options_;
  CacheReader cache_;
  GLFWwindow* window_ = nullptr;
  std::optional<vk::Context> context_;
  std::optional<vk::Presenter> presenter_;
  std::unique_ptr<ViewSource> source_, reference_;
  std::string technique_, tf_, status_, comparison_;
  std::string refused_;                        // why the last frame was refused ("": it was drawn)
  std::string refused_key_;                    // the refusal last reported (report_refusal)
  std::string tried_;                          // the technique last switched to, or tried
  std::optional<std::pair<int, int>> fitted_;  // the size source_ was fitted to (fit_frame)
  std::optional<Camera> flight_camera_;
  int flight_frame_ = 0, width_ = 0, height_ = 0, screenshots_ = 0;
  double azimuth_ = 0, elevation_ = 20, distance_ = 1;
  ViewFrame frame_;
  bool quit_ = false;
};

}  // namespace

Command add_view(CLI::App& app) {
  auto* sub = app.add_subcommand("view", "Show a cache in a window, one technique at a time");
  auto options = std::make_shared<Viewer::Options>();
  auto size_text = std::make_shared<std::string>("1280x720");
  sub->add_option("cache", options->cache, "Asset cache (.lbc.h5)")->required();
  sub->add_option("--technique", options->technique,
                  "First technique (default ll); T cycles: reference embree opaque dp ll mlab "
                  "mlabdb mboit wboit vrc vrc-gpu rtx tiles (rtx where the device ray traces; "
                  "elsewhere the status line says why not); vrc-gpu is vrc --on gpu");
  auto on = std::make_shared<std::string>();
  sub->add_option("--on", *on, "vrc: cpu (default) | gpu (Vulkan compute), as for render")
      ->check(one_of({"cpu", "gpu"}));
  sub->add_option("--tf", options->tf, "First transfer function (default semi); F cycles presets");
  sub->add_option("--size", *size_text, "Window size WxH (default 1280x720)");
  sub->add_option("--flight", options->flight,
                  "Flight whose frames the arrow keys and 'frame N' step through (orbit-zoom)");
  sub->add_option("--frame-count", options->frame_count, "Frames in that flight (default 64)")
      ->check(CLI::Range(1, 100000));
  sub->add_option("--device", options->device, "Vulkan device: part of its name");
  sub->add_flag("--validation", options->validation,
                "Vulkan: enable the Khronos validation layer; validation errors end the session");
  sub->add_option("--memory-budget", options->memory_budget,
                  "As render's, for every technique: a frame past it is not drawn and the status "
                  "line says why (default: half of physical memory, or of the cgroup's or ulimit "
                  "-v's limit when less); unlimited")
      ->check(memory_budget_size());
  sub->add_option("--script", options->script,
                  "Commands to run, one per frame (docs/viewer.md); the session ends after the "
                  "last");
  sub->get_option("--size")->check(image_size_check());
  check_when_parsed(sub, [sub, options, on] {
    const auto& names = view_techniques();
    if (std::find(names.begin(), names.end(), options->technique) == names.end()) {
      throw UsageError("--technique: unknown technique '" + options->technique + "' (" +
                       name_list(names) + ")" + did_you_mean(options->technique, names));
    }
    refuse_unless(sub, {"on"}, options->technique == "vrc", "with --technique vrc");
    if (*on == "gpu") options->technique = "vrc-gpu";
  });
  return [options, size_text] {
    check_cache_input(options->cache);
    if (!options->script.empty()) check_input_file(options->script);
    const auto [w, h] = parse_image_size(*size_text);
    options->width = w, options->height = h;
    Viewer viewer(*options);
    viewer.run();
  };
}

}  // namespace linebake::cli
