// The cache's own filter pipeline (chunk_codec) against HDF5's: chunks linebake encodes read back
// through stock HDF5's filtered path, chunks HDF5's filters wrote decode with linebake's code,
// and a dataset streamed in uneven pieces stores the same chunks as one written whole.

#include <gtest/gtest.h>
#include <hdf5.h>
#include <zlib.h>

#include <cstring>
#include <filesystem>
#include <numeric>
#include <random>

#include "cache/cache.hpp"
#include "cache/chunk_codec.hpp"
#include "cache/chunk_reader.hpp"
#include "core/error.hpp"
#include "core/h5.hpp"
#include "test_util.hpp"

namespace linebake {
namespace {

using h5::Handle;

// HDF5's H5_checksum_fletcher32 (H5checksum.c) as written there: sums folded every 360 words.
uint32_t fletcher32_as_hdf5_writes_it(const uint8_t* data, size_t bytes) {
  size_t len = bytes / 2;
  uint32_t sum1 = 0, sum2 = 0;
  while (len) {
    size_t tlen = len > 360 ? 360 : len;
    len -= tlen;
    do {
      sum1 += uint32_t(uint16_t(data[0]) << 8) | uint16_t(data[1]);
      data += 2;
      sum2 += sum1;
    } while (--tlen);
    sum1 = (sum1 & 0xffff) + (sum1 >> 16);
    sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  }
  if (bytes % 2) {
    sum1 += uint32_t(uint16_t(*data) << 8);
    sum2 += sum1;
    sum1 = (sum1 & 0xffff) + (sum1 >> 16);
    sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  }
  sum1 = (sum1 & 0xffff) + (sum1 >> 16);
  sum2 = (sum2 & 0xffff) + (sum2 >> 16);
  return (sum2 << 16) | sum1;
}

std::vector<uint8_t> random_bytes(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<uint8_t> v(n);
  for (auto& b : v) b = uint8_t(rng());
  return v;
}

TEST(ChunkCodec, Fletcher32EqualsHdf5sFoldedSums) {
  for (size_t n : {0, 1, 2, 3, 719, 720, 721, 1000, 65536 * 2 + 3, 1 << 20}) {
    const auto data = random_bytes(n, uint32_t(n));
    EXPECT_EQ(fletcher32(data.data(), n), fletcher32_as_hdf5_writes_it(data.data(), n)) << n;
  }
  // The edge cases of the folding: all zero, and sums that are multiples of 65535.
  const std::vector<uint8_t> zeros(1000, 0), ones(1000, 0xff);
  EXPECT_EQ(fletcher32(zeros.data(), 1000), 0u);
  EXPECT_EQ(fletcher32(ones.data(), 1000), fletcher32_as_hdf5_writes_it(ones.data(), 1000));
  EXPECT_EQ(fletcher32(ones.data(), 1), fletcher32_as_hdf5_writes_it(ones.data(), 1));
}

TEST(ChunkCodec, ShuffleIsHdf5sByteTransposeAndInverts) {
  for (size_t size : {1, 2, 3, 4, 8}) {
    for (size_t n : {0, 1, 7, 16, 17, 31, 1000, 4099}) {
      const size_t bytes = n * size + (size > 1 ? 1 : 0);  // a leftover byte stays last
      const auto in = random_bytes(bytes, uint32_t(size * 100000 + n));
      std::vector<uint8_t> out(bytes), back(bytes);
      shuffle_bytes(in.data(), bytes, size, out.data());
      const size_t elements = bytes / size;
      if (elements > 1 && size > 1) {
        for (size_t i = 0; i < elements; ++i)
          for (size_t k = 0; k < size; ++k)
            ASSERT_EQ(out[k * elements + i], in[i * size + k]) << size << " " << n;
        EXPECT_EQ(out.back(), in.back());
      } else {
        EXPECT_EQ(out, in);
      }
      unshuffle_bytes(out.data(), bytes, size, back.data());
      EXPECT_EQ(back, in) << size << " " << n;
    }
  }
}

// Floats with structure (a codec has something to find) and noise (so it cannot find all).
std::vector<float> sample_values(size_t n) {
  std::vector<float> v(n);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> noise(-1, 1);
  for (size_t i = 0; i < n; ++i) v[i] = float(i % 977) * 0.25f + noise(rng);
  return v;
}

const Compression kCodecs[] = {Compression::Lz4, Compression::Deflate, Compression::BloscZstd};

class ChunkCodecHdf5 : public ::testing::TestWithParam<Compression> {};

// linebake writes (its codec, H5Dwrite_chunk); HDF5 reads with its own filters and plugins.
TEST_P(ChunkCodecHdf5, StockHdf5ReadsWhatLinebakeEncodes) {
  test::TempDir dir;
  const std::string path = dir.file("c.lbc.h5");
  const size_t rows = 300001;  // 3 columns: 3.4 MiB, so several chunks and a padded edge chunk
  const std::vector<float> values = sample_values(rows * 3);
  {
    CacheWriter writer(path, GetParam());
    writer.write("/data", values.data(), rows, 3);
    writer.commit();
  }
  // Plain HDF5 C API from here: no linebake code reads the file.
  h5::init();  // registers the plugin directory, as HDF5_PLUGIN_PATH would
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  ASSERT_TRUE(file.valid());
  Handle d(H5Dopen2(file, "/data", H5P_DEFAULT), H5Dclose);
  ASSERT_TRUE(d.valid());
  Handle dcpl(H5Dget_create_plist(d), H5Pclose);
  EXPECT_EQ(H5Pget_nfilters(dcpl), 3);
  hsize_t chunks = 0;
  Handle space(H5Dget_space(d), H5Sclose);
  ASSERT_GE(H5Dget_num_chunks(d, space, &chunks), 0);
  EXPECT_GT(chunks, 3u);
  std::vector<float> read(values.size(), -1.0f);
  ASSERT_GE(H5Dread(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, read.data()), 0);
  EXPECT_EQ(read, values);
  EXPECT_LT(H5Dget_storage_size(d), values.size() * sizeof(float));  // it did compress
}

// HDF5 writes with its filter pipeline; linebake's decoder reads the raw chunks.
TEST_P(ChunkCodecHdf5, LinebakeDecodesWhatHdf5sFiltersStore) {
  test::TempDir dir;
  const std::string path = dir.file("h.h5");
  const size_t rows = 100000, chunk_rows = 8192;
  const std::vector<float> values = sample_values(rows);
  h5::init();
  {
    Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
    const hsize_t dims[1] = {rows}, chunk[1] = {chunk_rows};
    Handle space(H5Screate_simple(1, dims, nullptr), H5Sclose);
    Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
    H5Pset_chunk(dcpl, 1, chunk);
    H5Pset_shuffle(dcpl);
    if (GetParam() == Compression::Deflate) {
      H5Pset_deflate(dcpl, 4);
    } else if (GetParam() == Compression::Lz4) {
      H5Pset_filter(dcpl, kLz4Filter, H5Z_FLAG_MANDATORY, 0, nullptr);
    } else {
      const unsigned cd[7] = {0, 0, 0, 0, 5, 0, kBloscZstd};
      H5Pset_filter(dcpl, kBloscFilter, H5Z_FLAG_MANDATORY, 7, cd);
    }
    H5Pset_fletcher32(dcpl);
    Handle d(H5Dcreate2(file, "/data", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT),
             H5Dclose);
    ASSERT_TRUE(d.valid());
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()), 0);
  }
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  Handle d(H5Dopen2(file, "/data", H5P_DEFAULT), H5Dclose);
  const ChunkCodec codec{GetParam(), -1, sizeof(float)};
  std::vector<char> stored, raw, scratch;
  for (size_t c = 0; c * chunk_rows < rows; ++c) {
    const hsize_t offset[1] = {c * chunk_rows};
    hsize_t bytes = 0;
    ASSERT_GE(H5Dget_chunk_storage_size(d, offset, &bytes), 0);
    stored.resize(bytes);
    uint32_t mask = 0;
    ASSERT_GE(H5Dread_chunk(d, H5P_DEFAULT, offset, &mask, stored.data()), 0);
    decode_chunk(codec, mask, stored.data(), stored.size(), chunk_rows * sizeof(float), raw,
                 scratch);
    const size_t n = std::min(chunk_rows, rows - c * chunk_rows);
    ASSERT_EQ(std::memcmp(raw.data(), values.data() + c * chunk_rows, n * sizeof(float)), 0) << c;
  }
  // read_cache_rows: any range of rows, across chunk boundaries, is what was written.
  const std::pair<size_t, size_t> ranges[] = {
      {0, rows}, {chunk_rows - 3, 7}, {rows - 5, 5}, {chunk_rows, chunk_rows}};
  for (const auto& [first_row, count] : ranges) {
    std::vector<float> got(count, -1.0f);
    ASSERT_TRUE(read_cache_rows(d, H5T_NATIVE_FLOAT, first_row, count, got.data()));
    ASSERT_EQ(std::memcmp(got.data(), values.data() + first_row, count * sizeof(float)), 0)
        << first_row << " " << count;
  }
  // Read as another type, it is not read_cache_rows' to convert: H5Dread's.
  std::vector<double> as_double(rows);
  EXPECT_FALSE(read_cache_rows(d, H5T_NATIVE_DOUBLE, 0, rows, as_double.data()));
  // A flipped byte fails the checksum, with a message saying so.
  const hsize_t first[1] = {0};
  hsize_t bytes = 0;
  H5Dget_chunk_storage_size(d, first, &bytes);
  stored.resize(bytes);
  uint32_t mask = 0;
  H5Dread_chunk(d, H5P_DEFAULT, first, &mask, stored.data());
  stored[stored.size() / 2] ^= 0x10;
  try {
    decode_chunk(codec, mask, stored.data(), stored.size(), chunk_rows * sizeof(float), raw,
                 scratch);
    FAIL() << "corrupt chunk decoded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("Fletcher-32"), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(Codecs, ChunkCodecHdf5, ::testing::ValuesIn(kCodecs),
                         [](const auto& param_info) {
                           std::string name = to_string(param_info.param);
                           std::erase(name, '-');
                           return name;
                         });

// The raw bytes of every chunk of a dataset, as stored.
std::vector<std::vector<char>> stored_chunks(const std::string& path, const std::string& name) {
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  Handle d(H5Dopen2(file, name.c_str(), H5P_DEFAULT), H5Dclose);
  Handle space(H5Dget_space(d), H5Sclose);
  hsize_t count = 0;
  H5Dget_num_chunks(d, space, &count);
  std::vector<std::vector<char>> chunks;
  for (hsize_t i = 0; i < count; ++i) {
    hsize_t offset[2] = {0, 0}, size = 0;
    unsigned mask = 0;
    haddr_t address = 0;
    H5Dget_chunk_info(d, space, i, offset, &mask, &address, &size);
    std::vector<char> bytes(size);
    uint32_t read_mask = 0;
    H5Dread_chunk(d, H5P_DEFAULT, offset, &read_mask, bytes.data());
    chunks.push_back(std::move(bytes));
  }
  return chunks;
}

TEST(DatasetStream, UnevenAppendsStoreTheSameChunksAndHash) {
  test::TempDir dir;
  const size_t rows = 250000;
  std::vector<uint32_t> values(rows * 2);
  std::iota(values.begin(), values.end(), 17u);
  for (Compression c : {Compression::Lz4, Compression::None}) {
    const std::string whole = dir.file("whole.h5"), pieces = dir.file("pieces.h5");
    {
      CacheWriter w(whole, c);
      w.write("/v", values.data(), rows, 2);
      w.commit();
    }
    {
      CacheWriter w(pieces, c);
      DatasetStream s = w.stream<uint32_t>("/v", rows, 2);
      size_t at = 0;
      for (size_t step : {1, 3, 131072, 7, 65536, 100000}) {
        const size_t n = std::min(step, rows - at);
        s.append(values.data() + 2 * at, n);
        at += n;
      }
      s.append(values.data() + 2 * at, rows - at);
      s.close();
      w.commit();
    }
    const CacheReader a(whole), b(pieces);
    EXPECT_EQ(a.attribute("/v", "xxh3_128_blocks"), b.attribute("/v", "xxh3_128_blocks"));
    const Array<uint32_t> back = b.read<uint32_t>("/v", rows * 2);  // verifies the hash
    EXPECT_TRUE(std::equal(back.begin(), back.end(), values.begin()));
    if (c != Compression::None) {
      EXPECT_EQ(stored_chunks(whole, "/v"), stored_chunks(pieces, "/v"));
    }
  }
}

TEST(DatasetStream, MissingRowsAndOverrunsAreErrorsNamingTheDataset) {
  test::TempDir dir;
  CacheWriter w(dir.file("x.lbc.h5"), Compression::Lz4);
  const std::vector<float> v(10, 1.0f);
  DatasetStream s = w.stream<float>("/group/d", 10);
  s.append(v.data(), 4);
  EXPECT_THROW(s.append(v.data(), 7), OutputError);
  try {
    s.close();
    FAIL();
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("/group/d: only 4 of 10 rows"), std::string::npos)
        << e.what();
  }
}

