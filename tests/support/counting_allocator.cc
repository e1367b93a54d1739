// Replacement global operator new/delete that count per thread, then forward to malloc/free.
#include "support/counting_allocator.h"

#include <cstddef>
#include <cstdlib>
#include <new>

namespace {
thread_local std::uint64_t t_allocs = 0;
thread_local std::uint64_t t_frees = 0;
thread_local std::uint64_t t_bytes = 0;

void* CountedAlloc(std::size_t n, std::size_t align) {
  ++t_allocs;
  t_bytes += n;
  if (n == 0) n = 1;
  void* p = align > alignof(std::max_align_t) ? std::aligned_alloc(align, (n + align - 1) / align * align)
                                              : std::malloc(n);
  return p;
}
}  // namespace

namespace zm::test {
std::uint64_t ThreadAllocations() { return t_allocs; }
std::uint64_t ThreadDeallocations() { return t_frees; }
std::uint64_t ThreadAllocatedBytes() { return t_bytes; }
}  // namespace zm::test

void* operator new(std::size_t n) {
  if (void* p = CountedAlloc(n, 0)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (void* p = CountedAlloc(n, 0)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, std::align_val_t a) {
  if (void* p = CountedAlloc(n, static_cast<std::size_t>(a))) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) {
  if (void* p = CountedAlloc(n, static_cast<std::size_t>(a))) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return CountedAlloc(n, 0); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return CountedAlloc(n, 0); }
void operator delete(void* p) noexcept { if (p) { ++t_frees; std::free(p); } }
void operator delete[](void* p) noexcept { if (p) { ++t_frees; std::free(p); } }
void operator delete(void* p, std::size_t) noexcept { if (p) { ++t_frees; std::free(p); } }
void operator delete[](void* p, std::size_t) noexcept { if (p) { ++t_frees; std::free(p); } }
void operator delete(void* p, std::align_val_t) noexcept { if (p) { ++t_frees; std::free(p); } }
void operator delete[](void* p, std::align_val_t) noexcept { if (p) { ++t_frees; std::free(p); } }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { if (p) { ++t_frees; std::free(p); } }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { if (p) { ++t_frees; std::free(p); } }
