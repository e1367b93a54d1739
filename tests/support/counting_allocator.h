// Counts heap allocations made through global operator new/delete on the calling thread, so a
// test can assert that a block of code (arena acquire/release, a warm tick) allocates nothing.
//
//   zm::test::AllocationCounter c;   // starts counting
//   DoWork();
//   CHECK(c.allocations() == 0);
//
// The replacement operator new lives in counting_allocator.cc and is linked into every test
// executable; it forwards to malloc (so ASan still sees every block).
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

}  // namespace zm::test