// A stored chunk whose dataset claims far more raw bytes than its codec can give (a hostile or
// damaged cache) is refused before a buffer is sized from the claim (docs/fuzzing.md, guarded
// allocation).
TEST(ChunkCodec, RefusesRawSizesBeyondTheCodecsRatio) {
  std::vector<float> raw(1024);
  for (size_t i = 0; i < raw.size(); ++i) raw[i] = float(i % 7);
  for (const Compression c :
       {Compression::None, Compression::Lz4, Compression::Deflate, Compression::BloscZstd}) {
    ChunkCodec codec;
    codec.compression = c;
    codec.element_size = 4;
    std::vector<char> stored, out, scratch;
    encode_chunk(codec, raw.data(), raw.size() * 4, stored, scratch);
    decode_chunk(codec, 0, stored.data(), stored.size(), raw.size() * 4, out, scratch);
    EXPECT_EQ(std::memcmp(out.data(), raw.data(), raw.size() * 4), 0) << to_string(c);
    try {
      decode_chunk(codec, 0, stored.data(), stored.size(), size_t{1} << 40, out, scratch);
      ADD_FAILURE() << to_string(c) << ": a 1 TiB claim was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("cannot hold 1099511627776 raw bytes"),
                std::string::npos)
          << e.what();
    }
    EXPECT_LT(out.capacity(), size_t{1} << 30) << to_string(c);
  }
}

