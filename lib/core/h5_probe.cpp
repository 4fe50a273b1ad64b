#include "core/h5_probe.hpp"

#include <sys/stat.h>

#include <mutex>
#include <new>
#include <set>
#include <stdexcept>

#include "core/h5.hpp"
#include "core/hash.hpp"
#include "core/isolated.hpp"

namespace linebake::h5 {
namespace {

[[noreturn]] void fail(const std::string& where, const std::string& what) {
  const std::string detail = last_error();
  throw std::runtime_error((where.empty() ? "" : where + ": ") + what +
                           (detail.empty() ? "" : " (" + detail + ")"));
}

// Reads every attribute's value: the parsing is what may crash. A clean HDF5 error here is not
// the walk's to report (the readers skip attributes they cannot read, as h5py's of odd types).
void walk_attributes(hid_t object) {
  H5O_info_t info{};
  if (H5Oget_info2(object, &info, H5O_INFO_NUM_ATTRS) < 0) return;
  for (hsize_t i = 0; i < info.num_attrs; ++i) {
    Handle attribute(
        H5Aopen_by_idx(object, ".", H5_INDEX_NAME, H5_ITER_INC, i, H5P_DEFAULT, H5P_DEFAULT),
        H5Aclose);
    if (!attribute.valid()) continue;
    Handle type(H5Aget_type(attribute), H5Tclose);
    Handle space(H5Aget_space(attribute), H5Sclose);
    if (!type.valid() || !space.valid()) continue;
    const hssize_t count = H5Sget_simple_extent_npoints(space);
    if (count <= 0) continue;
    if (H5Tget_class(type) == H5T_STRING && H5Tis_variable_str(type) > 0) {
      Handle memory(H5Tcopy(H5T_C_S1), H5Tclose);
      H5Tset_size(memory, H5T_VARIABLE);
      H5Tset_cset(memory, H5Tget_cset(type));
      std::vector<char*> text(static_cast<size_t>(count));
      if (H5Aread(attribute, memory, text.data()) >= 0)
        H5Dvlen_reclaim(memory, space, H5P_DEFAULT, text.data());
      continue;
    }
    if (H5Tdetect_class(type, H5T_VLEN) > 0 || H5Tdetect_class(type, H5T_REFERENCE) > 0)
      continue;  // no reader of ours takes these
    const size_t size = H5Tget_size(type);
    if (size == 0 || static_cast<uint64_t>(count) > (uint64_t{1} << 30) / size) continue;
    std::vector<char> buffer(static_cast<size_t>(count) * size);
    H5Aread(attribute, type, buffer.data());
  }
}

// Type, shape, filters and the whole chunk index (H5Dget_num_chunks visits every index node).
void walk_dataset(hid_t dataset, const std::string& where, hsize_t file_size) {
  Handle type(H5Dget_type(dataset), H5Tclose);
  Handle space(H5Dget_space(dataset), H5Sclose);
  Handle dcpl(H5Dget_create_plist(dataset), H5Pclose);
  if (!type.valid() || !space.valid() || !dcpl.valid()) fail(where, "unreadable header");
  const int rank = H5Sget_simple_extent_ndims(space);
  if (rank < 0 || rank > H5S_MAX_RANK) fail(where, "unreadable shape");
  H5Dget_storage_size(dataset);
  const std::string damaged = damaged_storage(dataset);
  if (!damaged.empty()) fail(where, damaged);
  const int filters = H5Pget_nfilters(dcpl);
  for (int f = 0; f < filters; ++f) {
    unsigned flags = 0, config = 0;
    size_t values = 8;
    unsigned client[8];
    char name[256];
    if (H5Pget_filter2(dcpl, static_cast<unsigned>(f), &flags, &values, client, sizeof name, name,
                       &config) < 0)
      fail(where, "unreadable filter pipeline");
  }
  if (H5Pget_layout(dcpl) != H5D_CHUNKED) return;
  hsize_t chunks = 0;
  if (H5Dget_num_chunks(dataset, space, &chunks) < 0) fail(where, "unreadable chunk index");
  if (chunks == 0) return;
  hsize_t offset[H5S_MAX_RANK];
  unsigned mask = 0;
  haddr_t address = 0;
  hsize_t size = 0;
  if (H5Dget_chunk_info(dataset, space, 0, offset, &mask, &address, &size) < 0)
    fail(where, "unreadable chunk index");
  if (address != HADDR_UNDEF && (address > file_size || size > file_size - address))
    fail(where, "its first chunk lies past the end of the file");
}

struct Walk {
  hsize_t file_size = 0;
};

void walk_object(hid_t location, const char* name, const std::string& where, const Walk& walk) {
  Handle object(H5Oopen(location, name, H5P_DEFAULT), H5Oclose);
  if (!object.valid()) fail(where, "cannot open");
  walk_attributes(object);
  if (H5Iget_type(object) == H5I_DATASET) walk_dataset(object, where, walk.file_size);
}

}  // namespace

void walk_metadata(const std::string& path, const std::vector<std::string>& objects) {
  init();
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!file.valid()) fail("", "cannot open");
  Walk walk;
  if (H5Fget_filesize(file, &walk.file_size) < 0) fail("", "unknown size");
  walk_attributes(file);
  for (const std::string& name : objects) {
    if (!path_exists(file, name)) continue;
    walk_object(file, name.c_str(), name, walk);
    H5O_info_t info{};
    if (H5Oget_info_by_name2(file, name.c_str(), &info, H5O_INFO_BASIC, H5P_DEFAULT) < 0)
      fail(name, "unreadable object header");
    if (info.type != H5O_TYPE_GROUP) continue;
    // H5Ovisit visits each object once, also where hard links form a cycle.
    struct Visit {
      const Walk* walk;
      std::string prefix;
      std::string error;
      bool out_of_memory = false;
    } visit{&walk, name == "/" ? "/" : name + "/", "", false};
    auto each = [](hid_t group, const char* member, const H5O_info_t*, void* data) -> herr_t {
      auto& v = *static_cast<Visit*>(data);
      if (member[0] == '.' && member[1] == '\0') return 0;
      try {
        walk_object(group, member, v.prefix + member, *v.walk);
      } catch (const std::bad_alloc&) {
        v.out_of_memory = true;
        return -1;
      } catch (const std::exception& e) {
        v.error = e.what();
        return -1;
      }
      return 0;
    };
    Handle group(H5Gopen2(file, name.c_str(), H5P_DEFAULT), H5Gclose);
    if (!group.valid()) fail(name, "cannot open");
    const herr_t visited =
        H5Ovisit2(group, H5_INDEX_NAME, H5_ITER_INC, each, &visit, H5O_INFO_BASIC);
    if (visit.out_of_memory) throw std::bad_alloc();  // the child's memory cap: say so
    if (visited < 0)
      throw std::runtime_error(
          visit.error.empty() ? name + ": unreadable group (" + last_error() + ")" : visit.error);
  }
}

