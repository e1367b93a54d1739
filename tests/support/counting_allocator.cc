// Replacement global operator new/delete that count per thread, then forward to malloc/free;
// and the C allocator's count (see counting_allocator.h).
#include "support/counting_allocator.h"

#include "arena/frame_scratch.h"
#include "arena/scratch_malloc.h"

#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <new>

#if defined(__SANITIZE_ADDRESS__)
#define ZM_COUNTING_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ZM_COUNTING_ASAN 1
#endif
#endif
#ifndef ZM_COUNTING_ASAN
#define ZM_COUNTING_ASAN 0
#endif

namespace {
// Initial-exec TLS of the executable: reading it inside malloc never allocates.
thread_local std::uint64_t t_mallocs = 0;
}  // namespace

#if ZM_COUNTING_ASAN
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*,
                                                                             std::size_t),
                                                         void (*free_hook)(const volatile void*));
namespace {
void OnMalloc(const volatile void*, std::size_t) { ++t_mallocs; }
void OnFree(const volatile void*) {}
}  // namespace
#else
// glibc supports replacing malloc by defining it in the executable; the originals stay
// reachable as __libc_*. Everything glibc allocates (posix_memalign, strdup...) ends in the same
// heap, so every pointer is freed by the allocator that made it.
extern "C" {
void* __libc_malloc(std::size_t n);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t n);
void __libc_free(void* p);
void* __libc_memalign(std::size_t align, std::size_t n);

// A request inside a ScratchScope is served by the frame scratch, as the programs' allocator
// (arena/scratch_new.cc) does, and is not a heap allocation: not counted.
void* malloc(std::size_t n) noexcept {
  if (void* p = zm::scratch_c::Allocate(n)) return p;
  ++t_mallocs;
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  if (size != 0 && n > static_cast<std::size_t>(-1) / size) {
    errno = ENOMEM;
    return nullptr;
  }
  if (void* p = zm::scratch_c::Allocate(n * size)) {
    std::memset(p, 0, n * size);
    return p;
  }
  ++t_mallocs;
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t n) noexcept {
  if (p != nullptr && zm::FrameScratchContains(p)) {
    void* q = malloc(n);
    if (q == nullptr) return nullptr;
    const std::size_t old = zm::scratch_c::Size(p);
    std::memcpy(q, p, old < n ? old : n);
    zm::ScratchFree(p);
    return q;
  }
  ++t_mallocs;
  return __libc_realloc(p, n);
}
void free(void* p) noexcept {
  if (p != nullptr && !zm::ScratchFree(p)) __libc_free(p);
}
void* memalign(std::size_t align, std::size_t n) noexcept {
  if (void* p = zm::scratch_c::Allocate(n, align)) return p;
  ++t_mallocs;
  return __libc_memalign(align, n);
}
void* aligned_alloc(std::size_t align, std::size_t n) noexcept { return memalign(align, n); }
int posix_memalign(void** out, std::size_t align, std::size_t n) noexcept {
  if (align < sizeof(void*) || (align & (align - 1)) != 0) return EINVAL;
  void* p = memalign(align, n);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
}  // extern "C"
#endif

namespace zm::test {
std::uint64_t ThreadMallocs() { return t_mallocs; }
MallocCounter::MallocCounter() {
#if ZM_COUNTING_ASAN
  // Without the hooks nothing would be counted and every "no malloc" check would pass
  // silently: refuse to run instead.
  static const bool installed = __sanitizer_install_malloc_and_free_hooks(OnMalloc, OnFree) != 0;
  if (!installed) std::abort();
#endif
  start_ = t_mallocs;
}
}  // namespace zm::test

namespace {
thread_local std::uint64_t t_allocs = 0;
thread_local std::uint64_t t_frees = 0;
thread_local std::uint64_t t_bytes = 0;

void* CountedAlloc(std::size_t n, std::size_t align) {
  // A request inside a ScratchScope is the frame scratch's, not the heap's (arena/scratch_new.cc
  // is the programs' version of this hook): not counted as an allocation.
  if (void* p = zm::ScratchAllocate(n, align)) return p;
  ++t_allocs;
  t_bytes += n;
  if (n == 0) n = 1;
#if ZM_COUNTING_ASAN
  void* p = align > alignof(std::max_align_t) ? std::aligned_alloc(align, (n + align - 1) / align * align)
                                              : std::malloc(n);
#else
  // Straight to glibc: the interposed malloc above would ask the scratch a second time.
  ++t_mallocs;
  void* p = align > alignof(std::max_align_t) ? __libc_memalign(align, n) : __libc_malloc(n);
#endif
  return p;
}

void Release(void* p) noexcept {
  if (p != nullptr && !zm::ScratchFree(p)) {
    ++t_frees;
    std::free(p);
  }
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
void operator delete(void* p) noexcept { Release(p); }
void operator delete[](void* p) noexcept { Release(p); }
void operator delete(void* p, std::size_t) noexcept { Release(p); }
void operator delete[](void* p, std::size_t) noexcept { Release(p); }
void operator delete(void* p, std::align_val_t) noexcept { Release(p); }
void operator delete[](void* p, std::align_val_t) noexcept { Release(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { Release(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { Release(p); }
