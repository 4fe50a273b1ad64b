#include "cache/group_copy.hpp"

#include <algorithm>
#include <map>
#include <vector>

#include "cache/chunk_codec.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "core/interrupt.hpp"

namespace linebake {
namespace {

using h5::Handle;

// Values that point into their own file: variable-length data (global heap ids) and references.
// A variable-length string counts as a string to H5Tdetect_class, and arrays and compounds of
// them are looked into here.
bool holds_heap_ids(hid_t type) {
  const H5T_class_t kind = H5Tget_class(type);
  if (kind == H5T_VLEN || H5Tis_variable_str(type) > 0) return true;
  if (kind == H5T_ARRAY || kind == H5T_ENUM) {
    Handle base(H5Tget_super(type), H5Tclose);
    return base.valid() && holds_heap_ids(base);
  }
  if (kind == H5T_COMPOUND) {
    const int members = H5Tget_nmembers(type);
    for (int i = 0; i < members; ++i) {
      Handle member(H5Tget_member_type(type, unsigned(i)), H5Tclose);
      if (member.valid() && holds_heap_ids(member)) return true;
    }
  }
  return false;
}
bool holds_references(hid_t type) {
  return H5Tdetect_class(type, H5T_REFERENCE) > 0;
}

struct Copy {
  const std::string& source_path;
  const std::string& target_path;
  uint64_t slab_bytes;  // rows of a dataset without chunks read and written at a time
  hid_t target_file;
  const std::string& root;  // the group copied
  // The objects copied, by their place in the source file, with their path in the target: an
  // object linked twice (or a group linked into itself) is linked again, not copied again.
  mutable std::map<haddr_t, std::string> copied{};
  // The target's committed datatypes that datasets took, by the source type's place: opened
  // where the type was copied before them, committed without a name where it comes later (and
  // linked when the copy reaches it).
  mutable std::map<haddr_t, Handle> shared_types{};

  [[noreturn]] void cannot_read(const std::string& object, const std::string& what) const {
    throw InputError(source_path, object, "cannot read " + what + " (" + h5::last_error() + ")");
  }
  [[noreturn]] void cannot_write(const std::string& object, const std::string& what) const {
    throw OutputError(target_path,
                      object + ": cannot write " + what + " (" + h5::last_error() + ")");
  }

  // A group's creation properties as linebake sets them, taken from the source group's: the
  // order of links and attributes tracked or not, times not recorded. (The source's own list,
  // passed as it is, failed for a file written by parallel HDF5: "address of object past end of
  // allocation".)
  static Handle group_properties(hid_t source_gcpl) {
    Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
    unsigned links = 0, attributes = 0;
    hbool_t times = false;
    if (H5Pget_link_creation_order(source_gcpl, &links) >= 0)
      H5Pset_link_creation_order(gcpl, links);
    if (H5Pget_attr_creation_order(source_gcpl, &attributes) >= 0)
      H5Pset_attr_creation_order(gcpl, attributes);
    if (H5Pget_obj_track_times(source_gcpl, &times) >= 0) H5Pset_obj_track_times(gcpl, times);
    return gcpl;
  }

  // Links and attributes in creation order where the object tracks it, else by name.
  static H5_index_t index_of(hid_t creation_plist, bool links) {
    unsigned flags = 0;
    const herr_t r = links ? H5Pget_link_creation_order(creation_plist, &flags)
                           : H5Pget_attr_creation_order(creation_plist, &flags);
    return r >= 0 && (flags & H5P_CRT_ORDER_INDEXED) ? H5_INDEX_CRT_ORDER : H5_INDEX_NAME;
  }

