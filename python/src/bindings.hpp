#pragma once
// What the binding files share: the Python-side line set, NumPy views that keep their owner
// alive, JSON as Python objects, and the registration function of each file.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <cstddef>
#include <exception>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <type_traits>
#include <typeinfo>
#include <vector>

#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/memory_budget.hpp"
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
// The library's notes (notify()) on a thread within a LongCall are linebake.Note warnings
// (bind_errors sets the handler); on other threads they are printed to stderr.
int& long_calls_on_this_thread();
class LongCall {
 public:
  LongCall() {
    if (syscall(SYS_gettid) == getpid() && python_handles_sigint()) interrupts_.emplace();
    unlocked_.emplace();
    ++long_calls_on_this_thread();
  }
  ~LongCall() {
    --long_calls_on_this_thread();
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
// Text of the library's (a message, a path) as Python's str, decoded as os.fsdecode decodes: UTF-8,
// and a byte that is not as the surrogate escape that stands for it, so a path that is not UTF-8
// reads back as the str os.listdir gives for it (os.fsencode gives its bytes back).
py::str fs_str(const std::string& text);

// repr(value) as UTF-8 (what a repr cannot encode as a backslash escape), for messages.
std::string repr_of(const py::handle& value);

// TypeError "`what`: expected `wanted`, got repr(value)".
[[noreturn]] void wrong_kind(const py::handle& value, const std::string& what, const char* wanted);

// A str, bytes or os.PathLike (pathlib.Path) argument as a path's bytes, as os.fsencode gives
// them (a str's surrogate escapes as the bytes they stand for), as the stub's StrPath says: a
// TypeError naming `what` for anything else, a ValueError for a NUL byte in it (the file system
// would end the name there) or a str os.fsencode cannot encode.
std::string path_arg(const py::handle& value, const std::string& what);

// Python's kinds, strictly: a bool (or numpy.bool_) is no number, a float no integer.
bool is_bool(const py::handle& value);
bool is_integer(const py::handle& value);  // int or NumPy integer, not bool
bool is_number(const py::handle& value);   // int, float or NumPy number, not bool

// A str as UTF-8 text; a TypeError naming `what` for anything else (bytes included) or for a str
// UTF-8 cannot encode (a lone surrogate).
std::string text_arg(const py::handle& value, const std::string& what);

// A list, tuple or other iterable of str (not a str itself, whose characters are no names) as
// names; a TypeError naming `what` for anything else.
std::vector<std::string> text_list(const py::handle& value, const std::string& what);

// A memory budget as the CLI's --memory-budget text: a str ("8G", "unlimited") as it is, an int
// (not bool) a number of bytes; a TypeError naming `what` for anything else, a UsageError naming
// it for a size the CLI refuses, 0 included unless `refuse_zero` is false (render()'s options,
// refused in the CLI's own words).
std::string budget_arg(const py::handle& value, const std::string& what, bool refuse_zero = true);
// The process's budget from a memory_budget argument (None: the CLI's default), named `what`.
MemoryBudget budget_of(const py::object& value, const std::string& what);

// An origin (lines/origin.hpp) as the CLI's --origin text: None "", a str ("auto", "x,y,z") as
// it is, three numbers (a tuple, list or NumPy array) as their exact text; a TypeError naming
// `what` for anything else.
std::string origin_arg(const py::handle& value, const std::string& what);

template <class T>
constexpr const char* wanted_kind() {
  if constexpr (std::is_same_v<T, bool>)
    return "True or False";
  else if constexpr (std::is_same_v<T, std::string>)
    return "a str";
  else if constexpr (std::is_floating_point_v<T>)
    return "a number";
  else if constexpr (std::is_unsigned_v<T>)
    return "a non-negative integer in range";
  else
    return "an integer in range";
}

// `value` as T, of T's kind only (is_bool, is_integer, is_number, text_arg): a TypeError naming
// `what` and the kind otherwise, or when the value does not fit T.
template <class T>
T typed_arg(const py::handle& value, const std::string& what) {
  if constexpr (std::is_same_v<T, std::string>) {
    return text_arg(value, what);
  } else if constexpr (std::is_same_v<T, bool>) {
    py::detail::make_caster<bool> caster;
    if (!caster.load(value, false)) wrong_kind(value, what, wanted_kind<T>());
    return py::detail::cast_op<bool>(caster);
  } else if constexpr (std::is_integral_v<T>) {
    if (!is_integer(value)) wrong_kind(value, what, wanted_kind<T>());
    // As a Python int: pybind11's unsigned casters take no NumPy integer.
    const auto index = py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()));
    py::detail::make_caster<T> caster;
    if (!index || !caster.load(index, false)) {
      PyErr_Clear();
      wrong_kind(value, what, wanted_kind<T>());
    }
    return py::detail::cast_op<T>(caster);
  } else {
    static_assert(std::is_floating_point_v<T>);
    if (!is_number(value)) wrong_kind(value, what, wanted_kind<T>());
    const double number = PyFloat_AsDouble(value.ptr());
    if (number == -1 && PyErr_Occurred()) {
      PyErr_Clear();
      wrong_kind(value, what, wanted_kind<T>());
    }
    if (std::isfinite(number) && !std::isfinite(T(number)))
      wrong_kind(value, what, "a number in range");
    return T(number);
  }
}

