#pragma once
// Small RAII and error helpers over the HDF5 C API, shared by the HDF5 line-set format and the
// asset cache.

#include <hdf5.h>

#include <exception>
#include <string>
#include <vector>

namespace linebake::h5 {

// While one lives on this thread (a parallel write, whose closes are collective), the handles
// that an exception's unwinding destroys are left open: a rank whose write failed would
// otherwise wait in a collective close for ranks that wait in another collective, for ever.
// The process must end soon after (MPI_Abort: bake_mpi's CollectiveWriteFailed).
class LeaveOpenOnUnwind {
 public:
  LeaveOpenOnUnwind() { ++depth_; }
  ~LeaveOpenOnUnwind() { --depth_; }
  LeaveOpenOnUnwind(const LeaveOpenOnUnwind&) = delete;
  LeaveOpenOnUnwind& operator=(const LeaveOpenOnUnwind&) = delete;
  // Whether a handle destroyed now is left open.
  static bool now() { return depth_ > 0 && std::uncaught_exceptions() > 0; }

 private:
  static thread_local int depth_;
};

// Owns an HDF5 id and closes it with the matching function.
class Handle {
 public:
  Handle() = default;
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  ~Handle() {
    if (!LeaveOpenOnUnwind::now()) reset();
  }
  Handle(Handle&& other) noexcept : id_(other.id_), close_(other.close_) { other.id_ = -1; }
  Handle& operator=(Handle&& other) noexcept {
    if (this != &other) {
      reset();
      id_ = other.id_;
      close_ = other.close_;
      other.id_ = -1;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  operator hid_t() const { return id_; }
  bool valid() const { return id_ >= 0; }
  void reset() {
    if (id_ >= 0 && close_) close_(id_);
    id_ = -1;
  }
  // Gives up ownership (the caller closes it and checks the result).
  hid_t release() {
    const hid_t id = id_;
    id_ = -1;
    return id;
  }

 private:
  hid_t id_ = -1;
  herr_t (*close_)(hid_t) = nullptr;
};

// Turns off HDF5's own printing of error stacks (linebake reports errors itself) and registers
// the directories of Debian's HDF5 filter plugins, so LZ4 and Blosc work without the user
// setting HDF5_PLUGIN_PATH. Idempotent; call before any HDF5 use.
void init();

// The innermost message of the current HDF5 error stack ("" if none).
std::string last_error();
// The file starts with an HDF5 superblock (H5Fis_hdf5); false for a missing file.
bool is_hdf5_file(const std::string& path);

std::vector<hsize_t> shape_of(hid_t dataset);

// The object at the absolute `path` exists ("/" always does). H5Lexists answers only when every
// group on the way exists, so each prefix is asked first.
bool path_exists(hid_t location, const std::string& path);

// The most bytes `dataset` can decode to: its stored bytes (the sum of its chunks, from the chunk
// index) times the best ratio of its filter pipeline (deflate 1032:1, LZ4 255:1, Blosc and any
// filter we do not know 2^17:1; none: 1:1), plus 1 MiB for chunks left to the fill value.
uint64_t max_decoded_bytes(hid_t dataset);
// What is wrong with a dataset's header where HDF5 1.10.8 trusts it on a read (both found by
// fuzz_hdf5, tests/fuzz/known/hdf5/); empty when nothing is:
// - a compact dataset that stores other than its shape's bytes (a read copies the shape's bytes
//   from a null buffer when it says 0);
// - a scale-offset or N-bit filter whose parameters disagree with the chunk layout: their
//   decoders size their output from the parameters' element count and element size, not from
//   the chunk (a damaged count asked for 4 GB to decode a 20-byte chunk, and would fill it);
// - a number type whose precision, or a float's sign, exponent or mantissa, lies partly outside
//   its bytes: conversions copy those bits (an exponent at bits 54 to 64 of a double read past
//   the last element).
std::string damaged_storage(hid_t dataset);
// What is wrong with an integer or float type whose precision, or a float's sign, exponent or
// mantissa, lies partly outside its bytes (empty when nothing is, or for another class): HDF5's
// soft conversions (H5T__conv_f_f, H5T__conv_i_i) copy those bits as the type says, past the
// element. For datasets through damaged_storage; attributes with such a type are not read.
std::string damaged_number_type(hid_t type);
// Throws InputError naming `path` and `name` when the dataset's shape claims more bytes than
// max_decoded_bytes(), or its header is damaged (damaged_storage): refused before anything is
// sized or read from it.
void check_claimed_size(const std::string& path, hid_t dataset, const std::string& name);

// Maps any attribute name to an HDF5 link name: '/' and '%' (and a leading '.') become %XX;
// the empty name becomes "%".
std::string encode_link_name(const std::string& name);
std::string decode_link_name(const std::string& name);

// Member names of a group in creation order where tracked, else name order; empty if missing.
std::vector<std::string> group_members(hid_t location, const std::string& group);

// Variable-length-free fixed string attributes (readable by h5py as bytes/str).
bool write_string_attribute(hid_t object, const std::string& name, const std::string& value);
bool read_string_attribute(hid_t object, const std::string& name, std::string& value);

}  // namespace linebake::h5
