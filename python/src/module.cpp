// The `linebake` Python module: line sets from and to NumPy, every format, bakes, caches,
// renders and image metrics, through the same library calls as the CLI (issue 24).

#include <charconv>
#include <cstring>
#include <string_view>

#include "bindings.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/memory_budget.hpp"
#include "lines/origin.hpp"
#include "whole_output.hpp"

namespace linebake::python {

py::str fs_str(const std::string& text) {
  PyObject* decoded = PyUnicode_DecodeFSDefaultAndSize(text.data(), py::ssize_t(text.size()));
  if (!decoded) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(decoded);
}

std::string repr_of(const py::handle& value) {
  const py::str repr = py::repr(value);
  PyObject* bytes = PyUnicode_AsEncodedString(repr.ptr(), "utf-8", "backslashreplace");
  if (!bytes) throw py::error_already_set();
  return py::reinterpret_steal<py::bytes>(bytes);
}

void wrong_kind(const py::handle& value, const std::string& what, const char* wanted) {
  throw py::type_error(what + ": expected " + wanted + ", got " + repr_of(value));
}

std::string path_arg(const py::handle& value, const std::string& what) {
  py::object encoded;
  try {
    encoded = py::module_::import("os").attr("fsencode")(value);
  } catch (py::error_already_set& e) {
    if (e.matches(PyExc_TypeError)) wrong_kind(value, what, "a str, bytes or os.PathLike");
    if (e.matches(PyExc_UnicodeError))  // a lone surrogate no byte stands for
      throw py::value_error(what + ": " + std::string(py::str(e.value())));
    throw;
  }
  std::string path = encoded.cast<std::string>();
  // As open() and os.stat() refuse it: the C library would end the name at the NUL.
  if (path.find('\0') != std::string::npos)
    throw py::value_error(what + ": embedded null byte in " + repr_of(value));
  return path;
}

bool is_bool(const py::handle& value) {
  if (PyBool_Check(value.ptr())) return true;
  const std::string type = Py_TYPE(value.ptr())->tp_name;
  return type == "numpy.bool_" || type == "numpy.bool";
}

bool is_integer(const py::handle& value) {
  return !is_bool(value) && (PyLong_Check(value.ptr()) || PyIndex_Check(value.ptr()));
}

bool is_number(const py::handle& value) {
  if (is_bool(value)) return false;
  if (PyLong_Check(value.ptr()) || PyFloat_Check(value.ptr()) || PyIndex_Check(value.ptr()))
    return true;
  return py::isinstance(value, py::module_::import("numpy").attr("floating"));
}

std::string text_arg(const py::handle& value, const std::string& what) {
  if (!PyUnicode_Check(value.ptr())) wrong_kind(value, what, "a str");
  py::ssize_t size = 0;
  const char* data = PyUnicode_AsUTF8AndSize(value.ptr(), &size);
  if (!data) {
    PyErr_Clear();
    wrong_kind(value, what, "a str that UTF-8 can encode (no lone surrogates)");
  }
  // The C library would end the text at a NUL: an attribute name had been written cut short
  // to HDF5 and as U+FFFD to VTP, a provenance step read as the one before it.
  if (std::memchr(data, 0, size_t(size)) != nullptr)
    throw py::value_error(what + ": embedded null byte in " + repr_of(value));
  return std::string(data, size_t(size));
}

py::array number_array(const py::handle& value, const std::string& what, const char* wanted,
                       const char* kinds) {
  const py::module_ masked = py::module_::import("numpy.ma");
  if (py::isinstance(value, masked.attr("MaskedArray")) &&
      masked.attr("is_masked")(value).cast<bool>())
    throw py::value_error(what +
                          ": a masked array with masked values, whose values under the "
                          "mask would be read; fill them first (a.filled(numpy.nan))");
  // A list that mixes booleans with numbers becomes an integer array to NumPy ([[True, 0, 1]]:
  // positions 1, 0, 1): where booleans are refused, a nested list's bool is named instead.
  if (kinds && std::string_view(kinds).find('b') == std::string_view::npos &&
      (PyList_Check(value.ptr()) || PyTuple_Check(value.ptr()))) {
    const py::sequence rows = py::reinterpret_borrow<py::sequence>(value);
    for (size_t r = 0; r < rows.size(); ++r) {
      const py::handle row = rows[r];
      const auto bool_at = [&](const py::handle& item, const std::string& place) {
        throw py::type_error(what + ": expected " + wanted + ", got " + repr_of(item) + " at " +
                             place + "; booleans are no numbers here");
      };
      if (is_bool(row)) bool_at(row, "item " + std::to_string(r));
      if (!PyList_Check(row.ptr()) && !PyTuple_Check(row.ptr())) continue;
      const py::sequence items = py::reinterpret_borrow<py::sequence>(row);
      for (size_t c = 0; c < items.size(); ++c)
        if (is_bool(items[c]))
          bool_at(items[c], "row " + std::to_string(r) + ", column " + std::to_string(c));
    }
  }
  py::array array;
  try {
    array = py::array(py::reinterpret_borrow<py::object>(value));
  } catch (py::error_already_set& e) {
    if (!e.matches(PyExc_TypeError) && !e.matches(PyExc_ValueError)) throw;
    wrong_kind(value, what, wanted);
  }
  // By default booleans, integers, floats, and objects NumPy converts one by one (c_array says
  // which fail).
  if (kinds && std::string_view(kinds).find(array.dtype().kind()) == std::string_view::npos)
    throw py::type_error(what + ": expected " + wanted + ", got an array of " +
                         std::string(py::str(array.dtype())));
  // NumPy casts an object array's None to NaN: a missing value nobody marked as one ([1.0, None]
  // is an object array). NaN given as such is kept.
  if (kinds && std::string_view(kinds).find('O') != std::string_view::npos &&
      array.dtype().kind() == 'O') {
    const py::ssize_t columns = array.ndim() == 2 ? array.shape(1) : 0;
    py::ssize_t at = 0;
    for (const py::handle item : array.attr("ravel")()) {
      if (item.is_none())
        throw py::type_error(what + ": expected " + wanted + ", got None at " +
                             (columns > 0 ? "row " + std::to_string(at / columns) + ", column " +
                                                std::to_string(at % columns)
                                          : "item " + std::to_string(at)) +
                             "; give numpy.nan for a missing value");
      ++at;
    }
  }
  return array;
}

uint64_t wide_copy_bytes(const py::array& given) {
  const bool wide = given.dtype().kind() == 'f' && given.dtype().itemsize() > 4;
  const bool as_is = given.dtype().itemsize() == 8 && (given.flags() & py::array::c_style) != 0;
  return wide && !as_is ? uint64_t(given.size()) * sizeof(double) : 0;
}

std::optional<std::pair<size_t, std::string>> beyond_float32(const py::array& given,
                                                             const std::string& what,
                                                             const char* wanted, size_t stride,
                                                             size_t used) {
  if (given.dtype().kind() != 'f' || given.dtype().itemsize() <= 4) return std::nullopt;
  const auto wide = c_array<double>(given, what, wanted);
  const double* values = wide.data();
  for (size_t i = 0; i < size_t(wide.size()); ++i)
    if (i % stride < used && std::isfinite(values[i]) && !std::isfinite(float(values[i]))) {
      char text[32];  // the shortest text that reads back as the value, as Python's repr
      const auto end = std::to_chars(text, text + sizeof text, values[i]).ptr;
      return std::pair(i, std::string(text, end));
    }
  return std::nullopt;
}

std::vector<std::string> text_list(const py::handle& value, const std::string& what) {
  const char* wanted = "a list of str";
  if (PyUnicode_Check(value.ptr()) || PyBytes_Check(value.ptr())) wrong_kind(value, what, wanted);
  py::list items;
  try {
    items = py::list(py::reinterpret_borrow<py::object>(value));
  } catch (py::error_already_set& e) {
    if (!e.matches(PyExc_TypeError)) throw;
    wrong_kind(value, what, wanted);
  }
  std::vector<std::string> names;
  for (const py::handle item : items) names.push_back(typed_arg<std::string>(item, what));
  return names;
}

std::string budget_arg(const py::handle& value, const std::string& what, bool refuse_zero) {
  const char* wanted = "a size str ('2G', 'unlimited') or a number of bytes (an int >= 0)";
  std::string text;
  uint64_t bytes = 1;
  if (PyUnicode_Check(value.ptr())) {
    // A size the CLI would refuse is a UsageError naming the argument, as --memory-budget's is.
    text = text_arg(value, what);
    try {
      if (text != "unlimited") bytes = parse_size(text);
    } catch (const Error& e) {
      throw UsageError(what + ": " + e.what());
    }
  } else {
    if (!is_integer(value)) wrong_kind(value, what, wanted);
    try {
      bytes = typed_arg<uint64_t>(value, what);
    } catch (const py::type_error&) {
      wrong_kind(value, what, wanted);
    }
    text = std::to_string(bytes);
  }
  // No room for any work ('unlimited' is the word for none), as on the command line.
  if (bytes == 0 && refuse_zero) throw UsageError(what + ": " + kZeroBudget);
  return text;
}

MemoryBudget budget_of(const py::object& value, const std::string& what) {
  return MemoryBudget(cli::memory_budget_bytes(value.is_none() ? "" : budget_arg(value, what)));
}

std::string origin_arg(const py::handle& value, const std::string& what) {
  const char* wanted = "None, 'auto', or three numbers (x, y, z)";
  if (value.is_none()) return "";
  if (PyUnicode_Check(value.ptr())) {
    std::string text = text_arg(value, what);
    // "" is no origin to the option parser; here None says that.
    if (text.empty())
      throw UsageError(what + ": '' is neither 'auto' nor 'x,y,z' (None: no origin)");
    return text;
  }
  if (!PySequence_Check(value.ptr()) && !py::hasattr(value, "__array__"))
    wrong_kind(value, what, wanted);
  const py::sequence xyz =
      py::reinterpret_borrow<py::sequence>(py::module_::import("builtins").attr("list")(value));
  if (xyz.size() != 3) wrong_kind(value, what, wanted);
  Origin origin{};
  for (size_t k = 0; k < 3; ++k) {
    if (!is_number(xyz[k])) wrong_kind(value, what, wanted);
    origin[k] = typed_arg<double>(xyz[k], what);
    if (!std::isfinite(origin[k]))
      throw UsageError(what + ": " + repr_of(value) + " is not three finite numbers");
  }
  return origin_text(origin);
}

py::object to_python(const nlohmann::json& value) {
  using Type = nlohmann::json::value_t;
  switch (value.type()) {
    case Type::boolean:
      return py::bool_(value.get<bool>());
    case Type::number_integer:
      return py::int_(value.get<int64_t>());
    case Type::number_unsigned:
      return py::int_(value.get<uint64_t>());
    case Type::number_float:
      return py::float_(value.get<double>());
    case Type::string:  // paths among them: as os.fsdecode gives them
      return fs_str(value.get_ref<const std::string&>());
    case Type::array: {
      py::list list;
      for (const nlohmann::json& element : value) list.append(to_python(element));
      return list;
    }
    case Type::object: {
      py::dict dict;
      for (const auto& [key, element] : value.items()) dict[fs_str(key)] = to_python(element);
      return dict;
    }
    default:  // null, binary, discarded
      return py::none();
  }
}

py::object keep_alive(std::shared_ptr<const void> owner) {
  auto* held = new std::shared_ptr<const void>(std::move(owner));
  return py::capsule(
      held, [](void* pointer) { delete static_cast<std::shared_ptr<const void>*>(pointer); });
}

std::string option_name(const std::string& keyword) {
  std::string name = keyword;
  for (char& c : name)
    if (c == '_') c = '-';
  return name;
}

std::vector<std::string> option_names(const py::kwargs& options) {
  std::vector<std::string> names;
  for (const auto& item : options) names.push_back(option_name(py::str(item.first)));
  return names;
}

}  // namespace linebake::python

PYBIND11_MODULE(linebake, module) {
  using namespace linebake::python;
  // Before anything touches HDF5: no error stacks printed, Debian's filter plugins registered.
  linebake::h5::init();
  module.doc() =
      "linebake: 3D line sets (streamlines, trajectories) to tube meshes, voxel grids and asset "
      "caches; renders with transparency techniques; PSNR and SSIM.";
  module.attr("__version__") = LINEBAKE_VERSION;
  // pybind11 looks NumPy's C API up on first use, under a static guard that waits holding the
  // GIL: threads making their first arrays at once deadlocked. Looked up here, once.
  (void)py::array_t<float>(0);
  bind_errors(module);
  bind_line_sets(module);
  bind_assets(module);
  bind_rendering(module);
}
