// Counts heap allocations made through global operator new/delete on the calling thread, so a
// test can assert that a block of code (arena acquire/release, a warm tick) allocates nothing.
//
//   zm::test::AllocationCounter c;   // starts counting
//   DoWork();
//   CHECK(c.allocations() == 0);
//
// The replacement operator new lives in counting_allocator.cc and is linked into every test
// executable; it forwards to malloc (so ASan still sees every block).
//
// MallocCounter counts the C allocator too (malloc, calloc, realloc, aligned allocations: what
// SQLite, zlib or stdio use, which never touch operator new), exactly, on the calling thread:
//   - AddressSanitizer builds: through the sanitizer's malloc hooks (ASan owns malloc);
//   - other builds (the aarch64 tests under qemu): counting_allocator.cc interposes malloc,
//     calloc, realloc and free and forwards them to glibc's __libc_* entry points.
// So both builds prove "no malloc", not only "no net growth".
#pragma once

#include <cstdint>

namespace zm::test {

// Thread-local totals since the thread started.
std::uint64_t ThreadAllocations();
std::uint64_t ThreadDeallocations();
std::uint64_t ThreadAllocatedBytes();

class AllocationCounter {
 public:
  AllocationCounter()
      : allocs_(ThreadAllocations()), frees_(ThreadDeallocations()), bytes_(ThreadAllocatedBytes()) {}
  [[nodiscard]] std::uint64_t allocations() const { return ThreadAllocations() - allocs_; }
  [[nodiscard]] std::uint64_t deallocations() const { return ThreadDeallocations() - frees_; }
  [[nodiscard]] std::uint64_t bytes() const { return ThreadAllocatedBytes() - bytes_; }

 private:
  std::uint64_t allocs_, frees_, bytes_;
};

// Thread-local count of C allocator calls (malloc, calloc, realloc, aligned) since the thread
// started; see MallocCounter.
std::uint64_t ThreadMallocs();

class MallocCounter {
 public:
  MallocCounter();  // installs the ASan hooks on first use
  [[nodiscard]] std::uint64_t mallocs() const { return ThreadMallocs() - start_; }

 private:
  std::uint64_t start_;
};

}  // namespace zm::test