  void attributes(hid_t from, hid_t to, hid_t creation_plist, const std::string& object) const {
    H5O_info_t info{};
    if (H5Oget_info2(from, &info, H5O_INFO_NUM_ATTRS) < 0) cannot_read(object, "its attributes");
    const H5_index_t index = index_of(creation_plist, false);
    for (hsize_t i = 0; i < info.num_attrs; ++i) {
      Handle a(H5Aopen_by_idx(from, ".", index, H5_ITER_INC, i, H5P_DEFAULT, H5P_DEFAULT),
               H5Aclose);
      if (!a.valid()) cannot_read(object, "attribute " + std::to_string(i));
      std::string name(size_t(std::max<ssize_t>(H5Aget_name(a, 0, nullptr), 0)), '\0');
      H5Aget_name(a, name.size() + 1, name.data());
      Handle type(H5Aget_type(a), H5Tclose), space(H5Aget_space(a), H5Sclose);
      Handle acpl(H5Aget_create_plist(a), H5Pclose);
      if (!type.valid() || !space.valid() || !acpl.valid())
        cannot_read(object, "attribute " + name);
      if (holds_references(type)) refuse_references(object + " attribute " + name);
      const hssize_t n = H5Sget_simple_extent_npoints(space);
      std::vector<char> values(size_t(std::max<hssize_t>(n, 1)) * H5Tget_size(type));
      if (H5Aread(a, type, values.data()) < 0) cannot_read(object, "attribute " + name);
      const bool variable = holds_heap_ids(type);
      Handle out(H5Acreate2(to, name.c_str(), type, space, acpl, H5P_DEFAULT), H5Aclose);
      const herr_t written = out.valid() ? H5Awrite(out, type, values.data()) : -1;
      if (variable) H5Dvlen_reclaim(type, space, H5P_DEFAULT, values.data());
      if (written < 0) cannot_write(object, "attribute " + name);
    }
  }

  void dataset(hid_t from_parent, hid_t to_parent, const std::string& name,
               const std::string& object) const {
    Handle from(H5Dopen2(from_parent, name.c_str(), H5P_DEFAULT), H5Dclose);
    if (!from.valid()) cannot_read(object, "the dataset");
    Handle type(H5Dget_type(from), H5Tclose), space(H5Dget_space(from), H5Sclose);
    Handle dcpl(H5Dget_create_plist(from), H5Pclose);
    if (!type.valid() || !space.valid() || !dcpl.valid()) cannot_read(object, "its shape");
    if (holds_references(type)) refuse_references(object);
    filters_available(dcpl, object);
    const hid_t shared = shared_type(type, object);
    Handle to(H5Dcreate2(to_parent, name.c_str(), shared >= 0 ? shared : hid_t(type), space,
                         H5P_DEFAULT, dcpl, H5P_DEFAULT),
              H5Dclose);
    if (!to.valid()) cannot_write(object, "the dataset");
    // Variable-length values go through HDF5, which writes them to the new file's heap: their
    // stored chunks hold ids in the old file's (copied as stored, they had pointed at nothing).
    if (H5Pget_layout(dcpl) == H5D_CHUNKED && !holds_heap_ids(type))
      chunks(from, to, space, object);
    else
      rows(from, to, type, space, object);
    attributes(from, to, dcpl, object);
  }

