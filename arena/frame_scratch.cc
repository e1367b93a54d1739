// FrameScratch (see frame_scratch.h).
#include "arena/frame_scratch.h"

#include <sys/mman.h>
#include <unistd.h>

#include <array>
#include <cstring>

namespace zm {
namespace {

// The regions ScratchFree() may be asked about, from any thread. A handful at most (one per
// front-end); fixed so that the lookup never allocates or locks. An entry outlives its
// FrameScratch when blocks are still live at its destruction (see the header).
constexpr std::size_t kMaxRegions = 8;
struct Region {
  std::atomic<std::uintptr_t> base{0};  // 0: free entry
  std::atomic<std::size_t> size{0};
  std::atomic<std::int64_t> live{0};
};
std::array<Region, kMaxRegions> g_regions{};

Region* Find(const void* p) noexcept {
  const auto a = reinterpret_cast<std::uintptr_t>(p);
  for (Region& r : g_regions) {
    const std::uintptr_t base = r.base.load(std::memory_order_acquire);
    if (base != 0 && a >= base && a < base + r.size.load(std::memory_order_relaxed)) return &r;
  }
  return nullptr;
}

thread_local FrameScratch* t_active = nullptr;

constexpr std::size_t kMaxScratchBytes = std::size_t{1} << 30;

}  // namespace

std::unique_ptr<FrameScratch> FrameScratch::Create(std::size_t bytes, std::string* error) {
  if (bytes == 0 || bytes > kMaxScratchBytes) {
    *error = "frame scratch of " + std::to_string(bytes) + " bytes outside [1, " +
             std::to_string(kMaxScratchBytes) + "]";
    return nullptr;
  }
  const std::size_t size = ReservedBytes(bytes);
  void* p = mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) {
    *error = "frame scratch: mmap of " + std::to_string(size) + " bytes failed: " +
             std::strerror(errno);
    return nullptr;
  }
  std::memset(p, 0, size);  // resident now, not at the first frame
  const auto base = reinterpret_cast<std::uintptr_t>(p);
  for (std::size_t i = 0; i < kMaxRegions; ++i) {
    Region& r = g_regions[i];
    std::uintptr_t expected = 0;
    if (!r.base.compare_exchange_strong(expected, base, std::memory_order_acq_rel)) continue;
    // No block of the new region exists before Create returns, so a lookup that meanwhile sees
    // the base with the entry's old size cannot match one of ours wrongly.
    r.size.store(size, std::memory_order_release);
    r.live.store(0, std::memory_order_relaxed);
    std::unique_ptr<FrameScratch> s(new FrameScratch(i, base, size));
    s->stats_.capacity_bytes = size;
    return s;
  }
  munmap(p, size);
  *error = "frame scratch: more than " + std::to_string(kMaxRegions) + " regions";
  return nullptr;
}

std::size_t FrameScratch::ReservedBytes(std::size_t bytes) {
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  return (bytes + page - 1) / page * page;
}

FrameScratch::~FrameScratch() {
  if (live() != 0) return;  // blocks still out: the mapping and its entry stay (see the header)
  Region& r = g_regions[region_];
  munmap(reinterpret_cast<void*>(base_), size_);
  r.base.store(0, std::memory_order_release);
}

std::int64_t FrameScratch::live() const noexcept {
  return g_regions[region_].live.load(std::memory_order_acquire);
}

FrameScratchStats FrameScratch::stats() const { return stats_; }

void* FrameScratch::Allocate(std::size_t n, std::size_t align) noexcept {
  if (n == 0) n = 1;
  const std::uintptr_t start = (base_ + used_ + align - 1) & ~(std::uintptr_t{align} - 1);
  const std::uintptr_t end = start + n;
  if (end > base_ + size_ || end < start) {
    ++stats_.overflows;
    return nullptr;
  }
  used_ = end - base_;
  if (used_ > stats_.high_water_bytes) stats_.high_water_bytes = used_;
  ++stats_.allocations;
  g_regions[region_].live.fetch_add(1, std::memory_order_relaxed);
  return reinterpret_cast<void*>(start);
}

void FrameScratch::OpenScope() noexcept {
  if (live() == 0) used_ = 0;  // blocks that outlived an earlier scope may be back by now
}

void FrameScratch::CloseScope() noexcept {
  ++stats_.scopes;
  const std::int64_t n = live();
  if (n == 0) {
    used_ = 0;  // every block is back: the next scope starts at the base
  } else {
    // Keep the bump offset: the live blocks stay valid until they are freed (see the header).
    stats_.blocks_outliving_scope += static_cast<std::uint64_t>(n);
  }
}

ScratchScope::ScratchScope(FrameScratch& scratch) noexcept
    : previous_(t_active), scratch_(&scratch) {
  if (previous_ != scratch_) scratch_->OpenScope();
  t_active = &scratch;
}

ScratchScope::~ScratchScope() {
  t_active = previous_;
  // Only the outermost scope of a region closes it (a nested one on the same region is a no-op).
  if (previous_ != scratch_) scratch_->CloseScope();
}

void* ScratchAllocate(std::size_t n, std::size_t align) noexcept {
  FrameScratch* s = t_active;
  if (s == nullptr) return nullptr;
  return s->Allocate(n, align < alignof(std::max_align_t) ? alignof(std::max_align_t) : align);
}

bool FrameScratchContains(const void* p) noexcept { return p != nullptr && Find(p) != nullptr; }

bool ScratchFree(void* p) noexcept {
  if (p == nullptr) return false;
  Region* r = Find(p);
  if (r == nullptr) return false;
  r->live.fetch_sub(1, std::memory_order_acq_rel);
  return true;
}

}  // namespace zm