namespace {

// What identifies the file a walk passed: its inode, size and times, and for files up to 16 MiB
// (every fuzzed input) the hash of its bytes, as a file rewritten within one clock tick keeps
// its times.
std::string identity(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return "";
  std::string key = path + '\n' + std::to_string(st.st_dev) + ':' + std::to_string(st.st_ino) +
                    ':' + std::to_string(st.st_size) + ':' + std::to_string(st.st_mtim.tv_sec) +
                    '.' + std::to_string(st.st_mtim.tv_nsec) + ':' +
                    std::to_string(st.st_ctim.tv_sec) + '.' + std::to_string(st.st_ctim.tv_nsec);
  if (st.st_size <= (off_t{16} << 20)) {
    try {
      key += '\n' + hash_file(path);
    } catch (const std::exception&) {
      return "";
    }
  }
  return key;
}

std::string with_objects(std::string key, const std::vector<std::string>& objects) {
  for (const std::string& o : objects) key += '\n' + o;
  return key;
}

}  // namespace

void probe(const std::string& path, const std::vector<std::string>& objects) {
  if (!isolation_enabled()) return;
  // One command opens a cache several times (is it a cache, read it, copy from it): one walk.
  static std::mutex mutex;
  static std::set<std::string> passed;
  const std::string file = identity(path);
  const std::string key = file.empty() ? "" : with_objects(file, objects);
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (!key.empty() && passed.count(key)) return;
    // The whole file's walk covers the superblock and the root's attributes.
    if (!key.empty() && objects.empty() && passed.count(with_objects(file, {"/"}))) return;
  }
  std::vector<std::string> args{"hdf5", path};
  args.insert(args.end(), objects.begin(), objects.end());
  check_in_isolation(
      path, "HDF5", [&] { walk_metadata(path, objects); }, {}, args);
  std::lock_guard<std::mutex> lock(mutex);
  if (!key.empty()) passed.insert(key);
}

}  // namespace linebake::h5
