#include "core/array.hpp"

#include <sys/mman.h>

#include <new>

namespace linebake {

std::shared_ptr<void> allocate_bytes(size_t bytes) {
  constexpr size_t kHugePage = size_t{2} << 20;
  if (bytes < kHugePage) {
    void* p = ::operator new (bytes, std::align_val_t{64});
    return {p, [](void* q) { ::operator delete (q, std::align_val_t{64}); }};
  }
  // mmap gives page-aligned, lazily committed memory; advise huge pages over it.
  const size_t mapped = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* p = mmap(nullptr, mapped, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  madvise(p, mapped, MADV_HUGEPAGE);  // advisory: ignored where THP is off
  return {p, [mapped](void* q) { munmap(q, mapped); }};
}

}  // namespace linebake