// Keyword argument `name` of `function`'s **options as T (typed_arg), if given.
template <class T>
std::optional<T> keyword(const std::string& function, const py::kwargs& options, const char* name) {
  if (!options.contains(name)) return std::nullopt;
  return typed_arg<T>(options[name], function + ": " + name);
}

// `value` as NumPy converts an array-like (numpy.asarray), for an argument of numbers: a
// TypeError naming `what` for what is none (NumPy's own TypeError or ValueError, as for a
// ragged list; an array of text, dates, complex numbers or records, which NumPy would convert
// with a warning at most), and a ValueError for a masked array holding masked values (the
// values under the mask would be read), and a TypeError naming the place of a None in an object
// array where `kinds` takes them (NumPy's cast makes it NaN). Anything else the conversion raises
// (MemoryError; an OSError or KeyboardInterrupt from a lazy array's __array__) is raised as it is:
// py::array::ensure had put every failure down to the argument's kind. `kinds`: the NumPy kinds
// taken, nullptr for any (the caller checks them itself).
py::array number_array(const py::handle& value, const std::string& what, const char* wanted,
                       const char* kinds = "biufO");

// `array` (of number_array) as C-order T, a copy unless it is one already: NumPy's TypeError or
// ValueError (an object array holding something else) as number_array says them, anything else
// as it is.
template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> c_array(const py::array& array,
                                                                  const std::string& what,
                                                                  const char* wanted) {
  try {
    return py::array_t<T, py::array::c_style | py::array::forcecast>(array);
  } catch (py::error_already_set& e) {
    // An int past float's range in an object array ([10**400, 0, 0]): the value is wrong.
    if (e.matches(PyExc_OverflowError))
      throw py::value_error(what + ": expected " + wanted + " (" + e.what() + ")");
    if (!e.matches(PyExc_TypeError) && !e.matches(PyExc_ValueError)) throw;
    throw py::type_error(what + ": expected " + wanted + " (" + e.what() + ")");
  }
}

// The first finite value of an array of floats wider than float32 that float32 cannot hold
// (NumPy's cast makes it an infinity with no more than a RuntimeWarning), among the first `used`
// of each `stride` values in C order (an image's colour, not its alpha): its index and its text
// as Python's repr writes it. Nothing for any other array. Reads a C-order float64 array in
// place; another is copied as float64 first (wide_copy_bytes).
std::optional<std::pair<size_t, std::string>> beyond_float32(const py::array& given,
                                                             const std::string& what,
                                                             const char* wanted, size_t stride = 1,
                                                             size_t used = 1);
uint64_t wide_copy_bytes(const py::array& given);
// What beyond_float32 found, said after its place.
inline std::string beyond_float32_text(const std::string& value) {
  return value + " is outside float32's range (magnitude above 3.4028235e38)";
}

// Any mapping (a dict, types.MappingProxyType, ...) or iterable of pairs as a dict, as the stub's
// Mapping says (a TypeError naming `what` otherwise).
inline py::dict mapping_arg(const py::handle& value, const char* what) {
  if (py::isinstance<py::dict>(value)) return py::reinterpret_borrow<py::dict>(value);
  try {
    return py::dict(py::reinterpret_borrow<py::object>(value));
  } catch (const py::error_already_set&) {
    throw py::type_error(std::string(what) + ": expected a mapping, got " + repr_of(value));
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
  // Empty: nothing to view, but read-only as every view is.
  py::array array = data ? py::array(py::dtype::of<T>(), shape, {}, data, base)
                         : py::array(py::dtype::of<T>(), shape);
  array.attr("setflags")(py::arg("write") = false);
  return array;
}

// f(), with a plain Error (parse_invalid_policy's, parse_compression's: a value none of the
// names) raised as UsageError, as every bad value given is.
template <class F>
auto as_usage_error(F f) -> decltype(f()) {
  try {
    return f();
  } catch (const Error& e) {
    if (typeid(e) != typeid(Error)) throw;
    throw UsageError(e.what());
  }
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
