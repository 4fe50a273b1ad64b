#include "cache/cache.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tbb/info.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <ctime>

#include "core/error.hpp"
#include "core/hash.hpp"

namespace linebake {

using h5::Handle;

namespace {

constexpr unsigned kLz4Filter = 32004;    // registered id of the HDF5 LZ4 filter
constexpr unsigned kBloscFilter = 32001;  // registered id of the HDF5 Blosc filter
constexpr unsigned kBloscZstd = 5;        // Blosc's compressor code for zstd
constexpr const char* kHashAttribute = "xxh3_128";
constexpr const char* kFormatAttribute = "linebake_cache_format";
constexpr const char* kFormatVersion = "1";

template <class T>
hid_t native_type();
template <>
hid_t native_type<float>() {
  return H5T_NATIVE_FLOAT;
}
template <>
hid_t native_type<double>() {
  return H5T_NATIVE_DOUBLE;
}
template <>
hid_t native_type<uint8_t>() {
  return H5T_NATIVE_UINT8;
}
template <>
hid_t native_type<int16_t>() {
  return H5T_NATIVE_INT16;
}
template <>
hid_t native_type<uint16_t>() {
  return H5T_NATIVE_UINT16;
}
template <>
hid_t native_type<int32_t>() {
  return H5T_NATIVE_INT32;
}
template <>
hid_t native_type<uint32_t>() {
  return H5T_NATIVE_UINT32;
}
template <>
hid_t native_type<uint64_t>() {
  return H5T_NATIVE_UINT64;
}

// Little-endian file types, whatever the writing machine.
hid_t file_type(hid_t native) {
  if (H5Tequal(native, H5T_NATIVE_FLOAT) > 0) return H5T_IEEE_F32LE;
  if (H5Tequal(native, H5T_NATIVE_DOUBLE) > 0) return H5T_IEEE_F64LE;
  if (H5Tequal(native, H5T_NATIVE_UINT8) > 0) return H5T_STD_U8LE;
  if (H5Tequal(native, H5T_NATIVE_INT16) > 0) return H5T_STD_I16LE;
  if (H5Tequal(native, H5T_NATIVE_UINT16) > 0) return H5T_STD_U16LE;
  if (H5Tequal(native, H5T_NATIVE_INT32) > 0) return H5T_STD_I32LE;
  if (H5Tequal(native, H5T_NATIVE_UINT32) > 0) return H5T_STD_U32LE;
  return H5T_STD_U64LE;
}

void require_filter(unsigned id, const char* name, const char* package) {
  if (H5Zfilter_avail(id) <= 0)
    throw Error(std::string("compression ") + name + " needs the HDF5 filter plugin from " +
                package + " (not found; set HDF5_PLUGIN_PATH if it is elsewhere)");
}

}  // namespace

Compression parse_compression(const std::string& name) {
  if (name == "none") return Compression::None;
  if (name == "deflate") return Compression::Deflate;
  if (name == "lz4") return Compression::Lz4;
  if (name == "blosc-zstd") return Compression::BloscZstd;
  throw Error("unknown compression '" + name + "' (none | deflate | lz4 | blosc-zstd)");
}

const char* to_string(Compression compression) {
  switch (compression) {
    case Compression::None:
      return "none";
    case Compression::Deflate:
      return "deflate";
    case Compression::Lz4:
      return "lz4";
    case Compression::BloscZstd:
      return "blosc-zstd";
  }
  return "none";
}

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

nlohmann::json to_json(const Provenance& p) {
  return {{"step", p.step},
          {"key", p.key},
          {"input_hash", p.input_hash},
          {"parameters", p.parameters},
          {"stats", p.stats},
          {"linebake_version", p.linebake_version},
          {"created", p.created},
          {"build",
           {{"wall_s", p.build.wall_s},
            {"cpu_s", p.build.cpu_s},
            {"rss_before_bytes", p.build.rss_before},
            {"peak_rss_bytes", p.build.peak_rss},
            {"peak_is_step_local", p.build.peak_is_step_local},
            {"threads", p.threads}}},
          {"memory_bytes", p.memory_bytes},
          {"disk_bytes", p.disk_bytes},
          {"compression", p.compression}};
}

Provenance provenance_from_json(const nlohmann::json& j) {
  Provenance p;
  p.step = j.at("step");
  p.key = j.at("key");
  p.input_hash = j.at("input_hash");
  p.parameters = j.at("parameters");
  p.stats = j.value("stats", nlohmann::json::object());
  p.linebake_version = j.at("linebake_version");
  p.created = j.value("created", "");
  const auto& b = j.at("build");
  p.build.wall_s = b.at("wall_s");
  p.build.cpu_s = b.at("cpu_s");
  p.build.rss_before = b.at("rss_before_bytes");
  p.build.peak_rss = b.at("peak_rss_bytes");
  p.build.peak_is_step_local = b.at("peak_is_step_local");
  p.threads = b.value("threads", uint64_t{0});
  p.memory_bytes = j.at("memory_bytes");
  p.disk_bytes = j.at("disk_bytes");
  p.compression = j.value("compression", "");
  return p;
}

// ---- writer ----

CacheWriter::CacheWriter(const std::string& path, Compression compression, int level)
    : file_(path), compression_(compression), level_(level) {
  h5::init();
  if (compression == Compression::Lz4) require_filter(kLz4Filter, "lz4", "hdf5-filter-plugin");
  if (compression == Compression::BloscZstd)
    require_filter(kBloscFilter, "blosc-zstd", "hdf5-filter-plugin-blosc-serial");
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
  H5Pset_link_creation_order(fcpl, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  // Page-aligned datasets from 4 KiB up, so uncompressed ones can be viewed in a mapping.
  H5Pset_alignment(fapl, 4096, 4096);
  h5_ = Handle(H5Fcreate(file_.temp_path().c_str(), H5F_ACC_TRUNC, fcpl, fapl), H5Fclose);
  if (!h5_.valid()) throw OutputError(path, "cannot create (" + h5::last_error() + ")");
  write_attribute("/", kFormatAttribute, kFormatVersion);
  write_attribute("/", "linebake_version", LINEBAKE_VERSION);
}

CacheWriter::~CacheWriter() {
  h5_.reset();
}

void CacheWriter::set_progress(ProgressFn progress, uint64_t total_bytes) {
  progress_ = std::move(progress);
  progress_total_ = total_bytes;
  progress_done_ = 0;
}

void CacheWriter::create_group(const std::string& group) {
  if (H5Lexists(h5_, group.c_str(), H5P_DEFAULT) > 0) return;
  Handle lcpl(H5Pcreate(H5P_LINK_CREATE), H5Pclose);
  H5Pset_create_intermediate_group(lcpl, 1);
  Handle gcpl(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
  H5Pset_link_creation_order(gcpl, H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
  Handle g(H5Gcreate2(h5_, group.c_str(), lcpl, gcpl, H5P_DEFAULT), H5Gclose);
  if (!g.valid()) throw OutputError(path(), "cannot create group " + group);
}

void CacheWriter::copy_group(const std::string& source_path, const std::string& group) {
  Handle source(H5Fopen(source_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!source.valid()) throw InputError(source_path, "", "cannot open to copy " + group);
  const size_t slash = group.find_last_of('/');
  if (slash > 0) create_group(group.substr(0, slash));
  if (H5Ocopy(source, group.c_str(), h5_, group.c_str(), H5P_DEFAULT, H5P_DEFAULT) < 0)
    throw OutputError(
        path(), "cannot copy " + group + " from " + source_path + " (" + h5::last_error() + ")");
}

void CacheWriter::write_attribute(const std::string& object, const std::string& name,
                                  const std::string& value) {
  Handle o(H5Oopen(h5_, object.c_str(), H5P_DEFAULT), H5Oclose);
  if (!o.valid() || !h5::write_string_attribute(o, name, value))
    throw OutputError(path(), "cannot write attribute " + name + " of " + object);
}

void CacheWriter::write_provenance(const std::string& group, const Provenance& provenance) {
  write_attribute(group, "provenance", to_json(provenance).dump());
}

template <class T>
uint64_t CacheWriter::write(const std::string& dataset, const T* data, uint64_t rows,
                            uint64_t columns) {
  return write_raw(dataset, native_type<T>(), data, sizeof(T), rows, columns);
}

uint64_t CacheWriter::write_raw(const std::string& dataset, hid_t type, const void* data,
                                size_t element, uint64_t rows, uint64_t columns) {
  const size_t slash = dataset.find_last_of('/');
  if (slash > 0) create_group(dataset.substr(0, slash));
  const int rank = columns ? 2 : 1;
  const hsize_t dims[2] = {rows, columns ? columns : 1};
  const uint64_t row_bytes = element * (columns ? columns : 1);
  const uint64_t bytes = rows * row_bytes;
  Handle space(H5Screate_simple(rank, dims, nullptr), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  const bool compressed = compression_ != Compression::None && rows > 0;
  if (compressed) {
    // About 1 MiB per chunk: large enough for the codecs, small enough for HDF5's chunk cache.
    const hsize_t chunk[2] = {std::clamp<hsize_t>((1 << 20) / row_bytes, 1, rows), dims[1]};
    H5Pset_chunk(dcpl, rank, chunk);
    H5Pset_shuffle(dcpl);
    if (compression_ == Compression::Deflate) {
      H5Pset_deflate(dcpl, level_ < 0 ? 4 : unsigned(level_));
    } else if (compression_ == Compression::Lz4) {
      H5Pset_filter(dcpl, kLz4Filter, H5Z_FLAG_MANDATORY, 0, nullptr);
    } else {
      // Blosc's own shuffle is off: HDF5's shuffle above already did it.
      const unsigned cd[7] = {0, 0, 0, 0, unsigned(level_ < 0 ? 5 : level_), 0, kBloscZstd};
      H5Pset_filter(dcpl, kBloscFilter, H5Z_FLAG_MANDATORY, 7, cd);
    }
    H5Pset_fletcher32(dcpl);
  } else {
    H5Pset_layout(dcpl, H5D_CONTIGUOUS);
    H5Pset_alloc_time(dcpl, H5D_ALLOC_TIME_EARLY);
  }
  Handle d(H5Dcreate2(h5_, dataset.c_str(), file_type(type), space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
           H5Dclose);
  if (!d.valid())
    throw OutputError(path(), "cannot create dataset " + dataset + " (" + h5::last_error() + ")");
  // Written in slabs of about 64 MiB so a terminal can show progress.
  const uint64_t slab_rows = std::max<uint64_t>(1, (uint64_t{64} << 20) / row_bytes);
  for (uint64_t first = 0; first < rows; first += slab_rows) {
    const hsize_t start[2] = {first, 0};
    const hsize_t count[2] = {std::min(slab_rows, rows - first), dims[1]};
    Handle file_space(H5Dget_space(d), H5Sclose);
    H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr);
    Handle memory_space(H5Screate_simple(rank, count, nullptr), H5Sclose);
    const auto* bytes_at = static_cast<const unsigned char*>(data) + first * row_bytes;
    if (H5Dwrite(d, type, memory_space, file_space, H5P_DEFAULT, bytes_at) < 0)
      throw OutputError(path(), "cannot write dataset " + dataset + " (" + h5::last_error() + ")");
    progress_done_ += count[0] * row_bytes;
    if (progress_) progress_(progress_done_, progress_total_);
  }
  if (!h5::write_string_attribute(d, kHashAttribute, hash_bytes(data, bytes)))
    throw OutputError(path(), "cannot write the hash of " + dataset);
  return H5Dget_storage_size(d);
}

void CacheWriter::commit() {
  if (H5Fflush(h5_, H5F_SCOPE_GLOBAL) < 0) throw OutputError(path(), "cannot flush");
  h5_.reset();
  file_.commit();
}

template uint64_t CacheWriter::write(const std::string&, const float*, uint64_t, uint64_t);
template uint64_t CacheWriter::write(const std::string&, const double*, uint64_t, uint64_t);
template uint64_t CacheWriter::write(const std::string&, const uint8_t*, uint64_t, uint64_t);
template uint64_t CacheWriter::write(const std::string&, const int16_t*, uint64_t, uint64_t);
template uint64_t CacheWriter::write(const std::string&, const uint16_t*, uint64_t, uint64_t);
template uint64_t CacheWriter::write(const std::string&, const int32_t*, uint64_t, uint64_t);
template uint64_t CacheWriter::write(const std::string&, const uint32_t*, uint64_t, uint64_t);
template uint64_t CacheWriter::write(const std::string&, const uint64_t*, uint64_t, uint64_t);

// ---- reader ----

CacheReader::CacheReader(const std::string& path, bool verify) : path_(path), verify_(verify) {
  h5::init();
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw InputError(path, "", "no such cache file");
  file_size_ = static_cast<uint64_t>(st.st_size);
  if (H5Fis_hdf5(path.c_str()) <= 0)
    throw InputError(path, "", "not an HDF5 file (or its superblock is damaged)");
  h5_ = Handle(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!h5_.valid())
    throw InputError(
        path, "", "cannot open the cache: " + h5::last_error() + " (truncated or damaged file?)");
  std::string format;
  if (!h5::read_string_attribute(h5_, kFormatAttribute, format))
    throw InputError(path, "",
                     "an HDF5 file but not a linebake cache (no " + std::string(kFormatAttribute) +
                         " attribute)");
  if (format != kFormatVersion)
    throw InputError(path, "",
                     "cache format " + format + " is not supported (this linebake reads " +
                         kFormatVersion + ")");
  // The whole file, read-only: uncompressed datasets are handed out as views into it.
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd >= 0 && file_size_ > 0) {
    void* p = mmap(nullptr, file_size_, PROT_READ, MAP_SHARED, fd, 0);
    if (p != MAP_FAILED) {
      const uint64_t size = file_size_;
      mapping_ = std::shared_ptr<const void>(
          p, [size](const void* q) { munmap(const_cast<void*>(q), size); });
    }
  }
  if (fd >= 0) ::close(fd);
}

CacheReader::~CacheReader() = default;

bool CacheReader::exists(const std::string& object) const {
  if (object == "/") return true;
  // Every prefix must exist for H5Lexists to answer.
  size_t at = 0;
  while ((at = object.find('/', at + 1)) != std::string::npos) {
    if (H5Lexists(h5_, object.substr(0, at).c_str(), H5P_DEFAULT) <= 0) return false;
  }
  return H5Lexists(h5_, object.c_str(), H5P_DEFAULT) > 0;
}

std::vector<std::string> CacheReader::members(const std::string& group) const {
  return exists(group) ? h5::group_members(h5_, group) : std::vector<std::string>{};
}

std::optional<std::string> CacheReader::attribute(const std::string& object,
                                                  const std::string& name) const {
  if (!exists(object)) return std::nullopt;
  Handle o(H5Oopen(h5_, object.c_str(), H5P_DEFAULT), H5Oclose);
  std::string value;
  if (!o.valid() || !h5::read_string_attribute(o, name, value)) return std::nullopt;
  return value;
}

std::optional<Provenance> CacheReader::provenance(const std::string& group) const {
  const auto text = attribute(group, "provenance");
  if (!text) return std::nullopt;
  try {
    return provenance_from_json(nlohmann::json::parse(*text));
  } catch (const std::exception& e) {
    throw InputError(path_, "group " + group, std::string("unreadable provenance: ") + e.what());
  }
}

uint64_t CacheReader::stored_bytes(const std::string& dataset) const {
  Handle d(H5Dopen2(h5_, dataset.c_str(), H5P_DEFAULT), H5Dclose);
  return d.valid() ? H5Dget_storage_size(d) : 0;
}

template <class T>
Array<T> CacheReader::read(const std::string& dataset, size_t expected) const {
  Array<unsigned char> raw = read_raw(dataset, native_type<T>(), sizeof(T), expected);
  return Array<T>(raw.owner(), reinterpret_cast<const T*>(raw.data()), raw.size() / sizeof(T));
}

Array<unsigned char> CacheReader::read_raw(const std::string& dataset, hid_t type, size_t element,
                                           size_t expected) const {
  const std::string where = "dataset " + dataset;
  if (!exists(dataset)) throw InputError(path_, where, "missing");
  Handle d(H5Dopen2(h5_, dataset.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.valid()) throw InputError(path_, where, "cannot open: " + h5::last_error());
  uint64_t count = 1;
  for (hsize_t n : h5::shape_of(d)) count *= n;
  if (expected != SIZE_MAX && count != expected)
    throw InputError(path_, where,
                     std::to_string(count) + " values, expected " + std::to_string(expected));
  Handle stored_type(H5Dget_type(d), H5Tclose);
  if (H5Tget_size(stored_type) != element || H5Tget_class(stored_type) != H5Tget_class(type))
    throw InputError(path_, where, "stored with an unexpected type");
  const uint64_t bytes = count * element;

  Array<unsigned char> out;
  Handle dcpl(H5Dget_create_plist(d), H5Pclose);
  const haddr_t offset = H5Dget_offset(d);
  const bool viewable = mapping_ && H5Pget_layout(dcpl) == H5D_CONTIGUOUS &&
                        H5Pget_nfilters(dcpl) == 0 && offset != HADDR_UNDEF && offset % 64 == 0 &&
                        H5Tequal(stored_type, file_type(type)) > 0 &&
                        H5Tequal(file_type(type), type) > 0;  // little-endian host
  if (viewable) {
    if (offset + bytes > file_size_)
      throw InputError(path_, where,
                       "the file is truncated (data ends at byte " +
                           std::to_string(offset + bytes) + ", file has " +
                           std::to_string(file_size_) + ")");
    out = Array<unsigned char>(mapping_, static_cast<const unsigned char*>(mapping_.get()) + offset,
                               bytes);
  } else {
    out = Array<unsigned char>(bytes);
    if (bytes && H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
      throw InputError(path_, where,
                       "cannot read: " + h5::last_error() + " (corrupt or truncated data)");
  }
  if (verify_) {
    std::string stored;
    if (!h5::read_string_attribute(d, kHashAttribute, stored))
      throw InputError(path_, where, "no stored hash to verify against");
    if (stored != hash_bytes(out.data(), out.size()))
      throw InputError(path_, where, "checksum mismatch: the data is corrupt");
  }
  return out;
}

template Array<float> CacheReader::read(const std::string&, size_t) const;
template Array<double> CacheReader::read(const std::string&, size_t) const;
template Array<uint8_t> CacheReader::read(const std::string&, size_t) const;
template Array<int16_t> CacheReader::read(const std::string&, size_t) const;
template Array<uint16_t> CacheReader::read(const std::string&, size_t) const;
template Array<int32_t> CacheReader::read(const std::string&, size_t) const;
template Array<uint32_t> CacheReader::read(const std::string&, size_t) const;
template Array<uint64_t> CacheReader::read(const std::string&, size_t) const;

}  // namespace linebake
