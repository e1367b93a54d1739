// The global operator new/delete of a zonemap program, and (in builds without a sanitizer) its
// malloc family: a request made inside a ScratchScope is served from that scope's FrameScratch
// (arena/frame_scratch.h), every other one by glibc's allocator, as without this file. The
// malloc side exists because OpenCV's FAST takes its row buffers with cv::fastMalloc (malloc)
// through cv::utils::BufferArea, once per pyramid level and frame. Linked (as the object library zm_scratch_new) into the
// programs whose tick calls a library that allocates per frame (OpenCV's ORB); the test suites'
// counting allocator (tests/support/counting_allocator.cc) asks the same hook, so there is one
// replacement per executable either way.
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <new>

#include "arena/frame_scratch.h"
#include "arena/scratch_malloc.h"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define ZM_SCRATCH_MALLOC 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define ZM_SCRATCH_MALLOC 0
#endif
#endif
#ifndef ZM_SCRATCH_MALLOC
#define ZM_SCRATCH_MALLOC 1
#endif

#if ZM_SCRATCH_MALLOC
// glibc lets an executable define malloc; its own stays reachable as __libc_*. A scratch block
// is recognised by its address (ScratchFree), so every pointer goes back to the allocator that
// made it.
extern "C" {
void* __libc_malloc(std::size_t n);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t n);
void __libc_free(void* p);
void* __libc_memalign(std::size_t align, std::size_t n);

void* malloc(std::size_t n) noexcept {
  if (void* p = zm::scratch_c::Allocate(n)) return p;
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  if (size != 0 && n > static_cast<std::size_t>(-1) / size) {
    errno = ENOMEM;
    return nullptr;
  }
  if (void* p = zm::scratch_c::Allocate(n * size)) {
    std::memset(p, 0, n * size);  // the region is reused: not zero as fresh pages are
    return p;
  }
  return __libc_calloc(n, size);
}
void free(void* p) noexcept {
  if (p != nullptr && !zm::ScratchFree(p)) __libc_free(p);
}
void* realloc(void* p, std::size_t n) noexcept {
  if (p == nullptr || !zm::FrameScratchContains(p)) {
    if (p == nullptr) return malloc(n);
    return __libc_realloc(p, n);
  }
  void* q = malloc(n);  // the scope's region, or the heap when the block outlived its scope
  if (q == nullptr) return nullptr;
  const std::size_t old = zm::scratch_c::Size(p);
  std::memcpy(q, p, old < n ? old : n);
  zm::ScratchFree(p);
  return q;
}
void* memalign(std::size_t align, std::size_t n) noexcept {
  if (void* p = zm::scratch_c::Allocate(n, align)) return p;
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
// malloc_usable_size is not interposed (glibc has no __libc_ entry to forward to): it must not
// be asked about a scratch block, and nothing that runs inside a scope does.
}  // extern "C"
#endif

namespace {

void* Allocate(std::size_t n, std::size_t align) noexcept {
  if (void* p = zm::ScratchAllocate(n, align)) return p;
  if (n == 0) n = 1;
  if (align > alignof(std::max_align_t)) {
#if ZM_SCRATCH_MALLOC
    return __libc_memalign(align, n);
#else
    return std::aligned_alloc(align, (n + align - 1) / align * align);
#endif
  }
#if ZM_SCRATCH_MALLOC
  return __libc_malloc(n);  // outside a scope (or a full region): the heap
#else
  return std::malloc(n);
#endif
}

void* AllocateOrThrow(std::size_t n, std::size_t align) {
  // The standard's loop: a new_handler may free memory and let the request be retried.
  for (;;) {
    if (void* p = Allocate(n, align)) return p;
    std::new_handler handler = std::get_new_handler();
    if (handler == nullptr) throw std::bad_alloc();
    handler();
  }
}

void Release(void* p) noexcept {
  if (p != nullptr && !zm::ScratchFree(p)) std::free(p);
}

}  // namespace

void* operator new(std::size_t n) { return AllocateOrThrow(n, 0); }
void* operator new[](std::size_t n) { return AllocateOrThrow(n, 0); }
void* operator new(std::size_t n, std::align_val_t a) {
  return AllocateOrThrow(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return AllocateOrThrow(n, static_cast<std::size_t>(a));
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return Allocate(n, 0); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return Allocate(n, 0); }
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return Allocate(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return Allocate(n, static_cast<std::size_t>(a));
}
void operator delete(void* p) noexcept { Release(p); }
void operator delete[](void* p) noexcept { Release(p); }
void operator delete(void* p, std::size_t) noexcept { Release(p); }
void operator delete[](void* p, std::size_t) noexcept { Release(p); }
void operator delete(void* p, std::align_val_t) noexcept { Release(p); }
void operator delete[](void* p, std::align_val_t) noexcept { Release(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { Release(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { Release(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { Release(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { Release(p); }
