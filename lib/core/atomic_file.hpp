#pragma once
// Outputs are written under a temporary name beside the target and renamed when complete, so a
// failed or interrupted write never leaves a half-written file under the final name. The commit
// is durable: the temporary file is flushed to disk before the rename and the directory after
// it, so a power cut after "done" leaves the old file or the new one, never an empty or torn
// one. Temporary names carry the host and the process id: a writer removes the temporaries of
// its output that a dead process on the same host left behind.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace linebake {

class AtomicFile {
 public:
  // Removes stale temporaries of `final_path` first (see remove_stale_temporaries).
  explicit AtomicFile(std::string final_path);
  // A temporary file that several processes write together (MPI ranks): named by one of them;
  // only the `owner` removes it on failure and renames it on commit().
  AtomicFile(std::string final_path, std::string temp_path, bool owner);
  ~AtomicFile();  // removes the temporary file unless commit() succeeded
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  // Where the writer should write.
  const std::string& temp_path() const { return temp_path_; }
  const std::string& final_path() const { return final_path_; }

  // fsync, rename to the final name, fsync the directory. Throws OutputError naming the final
  // path (the temporary one in parentheses).
  void commit();
  // Runs `write` (which writes temp_path()); an OutputError it throws about the temporary file
  // is thrown again naming the final path, the temporary one in parentheses.
  void write_with(const std::function<void()>& write) const;

 private:
  std::string final_path_;
  std::string temp_path_;
  bool committed_ = false;
  bool owner_ = true;
};

// Outputs of one command that stand or fall together (an image and its --stats, every frame of
// a flight). While a group is open on this thread, AtomicFile::commit() only syncs its temporary
// file and hands it over; the group's commit() renames them all, and a group that ends without
// commit() (an error, an interruption) removes them all, so a failed command leaves nothing.
class OutputGroup {
 public:
  OutputGroup();
  ~OutputGroup();
  OutputGroup(const OutputGroup&) = delete;
  OutputGroup& operator=(const OutputGroup&) = delete;
  void commit();

 private:
  friend class AtomicFile;
  struct File {
    std::string temp, final;
  };
  std::vector<File> files_;
  OutputGroup* previous_ = nullptr;
  bool committed_ = false;
};

// Writes `bytes` to `path` through an AtomicFile. Throws OutputError.
void write_file_atomically(const std::string& path, const std::string& bytes);

// `<path>[.<tag>].tmp-<host>-<pid>-<n>`: a name no other process, here or on another host
// sharing the file system, uses at the same time. Where that name would pass the file system's
// limit on a name (255 bytes), `path`'s name is shortened first (side_name).
std::string temporary_name(const std::string& path, const std::string& tag = "");

// `path`, or where its name and `extra` bytes more would pass the file system's limit on a name,
// the path of its shortened name: its first 100 bytes, '~' and 16 hex digits of its hash. For
// the names made beside an output (temporaries, spill files, its lock): an output's own name may
// take the whole limit (they had failed names of 230-255 bytes once the work was done).
std::string side_name(const std::string& path, size_t extra);
std::string shortened_name(const std::string& name);

// Removes files beside `path` named `<name>.tmp-<host>-<pid>-<n>` or `<name>.<tag>.tmp-<host>-
// <pid>-<n>` (temporaries and spill files of that output) whose process is gone, on this host
// only: a process on another host may still be writing. Reports what it removed through
// notify() and returns the bytes.
uint64_t remove_stale_temporaries(const std::string& path);

// Throws OutputError when `output` is one of `inputs` (the same file, whatever the path):
// an output never replaces an input of its command.
void refuse_input_as_output(const std::string& output, const std::vector<std::string>& inputs);
// Before any work: refuse_input_as_output for each of `outputs` ("" skipped), and an
// OutputError when two of them are one file (the later would replace the earlier).
void refuse_clashing_outputs(const std::vector<std::string>& outputs,
                             const std::vector<std::string>& inputs);
// Where an output at `path` is written: `path`, or the file a symbolic link there names (the
// link is kept). Throws OutputError when that exists and is not a regular file (a device such as
// /dev/null, a FIFO, a socket, a directory): renaming over it would replace it.
std::string output_target(const std::string& path);
// Before any work: throws OutputError naming `path` when its directory does not exist or is not
// writable, or when `path` is a directory or another file that is not a regular one. "" passes
// (no such output).
void check_output_location(const std::string& path);
// Bytes free for this user on the file system that holds `path` (or would: its directory).
uint64_t free_bytes_for(const std::string& path);
// Why a write to `file` (being written) may have failed, where the writer was not told (MPI-IO
// reports "file write failed" without errno), as what is seen, not as a certainty: "the file
// system has only N free" when less than `attempted` bytes (1 MiB at least) are free, "the file
// is at the file size limit (ulimit -f) of N" when it is within `attempted` of it; "" otherwise.
std::string write_failure_cause(const std::string& file, uint64_t attempted);

// Fixes a file's bytes on disk (fsync); throws OutputError naming `name` on failure.
void sync_file(const std::string& path, const std::string& name);
// Fixes a directory entry (after a rename) on disk.
void sync_directory_of(const std::string& path, const std::string& name);

// The outputs this process has renamed to their final names so far, in order, and not removed
// since: what a failure after them (standard output's, at the end of a command) says was
// written whole.
std::vector<std::string> outputs_written();

// Messages the library has for the user that are not errors (stale files removed, a wait for
// another process's lock, values a format's reader cannot read back). The default prints
// "linebake: MESSAGE" to stderr; the Python module's makes each a linebake.Note warning. An
// exception the handler throws reaches notify()'s caller.
void notify(const std::string& message);
void set_notify_handler(std::function<void(const std::string&)> handler);

}  // namespace linebake
