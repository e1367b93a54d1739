// FrameScratch (arena/frame_scratch.h): the region a ScratchScope serves operator new and the C
// allocator from, how it resets, what it does when full or when a block outlives its scope.
// The test suites' counting allocator asks the same hook as the programs' (scratch_new.cc).
#include "arena/frame_scratch.h"

#include <doctest/doctest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "arena/sanitizers.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

std::unique_ptr<FrameScratch> Make(std::size_t bytes) {
  std::string error;
  std::unique_ptr<FrameScratch> s = FrameScratch::Create(bytes, &error);
  REQUIRE_MESSAGE(s != nullptr, error);
  return s;
}

TEST_CASE("frame scratch: bad sizes are one clear error") {
  std::string error;
  CHECK(FrameScratch::Create(0, &error) == nullptr);
  CHECK(error == "frame scratch of 0 bytes outside [1, 1073741824]");
  CHECK(FrameScratch::Create((std::size_t{1} << 30) + 1, &error) == nullptr);
  CHECK(error.find("outside [1, 1073741824]") != std::string::npos);
}

TEST_CASE("frame scratch: inside a scope operator new comes from the region, outside from the heap") {
  auto scratch = Make(1 << 20);
  {
    auto* outside = new std::uint64_t(1);
    CHECK_FALSE(scratch->Contains(outside));
    delete outside;
  }
  test::AllocationCounter heap;
  {
    ScratchScope scope(*scratch);
    std::vector<int> v(1000, 7);  // 4000 bytes
    CHECK(scratch->Contains(v.data()));
    auto* aligned = new (std::align_val_t{64}) double[8];
    CHECK(reinterpret_cast<std::uintptr_t>(aligned) % 64 == 0);
    CHECK(scratch->Contains(aligned));
    ::operator delete[](aligned, std::align_val_t{64});
  }
  CHECK(heap.allocations() == 0);
  const FrameScratchStats st = scratch->stats();
  CHECK(st.allocations == 2);
  CHECK(st.scopes == 1);
  CHECK(st.overflows == 0);
  CHECK(st.blocks_outliving_scope == 0);
  CHECK(st.high_water_bytes >= 4000 + 64);
}

TEST_CASE("frame scratch: the region resets when every block is back, so frames reuse it") {
  auto scratch = Make(64 << 10);
  void* first = nullptr;
  for (int frame = 0; frame < 100; ++frame) {
    ScratchScope scope(*scratch);
    std::vector<char> buf(40 << 10);
    if (frame == 0) first = buf.data();
    CHECK(buf.data() == first);  // a bump region that never reset would overflow by frame 2
  }
  CHECK(scratch->stats().overflows == 0);
  CHECK(scratch->stats().scopes == 100);
}

TEST_CASE("frame scratch: a full region hands the request to the heap and counts it") {
  auto scratch = Make(4096);
  test::AllocationCounter heap;
  ScratchScope scope(*scratch);
  std::vector<char> big(1 << 20, 'x');  // does not fit: heap
  CHECK_FALSE(scratch->Contains(big.data()));
  CHECK(heap.allocations() == 1);
  CHECK(scratch->stats().overflows == 1);
}

TEST_CASE("frame scratch: a block that outlives its scope stays valid, the region waits for it") {
  auto scratch = Make(64 << 10);
  std::uint64_t* kept = nullptr;
  {
    ScratchScope scope(*scratch);
    kept = new std::uint64_t(0x1234);
  }
  CHECK(scratch->stats().blocks_outliving_scope == 1);
  {
    ScratchScope scope(*scratch);
    std::vector<std::uint64_t> next(100, 0xFFFFFFFFFFFFFFFFull);  // must not land on `kept`
    CHECK(*kept == 0x1234);
  }
  delete kept;  // freed outside any scope, from the region
  void* at_base = nullptr;
  {
    ScratchScope scope(*scratch);
    auto* p = new char[16];
    at_base = p;
    delete[] p;
  }
  {
    ScratchScope scope(*scratch);
    auto* p = new char[16];
    CHECK(static_cast<void*>(p) == at_base);  // reset again once everything came back
    delete[] p;
  }
}

TEST_CASE("frame scratch: a block may be freed from another thread") {
  auto scratch = Make(64 << 10);
  int* p = nullptr;
  {
    ScratchScope scope(*scratch);
    p = new int(5);
  }
  std::thread([p] { delete p; }).join();
  void* base = nullptr;
  {
    ScratchScope scope(*scratch);
    auto* q = new int(1);
    base = q;
    delete q;
  }
  {
    ScratchScope scope(*scratch);
    auto* q = new int(1);
    CHECK(static_cast<void*>(q) == base);
    delete q;
  }
}

TEST_CASE("frame scratch: another thread's requests never come from this thread's scope") {
  auto scratch = Make(64 << 10);
  ScratchScope scope(*scratch);
  bool in_region = true;
  std::thread([&] {
    auto* p = new int(3);
    in_region = scratch->Contains(p);
    delete p;
  }).join();
  CHECK_FALSE(in_region);
}

TEST_CASE("frame scratch: nested scopes on one region close it once") {
  auto scratch = Make(64 << 10);
  {
    ScratchScope outer(*scratch);
    auto* a = new int(1);
    {
      ScratchScope inner(*scratch);
      auto* b = new int(2);
      delete b;
    }
    CHECK(scratch->Contains(a));
    delete a;
  }
  CHECK(scratch->stats().scopes == 1);
  CHECK(scratch->stats().blocks_outliving_scope == 0);
}

#if !ZM_ASAN
TEST_CASE("frame scratch: without a sanitizer the C allocator is served too (malloc, calloc, "
          "realloc, posix_memalign)") {
  auto scratch = Make(64 << 10);
  test::MallocCounter mallocs;
  {
    ScratchScope scope(*scratch);
    void* m = std::malloc(100);
    CHECK(scratch->Contains(m));
    std::memset(m, 0xAB, 100);
    auto* c = static_cast<unsigned char*>(std::calloc(10, 10));
    CHECK(scratch->Contains(c));
    bool zero = true;
    for (int i = 0; i < 100; ++i) zero = zero && c[i] == 0;
    CHECK(zero);  // the region is reused: calloc must clear it
    auto* r = static_cast<unsigned char*>(std::realloc(m, 300));
    CHECK(scratch->Contains(r));
    CHECK(r[99] == 0xAB);  // the old contents moved
    void* a = nullptr;
    CHECK(posix_memalign(&a, 256, 10) == 0);
    CHECK(reinterpret_cast<std::uintptr_t>(a) % 256 == 0);
    std::free(a);
    std::free(r);
    std::free(c);
  }
  CHECK(mallocs.mallocs() == 0);
  CHECK(scratch->stats().blocks_outliving_scope == 0);
}
#endif

}  // namespace
}  // namespace zm
