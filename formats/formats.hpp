#pragma once
// Per-format entry points. Readers take the file path: formats that can be read piece by piece
// open a LineReader (lines/line_reader.hpp), the others read the whole file. Writers write to the
// path given (the registry hands them a temporary name and renames it when they return).

#include <memory>
#include <string>

#include "formats/registry.hpp"
#include "lines/line_reader.hpp"

namespace linebake::formats {

LineSet read_obj(const std::string& path, const ReadOptions& options);
void write_obj(const LineSet& lines, const std::string& path, const WriteOptions& options);

std::unique_ptr<LineReader> open_binlines(const std::string& path, const ReadOptions& options);
// Writes batch by batch through a temporary file; the header's line count is filled in at close.
std::unique_ptr<LineWriter> open_binlines_writer(const std::string& path, const LineSet& header,
                                                 const WriteOptions& options);
void write_binlines(const LineSet& lines, const std::string& path, const WriteOptions& options);

LineSet read_vtk_legacy(const std::string& path, const ReadOptions& options);
void write_vtk_legacy(const LineSet& lines, const std::string& path, const WriteOptions& options);

LineSet read_vtp(const std::string& path, const ReadOptions& options);
void write_vtp(const LineSet& lines, const std::string& path, const WriteOptions& options);

std::unique_ptr<LineReader> open_netcdf(const std::string& path, const ReadOptions& options);
// What the NetCDF reader touches at open, walked first in an isolated child (core/isolated.hpp,
// and linebake-probe): the NetCDF library, and HDF5 under NetCDF-4, crash on some malformed
// files (docs/reliability.md). Throws on a file NetCDF refuses.
void walk_netcdf_metadata(const std::string& path);

// The plain layout, or the line set of a linebake asset cache (/lines).
std::unique_ptr<LineReader> open_hdf5(const std::string& path, const ReadOptions& options);
void write_hdf5(const LineSet& lines, const std::string& path, const WriteOptions& options);

std::unique_ptr<LineReader> open_trk(const std::string& path, const ReadOptions& options);
std::unique_ptr<LineReader> open_tck(const std::string& path, const ReadOptions& options);

std::unique_ptr<LineReader> open_csv(const std::string& path, const ReadOptions& options);
void write_csv(const LineSet& lines, const std::string& path, const WriteOptions& options);

}  // namespace linebake::formats
