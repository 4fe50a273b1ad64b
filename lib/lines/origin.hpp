#pragma once
// A local origin for lines far from 0. float32 keeps 24 bits: at UTM eastings and northings
// (1e5 to 1e7 m) or Earth-centred coordinates (6.4e6 m) it steps by 0.5 m, so a trajectory's
// fine structure is gone before any stage sees it. Such a line set keeps its positions relative
// to an origin held in double (world = origin + position, added in double): readers subtract it
// where they convert a file's numbers to float32, every stage works near 0, and the exports add
// it back (CSV, OBJ and VTK as float64 world coordinates, glTF as its node's translation, OpenVDB
// as its grids' transform, linebake's HDF5 as an `origin` attribute beside the float32 points).
// It is the relative-to-centre convention of 3D Tiles (RTC_CENTER) and of glTF viewers'
// translated nodes. The origin travels as the line set's metadata "origin": three numbers, the
// shortest that read back to the same doubles, separated by spaces.

#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "lines/line_set.hpp"

namespace linebake {

using Origin = std::array<double, 3>;

inline constexpr const char* kOriginKey = "origin";
// An "origin" a file's metadata carries that is not its points' frame (a VTK field, a NetCDF or
// foreign HDF5 attribute: a grid's corner, a seed point, text) is kept under this name instead.
inline constexpr const char* kSourceOriginKey = "source_origin";

// "x y z" as above.
std::string origin_text(const Origin& origin);
// The three numbers of origin_text (or separated by commas, as an option gives them); nullopt
// unless exactly three finite numbers.
std::optional<Origin> parse_origin(std::string_view text);

// The line set's origin: its metadata "origin", {0, 0, 0} without one. Throws InputError naming
// `where` when the metadata is not three finite numbers.
Origin origin_of(const LineSet& lines, const std::string& where = "metadata");
// The same from metadata alone (a cache's /lines, read without the lines).
Origin origin_of(const std::map<std::string, std::string>& metadata,
                 const std::string& where = "metadata");
bool has_origin(const LineSet& lines);
// origin_of where the line set has an origin, else none: what a writer of world coordinates asks.
std::optional<Origin> optional_origin(const LineSet& lines, const std::string& where = "metadata");
// The metadata without "origin": what a format that holds world coordinates stores beside them.
std::map<std::string, std::string> metadata_without_origin(const LineSet& lines);
// Sets the metadata "origin" (an all-zero origin is stored too: the lines were placed so).
void set_origin(LineSet& lines, const Origin& origin);
// Renames the metadata "origin" to "source_origin" (kept as it was written; where the file has a
// "source_origin" of its own, that one is kept and the "origin" dropped).
void keep_as_source_origin(std::map<std::string, std::string>& metadata);

// A world coordinate as a position relative to `origin`: subtracted in double, then rounded to
// float32 once. NaN and infinity stay what they are.
inline float to_local(double world, double origin) {
  return static_cast<float>(world - origin);
}
// to_local, and false where a finite world coordinate lies farther from the origin than float32
// reaches (the position would be infinite): what a reader that refuses such a number without an
// origin refuses with one.
inline bool to_local_in_range(double world, double origin, float& local) {
  local = to_local(world, origin);
  return !std::isinf(local) || std::isinf(world);
}
inline double to_world(float local, double origin) {
  return static_cast<double>(local) + origin;
}
// Positions (x y z triples) moved by -`by`, each coordinate rounded once: how a float32 source
// (binlines, TrackVis, MRtrix, a frame already local) is brought to another origin.
void shift_positions(std::span<float> xyz, const Origin& by);

// `--origin auto`: the first valid point (valid_point), each coordinate rounded to an integer,
// so that the lines lie near 0 and the origin reads as a plain number.
Origin rounded_origin(const Origin& point);

}  // namespace linebake
