// One replacement of an executable's allocator, shared by the programs (scratch_new.cc) and the
// test suites (tests/support/counting_allocator.cc), which differ only in what they count: a
// request made inside a ScratchScope is served from that scope's FrameScratch (frame_scratch.h;
// the C allocator's blocks through scratch_malloc.h), every other one by glibc's heap. A scratch
// block is recognised by its address (ScratchFree), so every pointer goes back to the allocator
// that made it.
//
// This header DEFINES the global operator new/delete family and, where no sanitizer owns malloc
// (ZM_SANITIZER_OWNS_MALLOC == 0), the malloc family: include it in exactly one .cc of an
// executable, after defining the hooks below (empty for the programs, counters for the tests).
// Under a sanitizer the C allocator's requests reach the heap even inside a scope.
//
//   namespace zm::alloc_hooks {
//   void OnHeapNew(std::size_t n) noexcept;  // operator new of n bytes, served by the heap
//   void OnHeapDelete() noexcept;            // operator delete of a heap block
//   void OnHeapMalloc() noexcept;            // a malloc-family request, served by the heap
//   }
#pragma once

#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <new>

#include "arena/frame_scratch.h"
#include "arena/sanitizers.h"
#include "arena/scratch_malloc.h"

// Which sanitizer owns malloc, if any: ZM_ASAN (arena/sanitizers.h; AddressSanitizer, whose
// malloc hooks the tests count through) and ZM_SANITIZER_OWNS_MALLOC (ASan, TSan or MSan).
#if ZM_ASAN || defined(__SANITIZE_THREAD__)
#define ZM_SANITIZER_OWNS_MALLOC 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define ZM_SANITIZER_OWNS_MALLOC 1
#endif
#endif
#ifndef ZM_SANITIZER_OWNS_MALLOC
#define ZM_SANITIZER_OWNS_MALLOC 0
#endif

namespace zm::alloc_hooks {
void OnHeapNew(std::size_t n) noexcept;
void OnHeapDelete() noexcept;
void OnHeapMalloc() noexcept;
}  // namespace zm::alloc_hooks

#if !ZM_SANITIZER_OWNS_MALLOC
// glibc lets an executable define malloc; its own stays reachable as __libc_*. Everything glibc
// allocates (posix_memalign, strdup...) ends in the same heap.
extern "C" {
void* __libc_malloc(std::size_t n);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t n);
void __libc_free(void* p);
void* __libc_memalign(std::size_t align, std::size_t n);

void* malloc(std::size_t n) noexcept {
  if (void* p = zm::scratch_c::Allocate(n)) return p;
  zm::alloc_hooks::OnHeapMalloc();
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
  zm::alloc_hooks::OnHeapMalloc();
  return __libc_calloc(n, size);
}
void free(void* p) noexcept {
  if (p != nullptr && !zm::ScratchFree(p)) __libc_free(p);
}
void* realloc(void* p, std::size_t n) noexcept {
  if (p == nullptr) return malloc(n);
  if (!zm::FrameScratchContains(p)) {
    zm::alloc_hooks::OnHeapMalloc();
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
  zm::alloc_hooks::OnHeapMalloc();
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

namespace zm::replace_allocator_detail {

inline void* Allocate(std::size_t n, std::size_t align) noexcept {
  if (void* p = ScratchAllocate(n, align)) return p;
  alloc_hooks::OnHeapNew(n);
  if (n == 0) n = 1;
#if ZM_SANITIZER_OWNS_MALLOC
  return align > alignof(std::max_align_t)
             ? std::aligned_alloc(align, (n + align - 1) / align * align)
             : std::malloc(n);
#else
  // Straight to glibc: the malloc above would ask the scratch a second time.
  alloc_hooks::OnHeapMalloc();
  return align > alignof(std::max_align_t) ? __libc_memalign(align, n) : __libc_malloc(n);
#endif
}

inline void* AllocateOrThrow(std::size_t n, std::size_t align) {
  // The standard's loop: a new_handler may free memory and let the request be retried.
  for (;;) {
    if (void* p = Allocate(n, align)) return p;
    std::new_handler handler = std::get_new_handler();
    if (handler == nullptr) throw std::bad_alloc();
    handler();
  }
}

inline void Release(void* p) noexcept {
  if (p != nullptr && !ScratchFree(p)) {
    alloc_hooks::OnHeapDelete();
    std::free(p);
  }
}

}  // namespace zm::replace_allocator_detail

void* operator new(std::size_t n) { return zm::replace_allocator_detail::AllocateOrThrow(n, 0); }
void* operator new[](std::size_t n) { return zm::replace_allocator_detail::AllocateOrThrow(n, 0); }
void* operator new(std::size_t n, std::align_val_t a) {
  return zm::replace_allocator_detail::AllocateOrThrow(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return zm::replace_allocator_detail::AllocateOrThrow(n, static_cast<std::size_t>(a));
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  return zm::replace_allocator_detail::Allocate(n, 0);
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  return zm::replace_allocator_detail::Allocate(n, 0);
}
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return zm::replace_allocator_detail::Allocate(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return zm::replace_allocator_detail::Allocate(n, static_cast<std::size_t>(a));
}
void operator delete(void* p) noexcept { zm::replace_allocator_detail::Release(p); }
void operator delete[](void* p) noexcept { zm::replace_allocator_detail::Release(p); }
void operator delete(void* p, std::size_t) noexcept { zm::replace_allocator_detail::Release(p); }
void operator delete[](void* p, std::size_t) noexcept { zm::replace_allocator_detail::Release(p); }
void operator delete(void* p, std::align_val_t) noexcept {
  zm::replace_allocator_detail::Release(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  zm::replace_allocator_detail::Release(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  zm::replace_allocator_detail::Release(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  zm::replace_allocator_detail::Release(p);
}
void operator delete(void* p, const std::nothrow_t&) noexcept {
  zm::replace_allocator_detail::Release(p);
}
void operator delete[](void* p, const std::nothrow_t&) noexcept {
  zm::replace_allocator_detail::Release(p);
}
