// FrameScratch: a fixed region, reserved once, that serves a third-party library's per-frame heap
// requests inside one tick, so that the tick makes no heap allocation even though the library
// (OpenCV's cv::ORB: its image pyramid, per-level keypoint vectors, FAST/Harris scratch, about
// a hundred operator new and malloc calls per frame) allocates on every call.
//
//   FrameScratch scratch = FrameScratch::Create(8 << 20).value();   // once, at start-up
//   ...
//   {
//     ScratchScope scope(scratch);   // this thread's operator new (and OpenCV's Mat data) now
//     orb->detectAndCompute(...);    // come from the region, bump-allocated
//   }                                // every block freed again -> the region resets
//
// How requests reach it: a program links `zm_scratch_new` (arena/scratch_new.cc), the global
// operator new/delete that ask ScratchAllocate() first and fall back to malloc; the test suites'
// counting allocator does the same. OpenCV's Mat data goes through cv::MatAllocator, which the
// ORB front-end points here (lib/localization/scratch_mat_allocator.h). Without a scope on the
// calling thread nothing changes: ScratchAllocate() returns nullptr and the heap serves.
//
// Why a bump region and not a pool: the requests have every size (a pyramid level of 300 kB,
// a 28-byte keypoint), they all die before the library call returns, and the order of frees does
// not matter to a bump pointer. The region resets only when every block it handed out has been
// freed (live == 0), checked when the outermost scope closes. A block that outlives its scope
// (a library cache, a bug) therefore stays valid: the region simply does not reset until it is
// freed, and is reported in stats().blocks_outliving_scope. Correctness never rests on the
// library freeing everything in time; only the "no heap" property does, and the tests check it.
//
// Full region: a request that does not fit is served by the heap (ScratchAllocate returns
// nullptr) and counted in stats().overflows, so an undersized region shows in telemetry and in
// the allocation tests instead of failing a tick.
//
// Threads: the active scope is per thread (thread_local); the region may be freed into from any
// thread (the live count is atomic, region lookup reads fixed bounds). One scope per region at a
// time; nesting on the same thread is allowed (only the outermost resets).
//
// Lifetime: a FrameScratch destroyed while blocks of it are still live (only a bug can do that)
// keeps its mapping and its table entry, so that freeing those blocks later stays harmless; the
// memory is then the process's until it exits.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace zm {

struct FrameScratchStats {
  std::size_t capacity_bytes = 0;
  std::size_t high_water_bytes = 0;          // most bytes in use at once since creation
  std::uint64_t allocations = 0;             // requests served from the region
  std::uint64_t overflows = 0;               // requests that did not fit (served by the heap)
  std::uint64_t scopes = 0;                  // outermost scopes closed
  std::uint64_t blocks_outliving_scope = 0;  // blocks still live when an outermost scope closed
};

class FrameScratch {
 public:
  // Reserves `bytes` (rounded up to pages) of anonymous memory and touches it, so the first
  // frame does not page-fault it in. Returns nullptr with *error set when the mapping fails or
  // bytes is 0 or above 1 GiB.
  static std::unique_ptr<FrameScratch> Create(std::size_t bytes, std::string* error);
  // What Create(bytes) reserves: bytes rounded up to whole pages (the memory budget counts this).
  [[nodiscard]] static std::size_t ReservedBytes(std::size_t bytes);
  ~FrameScratch();
  FrameScratch(const FrameScratch&) = delete;
  FrameScratch& operator=(const FrameScratch&) = delete;

  [[nodiscard]] FrameScratchStats stats() const;
  [[nodiscard]] std::size_t capacity() const { return size_; }
  [[nodiscard]] bool Contains(const void* p) const {
    const auto a = reinterpret_cast<std::uintptr_t>(p);
    return a >= base_ && a < base_ + size_;
  }

  // Internal to the hook and the scope (public so the allocator hook can reach them).
  void* Allocate(std::size_t n, std::size_t align) noexcept;
  void OpenScope() noexcept;
  void CloseScope() noexcept;

 private:
  FrameScratch(std::size_t region, std::uintptr_t base, std::size_t size)
      : region_(region), base_(base), size_(size) {}
  [[nodiscard]] std::int64_t live() const noexcept;

  // The region's entry in the process-wide table ScratchFree() reads (its live count too: a
  // block may be freed after this object is gone, see the destructor).
  std::size_t region_ = 0;
  std::uintptr_t base_ = 0;
  std::size_t size_ = 0;
  std::size_t used_ = 0;  // bump offset; only the scope's thread moves it
  FrameScratchStats stats_;
};

// While alive, this thread's ScratchAllocate() serves from `scratch`.
class ScratchScope {
 public:
  explicit ScratchScope(FrameScratch& scratch) noexcept;
  ~ScratchScope();
  ScratchScope(const ScratchScope&) = delete;
  ScratchScope& operator=(const ScratchScope&) = delete;

 private:
  FrameScratch* previous_;
  FrameScratch* scratch_;
};

// The hook the global allocator calls. ScratchAllocate: a block from this thread's active
// scope's region, or nullptr (no scope, or it does not fit). ScratchFree: true when p belongs to
// a live FrameScratch region (the block is released there; the caller must not free it).
void* ScratchAllocate(std::size_t n, std::size_t align) noexcept;
bool ScratchFree(void* p) noexcept;
// True when p lies in any live FrameScratch region (without releasing it).
bool FrameScratchContains(const void* p) noexcept;

}  // namespace zm
