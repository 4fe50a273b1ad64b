#pragma once
// One HDF5 group copied into another file object by object: its subgroups, datasets (chunks
// as stored, without decoding) and attributes, in creation order where it is tracked. In place
// of H5Ocopy, whose error path in HDF5 1.10 crashes (H5T_close_real under H5O_copy_header_map)
// when the disk fills during the copy: here a failed write is an OutputError like any other.

#include <hdf5.h>

#include <cstdint>
#include <string>

namespace linebake {

// Copies `group` of `source` (opened from `source_path`) to the same path in `target` (the file
// `target_path`); the groups above it must exist there, the group itself must not. Chunks go as
// stored but for variable-length values (read and written through HDF5, whose heap ids are the
// file's own), datasets without chunks `slab_bytes` of rows at a time; soft and external links
// as written; an object linked twice (or a group linked into itself) copied once and linked again.
// A committed datatype is copied as one, and the datasets in the group that used it use the
// copy (one linked after them is committed first without a name, then linked in its place);
// a dataset whose committed type lies outside the group, and an attribute with a committed
// type, get their own copy of the type (HDF5 makes a type committed in another file transient).
// Object and region references are refused. Throws
// InputError for what cannot be read, OutputError for what cannot be written, Interrupted
// between chunks on a signal.
void copy_group_tree(hid_t source, const std::string& source_path, hid_t target,
                     const std::string& target_path, const std::string& group,
                     uint64_t slab_bytes = uint64_t{64} << 20);

}  // namespace linebake