// A dataset another program wrote: `rows` x `columns` (1-D when `columns` is 0) of `file_type`,
// chunked `chunk`, with `filters` in that order (H5Z ids), a fill value of 7.5 and only the rows
// below `written` written (the chunks past them never allocated).
void write_foreign(const std::string& path, hid_t file_type, size_t rows, size_t columns,
                   const std::vector<hsize_t>& chunk, const std::vector<H5Z_filter_t>& filters,
                   size_t written) {
  Handle file(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  const int rank = columns ? 2 : 1;
  // Rows unlimited, as h5py's resizable datasets: a chunk may then hold more rows than there are.
  const hsize_t dims[2] = {rows, columns}, most[2] = {H5S_UNLIMITED, columns};
  Handle space(H5Screate_simple(rank, dims, most), H5Sclose);
  Handle dcpl(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  H5Pset_chunk(dcpl, rank, chunk.data());
  const double fill = 7.5;
  H5Pset_fill_value(dcpl, H5T_NATIVE_DOUBLE, &fill);
  for (const H5Z_filter_t id : filters) {
    if (id == H5Z_FILTER_SHUFFLE) H5Pset_shuffle(dcpl);
    if (id == H5Z_FILTER_DEFLATE) H5Pset_deflate(dcpl, 4);
    if (id == H5Z_FILTER_FLETCHER32) H5Pset_fletcher32(dcpl);
    if (id == H5Z_filter_t(kLz4Filter))
      H5Pset_filter(dcpl, kLz4Filter, H5Z_FLAG_MANDATORY, 0, nullptr);
    if (id == H5Z_FILTER_SCALEOFFSET) H5Pset_scaleoffset(dcpl, H5Z_SO_FLOAT_DSCALE, 3);
  }
  Handle d(H5Dcreate2(file, "/data", file_type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT), H5Dclose);
  ASSERT_TRUE(d.valid());
  const size_t width = columns ? columns : 1;
  std::vector<double> values(written * width);
  for (size_t i = 0; i < values.size(); ++i) values[i] = double(i % 1013) * 0.5 - 200;
  const hsize_t start[2] = {0, 0}, extent[2] = {written, columns};
  Handle file_space(H5Dget_space(d), H5Sclose);
  H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, extent, nullptr);
  Handle memory_space(H5Screate_simple(rank, extent, nullptr), H5Sclose);
  ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, memory_space, file_space, H5P_DEFAULT, values.data()),
            0);
}

