#pragma once
// Errors are values with context: which file, and where in it.

#include <cstdint>
#include <stdexcept>
#include <string>

namespace linebake {

// Any failure linebake reports to the user.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A bad command line found once it is parsed: an option the chosen technique or format does not
// read, options that contradict each other (exit code 1, as a parse error).
class UsageError : public Error {
 public:
  using Error::Error;
};

// Bad or unreadable input. `where` names the place: "line 12", "byte offset 4096",
// "dataset /points", "variable lon".
class InputError : public Error {
 public:
  InputError(const std::string& file, const std::string& where, const std::string& message)
      : Error(file + (where.empty() ? "" : ": " + where) + ": " + message),
        file_(file),
        where_(where) {}
  const std::string& file() const { return file_; }
  const std::string& where() const { return where_; }

 private:
  std::string file_;
  std::string where_;
};

// An output that could not be written.
class OutputError : public Error {
 public:
  OutputError(const std::string& file, const std::string& message)
      : Error(file + ": " + message), file_(file), detail_(message) {}
  const std::string& file() const { return file_; }
  const std::string& detail() const { return detail_; }

 private:
  std::string file_, detail_;
};

// Work that does not fit the memory budget (core/memory_budget.hpp): refused before it starts.
class BudgetExceeded : public Error {
 public:
  using Error::Error;
};

inline std::string at_line(uint64_t line) {
  return "line " + std::to_string(line);
}
inline std::string at_byte(uint64_t offset) {
  return "byte offset " + std::to_string(offset);
}

}  // namespace linebake
