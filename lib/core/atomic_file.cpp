#include "core/atomic_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <mutex>

#include "core/error.hpp"
#include "core/hash.hpp"
#include "core/interrupt.hpp"
#include "core/memory_budget.hpp"

namespace linebake {
namespace {

std::string host_name() {
  char host[256] = "host";
  if (::gethostname(host, sizeof host - 1) != 0) std::strcpy(host, "host");
  host[sizeof host - 1] = '\0';
  for (char* c = host; *c; ++c)
    if (*c == '/' || *c == '.' || *c == '-') *c = '_';
  return host;
}

std::mutex notify_mutex;
std::function<void(const std::string&)> notify_handler;

}  // namespace

void notify(const std::string& message) {
  // Called outside the lock: a handler may wait (Python's, for the GIL) or throw (a warnings
  // filter that makes an error of it).
  std::function<void(const std::string&)> handler;
  {
    std::lock_guard<std::mutex> lock(notify_mutex);
    handler = notify_handler;
  }
  if (handler)
    handler(message);
  else
    std::cerr << "linebake: " << message << "\n";
}

void set_notify_handler(std::function<void(const std::string&)> handler) {
  std::lock_guard<std::mutex> lock(notify_mutex);
  notify_handler = std::move(handler);
}

std::string shortened_name(const std::string& name) {
  return name.substr(0, 100) + "~" + Hasher().update(name).hex().substr(0, 16);
}

std::string side_name(const std::string& path, size_t extra) {
  const std::filesystem::path p(path);
  const std::string name = p.filename().string();
  const std::string dir = p.has_parent_path() ? p.parent_path().string() : ".";
  const long limit = ::pathconf(dir.c_str(), _PC_NAME_MAX);
  if (name.size() + extra <= (limit > 0 ? size_t(limit) : 255)) return path;
  return (p.parent_path() / shortened_name(name)).string();
}

std::string temporary_name(const std::string& path, const std::string& tag) {
  static std::atomic<unsigned> counter{0};
  const std::string suffix = (tag.empty() ? "" : "." + tag) + ".tmp-" + host_name() + "-" +
                             std::to_string(::getpid()) + "-" + std::to_string(counter++);
  // A few bytes to spare for what a caller appends (Python's bake input adds ".h5").
  return side_name(path, suffix.size() + 8) + suffix;
}

uint64_t remove_stale_temporaries(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  const std::string name = target.filename().string();
  const std::string marker = ".tmp-" + host_name() + "-";
  // Named after the output, or after its shortened name (side_name) for a long one.
  const std::string bases[] = {name, shortened_name(name)};
  uint64_t bytes = 0, files = 0;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string file = entry.path().filename().string();
    size_t base = 0;
    for (const std::string& b : bases)
      if (file.compare(0, b.size() + 1, b + ".") == 0) base = b.size();
    if (base == 0) continue;
    const size_t at = file.find(marker, base);
    if (at == std::string::npos) continue;
    // Between the marker and the next '-': the writer's pid.
    const size_t pid_begin = at + marker.size(), pid_end = file.find('-', pid_begin);
    if (pid_end == std::string::npos) continue;
    long pid = 0;
    try {
      pid = std::stol(file.substr(pid_begin, pid_end - pid_begin));
    } catch (const std::exception&) {
      continue;
    }
    if (pid <= 0 || pid == ::getpid() || ::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;
    const uint64_t size = entry.is_regular_file(ec) ? uint64_t(entry.file_size(ec)) : 0;
    if (fs::remove(entry.path(), ec)) {
      bytes += size;
      ++files;
    }
  }
  if (files)
    notify("removed " + std::to_string(files) + " temporary file(s) of " + path + " (" +
           format_bytes(bytes) + ") left by a process that no longer runs");
  return bytes;
}

void refuse_input_as_output(const std::string& output, const std::vector<std::string>& inputs) {
  struct stat out {};
  if (::stat(output.c_str(), &out) != 0) return;  // a new file
  for (const std::string& input : inputs) {
    struct stat in {};
    if (::stat(input.c_str(), &in) == 0 && in.st_dev == out.st_dev && in.st_ino == out.st_ino)
      throw OutputError(
          output, "is the input " + input + " of this command; an output never replaces its input");
  }
}

void refuse_clashing_outputs(const std::vector<std::string>& outputs,
                             const std::vector<std::string>& inputs) {
  // Each output's file, resolved as the kernel would (links and ".." in order), with the output
  // that named it first: a flight's 100,000 frames are checked in a sorted map, not pairwise.
  std::map<std::filesystem::path, const std::string*> seen;
  for (const std::string& output : outputs) {
    if (output.empty()) continue;
    refuse_input_as_output(output, inputs);
    const std::filesystem::path absolute = std::filesystem::absolute(output);
    std::error_code ec;
    std::filesystem::path resolved = std::filesystem::weakly_canonical(absolute, ec);
    if (ec) resolved = absolute;
    const auto [at, added] = seen.emplace(resolved, &output);
    if (!added)
      throw OutputError(output, "is also the output " + *at->second +
                                    " of this command; each output needs a file of its own");
  }
}

void check_output_location(const std::string& path) {
  if (path.empty()) return;
  // A device, FIFO or socket is refused before any work; a symbolic link is checked where it
  // leads, which is where the file is written (output_target).
  const std::string target = output_target(path);
  const std::string via = target == path ? "" : " (where the link leads: " + target + ")";
  const std::filesystem::path p(target);
  const std::string dir = p.has_parent_path() ? p.parent_path().string() : ".";
  std::error_code ec;
  if (std::filesystem::is_directory(p, ec)) throw OutputError(path, "is a directory" + via);
  if (!std::filesystem::is_directory(dir, ec))
    throw OutputError(path, "the directory " + dir + " does not exist" + via);
  if (::access(dir.c_str(), W_OK) != 0)
    throw OutputError(path, "the directory " + dir + " is not writable" + via);
  // A name past the file system's limit is refused here, with the others, before any work
  // (std::filesystem would throw its own error on it later; the pipeline fuzzer's finding).
  const long name_max = ::pathconf(dir.c_str(), _PC_NAME_MAX);
  if (name_max > 0 && p.filename().string().size() > size_t(name_max))
    throw OutputError(path, "the file name is " + std::to_string(p.filename().string().size()) +
                                " bytes, longer than the file system allows (" +
                                std::to_string(name_max) + ")");
}

uint64_t free_bytes_for(const std::string& path) {
  std::string target = path;  // where a symbolic link leads: the file system written to
  try {
    target = output_target(path);
  } catch (const Error&) {
  }
  const std::filesystem::path p(target);
  const std::string dir = p.has_parent_path() ? p.parent_path().string() : ".";
  struct statvfs fs {};
  if (::statvfs(dir.c_str(), &fs) != 0) return UINT64_MAX;  // unknown: do not refuse
  return uint64_t(fs.f_bavail) * uint64_t(fs.f_frsize);
}

std::string write_failure_cause(const std::string& file, uint64_t attempted) {
  const uint64_t margin = std::max<uint64_t>(attempted, uint64_t{1} << 20);
  const uint64_t free = free_bytes_for(file);
  if (free < margin) return "the file system has only " + format_bytes(free) + " free";
  struct rlimit limit {};
  struct stat st {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY &&
      ::stat(file.c_str(), &st) == 0 && uint64_t(st.st_size) + margin > uint64_t(limit.rlim_cur))
    return "the file is at the file size limit (ulimit -f) of " +
           format_bytes(uint64_t(limit.rlim_cur));
  return "";
}

void sync_file(const std::string& path, const std::string& name) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw OutputError(name, std::string("cannot open to sync: ") + std::strerror(errno));
  const int rc = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (rc != 0)
    throw OutputError(name, std::string("cannot write to disk (fsync): ") + std::strerror(error) +
                                (path == name ? "" : " (" + path + ")"));
}

