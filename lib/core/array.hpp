#pragma once
// Array<T>: a typed view of memory that keeps its owner alive. Large assets are allocated
// uninitialised (every byte gets written once by the builder, not zeroed first) and can equally
// view a memory-mapped file region, so a cache load hands out the mapped bytes without a copy.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <type_traits>

namespace linebake {

// Uninitialised, page-aligned memory; regions of 2 MiB and more ask for transparent huge pages,
// which cuts the page faults of a multi-GiB build by 512x. Throws std::bad_alloc.
std::shared_ptr<void> allocate_bytes(size_t bytes);

template <class T>
class Array {
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  Array() = default;
  // Fresh, uninitialised storage for n elements.
  explicit Array(size_t n) : size_(n) {
    if (n) {
      owner_ = allocate_bytes(n * sizeof(T));
      data_ = static_cast<T*>(owner_.get());
    }
  }
  // A view of memory kept alive by `owner` (a mapping, another array's storage).
  Array(std::shared_ptr<const void> owner, const T* data, size_t n)
      : owner_(std::const_pointer_cast<void>(std::move(owner))),
        data_(const_cast<T*>(data)),
        size_(n) {}

  T* data() { return data_; }
  const T* data() const { return data_; }
  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  size_t bytes() const { return size_ * sizeof(T); }
  T& operator[](size_t i) { return data_[i]; }
  const T& operator[](size_t i) const { return data_[i]; }
  T* begin() { return data_; }
  T* end() { return data_ + size_; }
  const T* begin() const { return data_; }
  const T* end() const { return data_ + size_; }
  std::span<T> span() { return {data_, size_}; }
  std::span<const T> span() const { return {data_, size_}; }
  const std::shared_ptr<void>& owner() const { return owner_; }

 private:
  std::shared_ptr<void> owner_;
  T* data_ = nullptr;
  size_t size_ = 0;
};

}  // namespace linebake
