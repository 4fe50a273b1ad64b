#pragma once
// What the binding files share: the Python-side line set, NumPy views that keep their owner
// alive, JSON as Python objects, and the registration function of each file.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <csignal>
#include <cstddef>
#include <exception>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/interrupt.hpp"
#include "lines/line_set.hpp"

namespace linebake::python {

namespace py = pybind11;

// A line set as Python holds it: the arrays, and where they came from (info() names them as
// `linebake info --json` does). Python never resizes the arrays, so views of them stay valid
// for as long as the object lives.
struct PyLineSet {
  LineSet lines;
  std::string source;  // the path or synth: source it was read from; "" when made from arrays
  std::string format;  // that source's format name
};

// A call into the library that may take long: the GIL released and, on the main thread (where
// Python's signals go) while Python's own SIGINT handler is in place, Ctrl-C stopping the work
// at its next check (Interrupted, raised as KeyboardInterrupt, the temporaries removed) instead
// of when the call returns, if no other thread's call is in flight (it would see it too). A
// Ctrl-C the work did not act on is handed back to Python as the call returns. A handler of the
// user's, or SIGINT ignored, is left as it is.
class LongCall {
 public:
  LongCall() {
    if (syscall(SYS_gettid) == getpid() && python_handles_sigint()) interrupts_.emplace();
    unlocked_.emplace();
  }
  ~LongCall() {
    unlocked_.reset();                                           // the GIL again
    const int signal = interrupts_ ? interrupts_->finish() : 0;  // Python's handler back first
    if (signal != 0 && std::uncaught_exceptions() == 0) PyErr_SetInterrupt();
  }
  LongCall(const LongCall&) = delete;
  LongCall& operator=(const LongCall&) = delete;

 private:
  // Whether SIGINT is Python's default handling (KeyboardInterrupt), with the GIL.
  static bool python_handles_sigint() {
    const py::module_ signal = py::module_::import("signal");
    return signal.attr("getsignal")(int(SIGINT)).is(signal.attr("default_int_handler"));
  }

  EmbeddedCall call_;
  std::optional<InterruptScope> interrupts_;
  std::optional<py::gil_scoped_release> unlocked_;
};
// A str, bytes or os.PathLike (pathlib.Path) argument as a path string, as the stub's StrPath
// says (a TypeError naming `what` otherwise).
inline std::string path_arg(const py::handle& value, const char* what) {
  try {
    const py::object path = py::module_::import("os").attr("fspath")(value);
    return path.cast<std::string>();  // str, or bytes as they are
  } catch (const py::error_already_set&) {
    throw py::type_error(std::string(what) + ": expected a str or os.PathLike, got " +
                         std::string(py::repr(value)));
  }
}

// Any mapping (a dict, types.MappingProxyType, ...) or iterable of pairs as a dict, as the stub's
// Mapping says (a TypeError naming `what` otherwise).
inline py::dict mapping_arg(const py::handle& value, const char* what) {
  if (py::isinstance<py::dict>(value)) return py::reinterpret_borrow<py::dict>(value);
  try {
    return py::dict(py::reinterpret_borrow<py::object>(value));
  } catch (const py::error_already_set&) {
    throw py::type_error(std::string(what) + ": expected a mapping, got " +
                         std::string(py::repr(value)));
  }
}

// nlohmann::json -> dict, list, str, int, float, bool or None.
py::object to_python(const nlohmann::json& value);

// A capsule that holds `owner` for as long as a view of its memory lives.
py::object keep_alive(std::shared_ptr<const void> owner);

// A read-only NumPy view (no copy) of `rows` rows of `shape_tail` values each of T at `data`;
// `base` keeps the memory alive. An empty `shape_tail` makes a 1-D array.
template <class T>
py::array view(const T* data, size_t rows, const std::vector<size_t>& shape_tail, py::handle base) {
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(rows)};
  for (size_t n : shape_tail) shape.push_back(static_cast<py::ssize_t>(n));
  if (!data) return py::array(py::dtype::of<T>(), shape);  // empty: nothing to view
  py::array array(py::dtype::of<T>(), shape, {}, data, base);
  array.attr("setflags")(py::arg("write") = false);
  return array;
}

// The Python name of a keyword argument as the CLI spells its option: "tube_sides" ->
// "tube-sides".
std::string option_name(const std::string& keyword);
// The keyword arguments' names, as option names.
std::vector<std::string> option_names(const py::kwargs& options);
// TypeError for a keyword none of `known` is, with the nearest ("did you mean").
void check_keywords(const char* function, const py::kwargs& options,
                    const std::vector<std::string>& known);

void bind_errors(py::module_& module);
void bind_line_sets(py::module_& module);
void bind_assets(py::module_& module);
void bind_rendering(py::module_& module);

}  // namespace linebake::python
