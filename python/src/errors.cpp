// linebake's errors as Python exceptions: linebake.Error (a RuntimeError) and one subclass per
// kind the CLI tells apart by exit code, with the CLI's messages.

#include <algorithm>
#include <iostream>

#include "bindings.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/interrupt.hpp"
#include "core/nearest.hpp"

namespace linebake::python {

int& long_calls_on_this_thread() {
  static thread_local int calls = 0;
  return calls;
}

namespace {

// Raises `type(message)` with extra attributes (file, where) set on the instance; the message and
// the attributes decoded as os.fsdecode decodes (a path that is not UTF-8 among them).
void raise_with(py::handle type, const std::string& message,
                const std::vector<std::pair<const char*, std::string>>& fields) {
  py::object instance = type(fs_str(message));
  for (const auto& [name, value] : fields) instance.attr(name) = fs_str(value);
  PyErr_SetObject(type.ptr(), instance.ptr());
}

void raise(py::handle type, const std::string& message) {
  PyErr_SetObject(type.ptr(), fs_str(message).ptr());
}

}  // namespace

void check_keywords(const char* function, const py::kwargs& options,
                    const std::vector<std::string>& known) {
  for (const auto& item : options) {
    const std::string name = py::str(item.first);
    if (std::find(known.begin(), known.end(), name) == known.end())
      throw py::type_error(std::string(function) + "() got an unexpected keyword argument '" +
                           name + "'" + did_you_mean(name, known));
  }
}

void bind_errors(py::module_& module) {
  // Created once and never released: the module holds them, and a static py::object would be
  // released after the interpreter is gone.
  static py::handle error = py::exception<Error>(module, "Error", PyExc_RuntimeError).release();
  static py::handle usage = py::exception<UsageError>(module, "UsageError", error).release();
  static py::handle input = py::exception<InputError>(module, "InputError", error).release();
  static py::handle output = py::exception<OutputError>(module, "OutputError", error).release();
  static py::handle budget =
      py::exception<BudgetExceeded>(module, "BudgetExceeded", error).release();
  error.attr("__doc__") =
      "Any failure linebake reports, with the CLI's message (FILE: PLACE: message).";
  usage.attr("__doc__") = "Options that contradict each other or that nothing reads.";
  input.attr("__doc__") = "Bad or unreadable input; .file and .where name the place.";
  output.attr("__doc__") = "An output that could not be written; .file names it.";
  budget.attr("__doc__") = "Work that does not fit the memory budget, refused before it starts.";
  // What an instance made in Python (InputError("x")) has: linebake's own set them.
  input.attr("file") = py::none();
  input.attr("where") = py::none();
  output.attr("file") = py::none();
  static py::handle note = PyErr_NewException("linebake.Note", PyExc_UserWarning, nullptr);
  module.add_object("Note", note);
  note.attr("__doc__") =
      "What linebake tells besides errors: stale temporaries it removed, a wait for another "
      "process writing the same output, values a format's reader cannot read back.";
  // A note on the calling thread of a call (which has released the GIL) is warned at once, so
  // that a notebook shows it and a warnings filter can make an error of it (raised from the
  // call: what the call had written is removed as for any error); notes of other threads (none
  // of linebake's own so far) go to stderr.
  linebake::set_notify_handler([](const std::string& message) {
    if (long_calls_on_this_thread() == 0 || !Py_IsInitialized()) {
      std::cerr << "linebake: " << message << "\n";
      return;
    }
    py::gil_scoped_acquire gil;
    py::module_::import("warnings").attr("warn")(fs_str(message), note, 1);
  });
  // Most derived first: a translator sees the C++ exception once.
  py::register_exception_translator([](std::exception_ptr thrown) {
    try {
      if (thrown) std::rethrow_exception(thrown);
    } catch (const Interrupted& e) {
      PyErr_SetString(PyExc_KeyboardInterrupt, e.what());
    } catch (const InputError& e) {
      raise_with(input, e.what(), {{"file", e.file()}, {"where", e.where()}});
    } catch (const OutputError& e) {
      raise_with(output, e.what(), {{"file", e.file()}});
    } catch (const UsageError& e) {
      raise(usage, e.what());
    } catch (const BudgetExceeded& e) {
      raise(budget, e.what());
    } catch (const Error& e) {
      raise(error, e.what());
    }
  });
}

}  // namespace linebake::python
