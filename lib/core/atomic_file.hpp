#pragma once
// Outputs are written under a temporary name beside the target and renamed when complete, so a
// failed or interrupted write never leaves a half-written file under the final name.

#include <string>

namespace linebake {

class AtomicFile {
 public:
  explicit AtomicFile(std::string final_path);
  ~AtomicFile();  // removes the temporary file unless commit() succeeded
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  // Where the writer should write.
  const std::string& temp_path() const { return temp_path_; }
  const std::string& final_path() const { return final_path_; }

  // Renames the temporary file to the final name. Throws OutputError on failure.
  void commit();

 private:
  std::string final_path_;
  std::string temp_path_;
  bool committed_ = false;
};

// `<path>.tmp-<host>-<pid>-<n>`: a name no other process, here or on another host sharing the
// file system, uses at the same time.
std::string temporary_name(const std::string& path);

// Writes `bytes` to `path` through an AtomicFile. Throws OutputError.
void write_file_atomically(const std::string& path, const std::string& bytes);

}  // namespace linebake