void sync_directory_of(const std::string& path, const std::string& name) {
  const std::filesystem::path p(path);
  const std::string dir = p.has_parent_path() ? p.parent_path().string() : ".";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;  // some file systems do not open directories; the rename stands
  const int rc = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  // EINVAL: the file system cannot sync directories (the rename is already as durable as it
  // gets there).
  if (rc != 0 && error != EINVAL)
    throw OutputError(name, std::string("cannot write the directory entry to disk (fsync): ") +
                                std::strerror(error));
}

std::string output_target(const std::string& path) {
  std::error_code ec;
  std::string target = path;
  // A symbolic link is written through, as editors do: the file it names gets the bytes (its
  // temporary beside it, so the rename stays on its file system) and the link stays a link.
  // (Followed link by link: weakly_canonical does not follow a link to a file not yet there.)
  for (int links = 0; links < 40 && std::filesystem::is_symlink(target, ec); ++links) {
    const std::filesystem::path link(target), to = std::filesystem::read_symlink(link, ec);
    if (ec) break;
    // Not lexically normalised: a ".." after a linked directory is the kernel's to resolve.
    target = (to.is_absolute() ? to : link.parent_path() / to).string();
  }
  // Still a link after 40 (the kernel's limit): a loop, which renaming over it would replace.
  if (std::filesystem::is_symlink(target, ec))
    throw OutputError(path, "is a loop of symbolic links (or a chain of more than 40)");
  const auto status = std::filesystem::status(target, ec);
  if (!ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status))
    throw OutputError(path, std::filesystem::is_directory(status)
                                ? "is a directory"
                                : "is not a regular file (a device, FIFO or socket): linebake "
                                  "writes files, renamed into place when complete");
  return target;
}