  // A dataset's committed datatype as the target's, so that the datasets share it there as in
  // the source: the one copied already, else, for a type inside the group copied (one linked
  // after the dataset), one committed now without a name and linked when the copy reaches its
  // name. -1 for a transient type or one outside the group: the dataset keeps a copy of its own
  // (HDF5 makes a type committed in another file transient).
  hid_t shared_type(hid_t type, const std::string& object) const {
    if (H5Tcommitted(type) <= 0) return -1;
    H5O_info_t info{};
    if (H5Oget_info2(type, &info, H5O_INFO_BASIC) < 0) cannot_read(object, "its datatype");
    if (const auto taken = shared_types.find(info.addr); taken != shared_types.end())
      return taken->second;
    if (const auto seen = copied.find(info.addr); seen != copied.end()) {
      Handle opened(H5Topen2(target_file, seen->second.c_str(), H5P_DEFAULT), H5Tclose);
      if (!opened.valid()) cannot_write(object, "its datatype " + seen->second);
      return shared_types.emplace(info.addr, std::move(opened)).first->second;
    }
    std::string path(size_t(std::max<ssize_t>(H5Iget_name(type, nullptr, 0), 0)), '\0');
    if (!path.empty()) H5Iget_name(type, path.data(), path.size() + 1);
    if (path.rfind(root + "/", 0) != 0) return -1;
    Handle tcpl(H5Tget_create_plist(type), H5Pclose);
    Handle copy(H5Tcopy(type), H5Tclose);
    if (!tcpl.valid() || !copy.valid()) cannot_read(path, "the datatype");
    if (H5Tcommit_anon(target_file, copy, tcpl, H5P_DEFAULT) < 0)
      cannot_write(path, "the datatype");
    attributes(type, copy, tcpl, path);
    return shared_types.emplace(info.addr, std::move(copy)).first->second;
  }

  [[noreturn]] void refuse_references(const std::string& object) const {
    throw InputError(source_path, object,
                     "holds HDF5 object or region references, which point into this file: not "
                     "copied (a linebake cache has none)");
  }

  // Chunks go across as stored, but HDF5 creates a dataset only with its mandatory filters
  // registered: a bake without LZ4 keeping an LZ4 group had failed ("required filter 32004 is
  // not registered"; H5Ocopy had not asked). The plugins are looked for, and linebake's own LZ4
  // and Blosc filters (chunk_codec) stand in where they are missing.
  void filters_available(hid_t dcpl, const std::string& object) const {
    const int count = H5Pget_nfilters(dcpl);
    for (int i = 0; i < count; ++i) {
      unsigned flags = 0, config = 0;
      size_t values = 0;
      const H5Z_filter_t id =
          H5Pget_filter2(dcpl, unsigned(i), &flags, &values, nullptr, 0, nullptr, &config);
      // An optional filter HDF5 skips where it is missing; chunks go as stored either way.
      if (id < 0 || (flags & H5Z_FLAG_OPTIONAL) || H5Zfilter_avail(id) > 0) continue;
      if (id == H5Z_filter_t(kLz4Filter) || id == H5Z_filter_t(kBloscFilter))
        register_hdf5_filters();
      if (H5Zfilter_avail(id) <= 0)
        throw InputError(source_path, object,
                         "its HDF5 filter " + std::to_string(id) +
                             " is not available to copy it with (set HDF5_PLUGIN_PATH)");
    }
  }

  // Each stored chunk as it is (compressed, with its filter mask).
  void chunks(hid_t from, hid_t to, hid_t space, const std::string& object) const {
    hsize_t count = 0;
    if (H5Dget_num_chunks(from, space, &count) < 0) cannot_read(object, "its chunk index");
    const int rank = H5Sget_simple_extent_ndims(space);
    std::vector<hsize_t> offset(size_t(std::max(rank, 1)));
    std::vector<char> stored;
    for (hsize_t i = 0; i < count; ++i) {
      throw_if_interrupted();
      unsigned mask = 0;
      haddr_t address = 0;
      hsize_t size = 0;
      if (H5Dget_chunk_info(from, space, i, offset.data(), &mask, &address, &size) < 0)
        cannot_read(object, "chunk " + std::to_string(i));
      stored.resize(size_t(size));
      if (H5Dread_chunk(from, H5P_DEFAULT, offset.data(), &mask, stored.data()) < 0)
        cannot_read(object, "chunk " + std::to_string(i));
      if (H5Dwrite_chunk(to, H5P_DEFAULT, mask, offset.data(), size_t(size), stored.data()) < 0)
        cannot_write(object, "chunk " + std::to_string(i));
    }
  }

