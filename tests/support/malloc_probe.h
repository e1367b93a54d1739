// Counts malloc calls on the calling thread, for tests that assert a warm path allocates nothing
// even through C libraries (libjpeg, zlib, SQLite) that never touch operator new:
//   - under ASan: every malloc call, through the sanitizer's malloc hooks;
//   - otherwise: the change of glibc's bytes in use (mallinfo2), which catches a block kept but
//     not one freed again before count(), nor a small block glibc's tcache hands out (it counts
//     as in use already). So the ASan build (host-debug) is the one that proves "no malloc".
// Pair it with support/counting_allocator.h (operator new). Same approach as the PnP test's.
#pragma once

#include <doctest/doctest.h>
#include <malloc.h>

#include <cstddef>
#include <cstdint>

#include "arena/sanitizers.h"

#if ZM_ASAN
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*,
                                                                             std::size_t),
                                                         void (*free_hook)(const volatile void*));
#endif

namespace zm::test {

#if ZM_ASAN
inline thread_local std::uint64_t t_probe_mallocs = 0;
inline void ProbeOnMalloc(const volatile void*, std::size_t) { ++t_probe_mallocs; }
inline void ProbeOnFree(const volatile void*) {}
#endif

class MallocProbe {
 public:
  MallocProbe() {
#if ZM_ASAN
    static const bool installed =
        __sanitizer_install_malloc_and_free_hooks(ProbeOnMalloc, ProbeOnFree) != 0;
    REQUIRE(installed);
    start_ = t_probe_mallocs;
#else
    start_ = InUse();
#endif
  }
  // Zero when nothing was allocated (see the file comment for what each build can see).
  [[nodiscard]] std::uint64_t count() const {
#if ZM_ASAN
    return t_probe_mallocs - start_;
#else
    return InUse() - start_;
#endif
  }
  [[nodiscard]] static constexpr bool counts_every_call() { return ZM_ASAN != 0; }

 private:
#if !ZM_ASAN
  static std::uint64_t InUse() {
    const struct mallinfo2 m = mallinfo2();
    return m.uordblks + m.hblkhd;
  }
#endif
  std::uint64_t start_ = 0;
};

}  // namespace zm::test
