// The test suites' allocator: the programs' replacement (arena/replace_allocator.h: a
// ScratchScope's requests from its FrameScratch, the rest from glibc's heap) with counters in its
// hooks, per thread: operator new and delete, and the C allocator (see counting_allocator.h).
// A request the frame scratch serves is not a heap allocation: not counted.
#include "support/counting_allocator.h"

#include <cstddef>
#include <cstdint>
#include <cstdlib>

namespace {
// Initial-exec TLS of the executable: reading it inside malloc never allocates.
thread_local std::uint64_t t_mallocs = 0;
thread_local std::uint64_t t_allocs = 0;
thread_local std::uint64_t t_frees = 0;
thread_local std::uint64_t t_bytes = 0;
}  // namespace

namespace zm::alloc_hooks {
void OnHeapNew(std::size_t n) noexcept {
  ++t_allocs;
  t_bytes += n;
}
void OnHeapDelete() noexcept { ++t_frees; }
// Called by the interposed malloc family; under ASan (which owns malloc) the sanitizer's hooks
// count instead (MallocCounter).
void OnHeapMalloc() noexcept { ++t_mallocs; }
}  // namespace zm::alloc_hooks

#include "arena/replace_allocator.h"

#if ZM_ASAN
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*,
                                                                             std::size_t),
                                                         void (*free_hook)(const volatile void*));
namespace {
void OnMalloc(const volatile void*, std::size_t) { ++t_mallocs; }
void OnFree(const volatile void*) {}
}  // namespace
#endif

namespace zm::test {
std::uint64_t ThreadMallocs() { return t_mallocs; }
MallocCounter::MallocCounter() {
  // Without a count nothing would be counted and every "no malloc" check would pass silently:
  // refuse to run instead.
#if ZM_ASAN
  static const bool installed = __sanitizer_install_malloc_and_free_hooks(OnMalloc, OnFree) != 0;
  if (!installed) std::abort();
#elif ZM_SANITIZER_OWNS_MALLOC
  std::abort();  // another sanitizer owns malloc, and nothing here counts it
#endif
  start_ = t_mallocs;
}
std::uint64_t ThreadAllocations() { return t_allocs; }
std::uint64_t ThreadDeallocations() { return t_frees; }
std::uint64_t ThreadAllocatedBytes() { return t_bytes; }
}  // namespace zm::test