AtomicFile::AtomicFile(std::string final_path)
    : final_path_(output_target(final_path)), temp_path_(temporary_name(final_path_)) {
  remove_stale_temporaries(final_path_);
}

AtomicFile::AtomicFile(std::string final_path, std::string temp_path, bool owner)
    : final_path_(std::move(final_path)), temp_path_(std::move(temp_path)), owner_(owner) {}

AtomicFile::~AtomicFile() {
  if (!committed_ && owner_) std::remove(temp_path_.c_str());
}

namespace {
thread_local OutputGroup* open_group = nullptr;

std::mutex written_mutex;
std::vector<std::string> written;  // outputs_written()

void record_written(const std::string& path) {
  const std::lock_guard<std::mutex> lock(written_mutex);
  written.push_back(path);
}
}  // namespace

OutputGroup::OutputGroup() : previous_(open_group) {
  open_group = this;
}

OutputGroup::~OutputGroup() {
  open_group = previous_;
  if (!committed_)
    for (const File& f : files_) std::remove(f.temp.c_str());
}

void OutputGroup::commit() {
  open_group = previous_;
  committed_ = true;
  size_t renamed = 0;
  for (const File& f : files_) {
    if (std::rename(f.temp.c_str(), f.final.c_str()) != 0) {
      const int error = errno;
      for (size_t i = renamed + 1; i < files_.size(); ++i) std::remove(files_[i].temp.c_str());
      std::remove(f.temp.c_str());
      throw OutputError(f.final, std::string("cannot rename the temporary file: ") +
                                     std::strerror(error) + " (" + f.temp + ")");
    }
    ++renamed;
    record_written(f.final);
  }
  for (const File& f : files_) sync_directory_of(f.final, f.final);
}

std::vector<std::string> outputs_written() {
  const std::lock_guard<std::mutex> lock(written_mutex);
  // Those still there: bench bake removes the cache it wrote, which a failure after it had named.
  std::vector<std::string> there;
  std::error_code ec;
  for (const std::string& path : written)
    if (std::filesystem::exists(path, ec)) there.push_back(path);
  return there;
}

void AtomicFile::commit() {
  if (!owner_) {
    committed_ = true;
    return;
  }
  sync_file(temp_path_, final_path_);
  // The last moment a signal can still leave nothing (fsync takes tens of milliseconds on a large
  // file): past the rename the file is whole, and said to be.
  if (!open_group) throw_if_interrupted();
  if (open_group) {
    open_group->files_.push_back({temp_path_, final_path_});
    committed_ = true;
    return;
  }
  if (std::rename(temp_path_.c_str(), final_path_.c_str()) != 0) {
    throw OutputError(final_path_, std::string("cannot rename the temporary file: ") +
                                       std::strerror(errno) + " (" + temp_path_ + ")");
  }
  committed_ = true;
  record_written(final_path_);
  sync_directory_of(final_path_, final_path_);
}

void AtomicFile::write_with(const std::function<void()>& write) const {
  try {
    write();
  } catch (const OutputError& e) {
    if (e.file() != temp_path_) throw;
    throw OutputError(final_path_, e.detail() + " (" + temp_path_ + ")");
  }
}

void write_file_atomically(const std::string& path, const std::string& bytes) {
  AtomicFile file(path);
  const int fd = ::open(file.temp_path().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw OutputError(path, std::string("cannot create: ") + std::strerror(errno));
  const char* p = bytes.data();
  size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : ENOSPC;
      ::close(fd);
      throw OutputError(path, std::string("cannot write: ") + std::strerror(error) + " (" +
                                  file.temp_path() + ")");
    }
    p += n;
    left -= size_t(n);
  }
  if (::close(fd) != 0)
    throw OutputError(
        path, std::string("cannot write: ") + std::strerror(errno) + " (" + file.temp_path() + ")");
  file.commit();
}

}  // namespace linebake
