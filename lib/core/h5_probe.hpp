#pragma once
// Foreign HDF5 files are opened first in an isolated child (core/isolated.hpp) that walks the
// metadata linebake will touch: the superblock, the groups read, every object header, every
// attribute's value, each dataset's type, shape, filter pipeline and whole chunk index. HDF5
// 1.10.8 crashes on some malformed files (docs/reliability.md); the crash ends the child, and the
// caller gets an InputError naming the file. The data itself is read later, in-process.

#include <string>
#include <vector>

namespace linebake::h5 {

// Walks `objects` (absolute paths; a group is walked with everything under it; "/" is the whole
// file) and the root's attributes. Objects that do not exist are skipped: the reader decides what
// is missing. Throws InputError when the walk crashes, hangs, runs out of memory or fails.
void probe(const std::string& path, const std::vector<std::string>& objects = {"/"});

// The walk itself, in-process (the fuzz targets and tests call it to compare).
void walk_metadata(const std::string& path, const std::vector<std::string>& objects);

}  // namespace linebake::h5