// Rows [first, first + count) by HDF5's own read, the second method.
template <class T>
std::vector<T> hdf5_rows(hid_t d, hid_t memory_type, size_t first, size_t count) {
  const std::vector<hsize_t> dims = h5::shape_of(d);
  const hsize_t columns = dims.size() == 2 ? dims[1] : 1;
  std::vector<T> out(count * columns);
  const hsize_t start[2] = {first, 0}, extent[2] = {count, columns};
  Handle file_space(H5Dget_space(d), H5Sclose);
  H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, extent, nullptr);
  Handle memory_space(H5Screate_simple(int(dims.size()), extent, nullptr), H5Sclose);
  EXPECT_GE(H5Dread(d, memory_type, memory_space, file_space, H5P_DEFAULT, out.data()), 0);
  return out;
}

// Another program's chunks, decoded by linebake: every pipeline it decodes, in the orders HDF5
// allows, chunks that split the columns and pass the edges, chunks never written (the fill
// value), big-endian and integer file types read as float and double: the same values as
// HDF5's own read of the same rows.
TEST(ReadRowsChecked, EqualsHdf5sReadForEveryPipelineLayoutAndType) {
  test::TempDir dir;
  h5::init();
  const H5Z_filter_t shuffle = H5Z_FILTER_SHUFFLE, deflate = H5Z_FILTER_DEFLATE,
                     fletcher = H5Z_FILTER_FLETCHER32, lz4 = H5Z_filter_t(kLz4Filter);
  const std::vector<std::vector<H5Z_filter_t>> pipelines = {
      {},         {deflate}, {shuffle, deflate},  {shuffle, deflate, fletcher},
      {fletcher}, {shuffle}, {fletcher, deflate}, {shuffle, lz4, fletcher}};
  struct Layout {
    size_t columns;
    std::vector<hsize_t> chunk;
  };
  const Layout layouts[] = {{3, {64, 3}}, {3, {100, 2}}, {0, {128}}, {1, {4096, 1}}};
  const hid_t file_types[] = {H5T_IEEE_F32LE, H5T_IEEE_F64BE, H5T_STD_I32BE};
  const size_t rows = 1001, written = 600;
  int n = 0;
  for (const auto& pipeline : pipelines)
    for (const Layout& layout : layouts)
      for (const hid_t file_type : file_types) {
        const std::string path = dir.file("f" + std::to_string(n++) + ".h5");
        write_foreign(path, file_type, rows, layout.columns, layout.chunk, pipeline, written);
        Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
        Handle d(H5Dopen2(file, "/data", H5P_DEFAULT), H5Dclose);
        const size_t width = layout.columns ? layout.columns : 1;
        for (const auto& [first, count] : std::vector<std::pair<size_t, size_t>>{
                 {0, rows}, {63, 2}, {599, 3}, {1000, 1}, {130, 470}}) {
          SCOPED_TRACE(path + " rows " + std::to_string(first) + "+" + std::to_string(count));
          std::vector<float> f(count * width, -1.0f);
          ASSERT_TRUE(read_rows_checked(d, H5T_NATIVE_FLOAT, first, count, f.data()));
          EXPECT_EQ(f, hdf5_rows<float>(d, H5T_NATIVE_FLOAT, first, count));
          std::vector<double> g(count * width, -1.0);
          ASSERT_TRUE(read_rows_checked(d, H5T_NATIVE_DOUBLE, first, count, g.data()));
          EXPECT_EQ(g, hdf5_rows<double>(d, H5T_NATIVE_DOUBLE, first, count));
        }
      }
  // Scale-offset is HDF5's to decode; a contiguous dataset HDF5's to read.
  const std::string other = dir.file("scaleoffset.h5");
  write_foreign(other, H5T_IEEE_F32LE, rows, 3, {64, 3}, {H5Z_FILTER_SCALEOFFSET}, rows);
  Handle file(H5Fopen(other.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  Handle d(H5Dopen2(file, "/data", H5P_DEFAULT), H5Dclose);
  std::vector<float> f(3);
  EXPECT_FALSE(read_rows_checked(d, H5T_NATIVE_FLOAT, 0, 1, f.data()));
}

// The chunk fuzz_hdf5 found, made by hand: a deflate stream that is whole but decodes to fewer
// bytes than the chunk holds. HDF5 1.10.8's read copies the chunk's nominal size out of the
// shorter buffer (a SEGV or garbage, in-process); linebake's decoder names the chunk.
TEST(ReadRowsChecked, AChunkThatDecodesShortIsAnErrorNamingIt) {
  test::TempDir dir;
  h5::init();
  const std::string path = dir.file("short.h5");
  write_foreign(path, H5T_IEEE_F32LE, 256, 3, {64, 3}, {H5Z_FILTER_DEFLATE}, 256);
  {
    Handle file(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT), H5Fclose);
    Handle d(H5Dopen2(file, "/data", H5P_DEFAULT), H5Dclose);
    std::vector<char> half(64 * 3 * sizeof(float) / 2, 1);
    std::vector<char> stored(compressBound(uLong(half.size())));
    uLongf n = uLongf(stored.size());
    ASSERT_EQ(compress2(reinterpret_cast<Bytef*>(stored.data()), &n,
                        reinterpret_cast<const Bytef*>(half.data()), uLong(half.size()), 4),
              Z_OK);
    const hsize_t offset[2] = {64, 0};
    ASSERT_GE(H5Dwrite_chunk(d, H5P_DEFAULT, 0, offset, n, stored.data()), 0);
  }
  Handle file(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  Handle d(H5Dopen2(file, "/data", H5P_DEFAULT), H5Dclose);
  std::vector<float> rows(256 * 3);
  EXPECT_TRUE(read_rows_checked(d, H5T_NATIVE_FLOAT, 0, 64, rows.data()));  // chunk 0 is sound
  try {
    (void)read_rows_checked(d, H5T_NATIVE_FLOAT, 0, 256, rows.data());
    FAIL() << "a short chunk decoded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the chunk at row 64, column 0: deflate"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace linebake