  // A dataset without chunks: slabs of rows along its first dimension.
  void rows(hid_t from, hid_t to, hid_t type, hid_t space, const std::string& object) const {
    const int rank = H5Sget_simple_extent_ndims(space);
    std::vector<hsize_t> dims(size_t(std::max(rank, 1)), 1);
    if (rank > 0) H5Sget_simple_extent_dims(space, dims.data(), nullptr);
    if (rank <= 0 || holds_heap_ids(type)) {
      const hssize_t n = H5Sget_simple_extent_npoints(space);
      if (n == 0) return;
      std::vector<char> values(size_t(std::max<hssize_t>(n, 1)) * H5Tget_size(type));
      if (H5Dread(from, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0)
        cannot_read(object, "its values");
      const herr_t written = H5Dwrite(to, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
      if (holds_heap_ids(type)) H5Dvlen_reclaim(type, space, H5P_DEFAULT, values.data());
      if (written < 0) cannot_write(object, "its values");
      return;
    }
    hsize_t row_bytes = H5Tget_size(type);
    for (int d = 1; d < rank; ++d) row_bytes *= dims[size_t(d)];
    const hsize_t slab = std::max<hsize_t>(1, slab_bytes / std::max<hsize_t>(row_bytes, 1));
    std::vector<char> values;
    std::vector<hsize_t> start(dims.size(), 0), extent = dims;
    for (hsize_t row = 0; row < dims[0]; row += slab) {
      throw_if_interrupted();
      start[0] = row;
      extent[0] = std::min(slab, dims[0] - row);
      values.resize(size_t(extent[0] * row_bytes));
      Handle file_space(H5Scopy(space), H5Sclose);
      Handle memory(H5Screate_simple(rank, extent.data(), nullptr), H5Sclose);
      H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start.data(), nullptr, extent.data(),
                          nullptr);
      if (H5Dread(from, type, memory, file_space, H5P_DEFAULT, values.data()) < 0)
        cannot_read(object, "rows from " + std::to_string(row));
      if (H5Dwrite(to, type, memory, file_space, H5P_DEFAULT, values.data()) < 0)
        cannot_write(object, "rows from " + std::to_string(row));
    }
  }

  // `from` exists as `to` already; its attributes and members follow.
  void group(hid_t from, hid_t to, const std::string& object) const {
    Handle gcpl(H5Gget_create_plist(from), H5Pclose);
    if (!gcpl.valid()) cannot_read(object, "the group");
    attributes(from, to, gcpl, object);
    H5G_info_t info{};
    if (H5Gget_info(from, &info) < 0) cannot_read(object, "its members");
    const H5_index_t index = index_of(gcpl, true);
    for (hsize_t i = 0; i < info.nlinks; ++i) {
      std::string name(
          size_t(std::max<ssize_t>(
              H5Lget_name_by_idx(from, ".", index, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT), 0)),
          '\0');
      if (H5Lget_name_by_idx(from, ".", index, H5_ITER_INC, i, name.data(), name.size() + 1,
                             H5P_DEFAULT) < 0)
        cannot_read(object, "member " + std::to_string(i));
      const std::string member = object + "/" + name;
      H5L_info_t link{};
      if (H5Lget_info(from, name.c_str(), &link, H5P_DEFAULT) < 0) cannot_read(member, "its link");
      if (link.type != H5L_TYPE_HARD) {
        symbolic_link(from, to, name, link, member);
        continue;
      }
      H5O_info_t kind{};
      if (H5Oget_info_by_name2(from, name.c_str(), &kind, H5O_INFO_BASIC, H5P_DEFAULT) < 0)
        cannot_read(member, "its kind");
      if (const auto seen = copied.find(kind.addr); seen != copied.end()) {
        if (H5Lcreate_hard(target_file, seen->second.c_str(), to, name.c_str(), H5P_DEFAULT,
                           H5P_DEFAULT) < 0)
          cannot_write(member, "a link to " + seen->second);
        continue;
      }
      copied[kind.addr] = member;
      if (kind.type == H5O_TYPE_DATASET) {
        dataset(from, to, name, member);
      } else if (kind.type == H5O_TYPE_GROUP) {
        Handle sub_from(H5Gopen2(from, name.c_str(), H5P_DEFAULT), H5Gclose);
        Handle sub_gcpl(sub_from.valid() ? H5Gget_create_plist(sub_from) : -1, H5Pclose);
        if (!sub_gcpl.valid()) cannot_read(member, "the group");
        Handle sub_to(
            H5Gcreate2(to, name.c_str(), H5P_DEFAULT, group_properties(sub_gcpl), H5P_DEFAULT),
            H5Gclose);
        if (!sub_to.valid()) cannot_write(member, "the group");
        group(sub_from, sub_to, member);
      } else if (kind.type == H5O_TYPE_NAMED_DATATYPE) {
        if (const auto early = shared_types.find(kind.addr); early != shared_types.end()) {
          // Committed for a dataset before, without a name.
          if (H5Olink(early->second, to, name.c_str(), H5P_DEFAULT, H5P_DEFAULT) < 0)
            cannot_write(member, "the datatype");
          continue;
        }
        Handle type(H5Topen2(from, name.c_str(), H5P_DEFAULT), H5Tclose);
        Handle tcpl(type.valid() ? H5Tget_create_plist(type) : -1, H5Pclose);
        Handle copy(type.valid() ? H5Tcopy(type) : -1, H5Tclose);
        if (!tcpl.valid() || !copy.valid()) cannot_read(member, "the datatype");
        if (H5Tcommit2(to, name.c_str(), copy, H5P_DEFAULT, tcpl, H5P_DEFAULT) < 0)
          cannot_write(member, "the datatype");
        attributes(type, copy, tcpl, member);
      } else {
        throw InputError(source_path, member, "neither a group, a dataset nor a datatype");
      }
    }
  }

  // A soft link as its path, an external one as its file and object: as written, not followed.
  void symbolic_link(hid_t from, hid_t to, const std::string& name, const H5L_info_t& link,
                     const std::string& member) const {
    std::vector<char> value(std::max<size_t>(link.u.val_size, 1));
    if (H5Lget_val(from, name.c_str(), value.data(), value.size(), H5P_DEFAULT) < 0)
      cannot_read(member, "its link");
    herr_t made = -1;
    if (link.type == H5L_TYPE_SOFT) {
      made = H5Lcreate_soft(value.data(), to, name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
    } else if (link.type == H5L_TYPE_EXTERNAL) {
      const char *file = nullptr, *object = nullptr;
      unsigned flags = 0;
      if (H5Lunpack_elink_val(value.data(), value.size(), &flags, &file, &object) < 0)
        cannot_read(member, "its external link");
      made = H5Lcreate_external(file, object, to, name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
    } else {
      throw InputError(source_path, member, "a user-defined link: not copied");
    }
    if (made < 0) cannot_write(member, "the link");
  }
};

}  // namespace

void copy_group_tree(hid_t source, const std::string& source_path, hid_t target,
                     const std::string& target_path, const std::string& group,
                     uint64_t slab_bytes) {
  const Copy copy{source_path, target_path, std::max<uint64_t>(slab_bytes, 1), target, group};
  Handle from(H5Gopen2(source, group.c_str(), H5P_DEFAULT), H5Gclose);
  if (!from.valid()) copy.cannot_read(group, "the group");
  if (H5O_info_t top{}; H5Oget_info2(from, &top, H5O_INFO_BASIC) >= 0)
    copy.copied[top.addr] = group;
  Handle gcpl(H5Gget_create_plist(from), H5Pclose);
  if (!gcpl.valid()) copy.cannot_read(group, "the group");
  Handle to(
      H5Gcreate2(target, group.c_str(), H5P_DEFAULT, Copy::group_properties(gcpl), H5P_DEFAULT),
      H5Gclose);
  if (!to.valid()) copy.cannot_write(group, "the group");
  copy.group(from, to, group);
}

}  // namespace linebake
