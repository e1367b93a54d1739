// Fixed-slot arena. See arena.h for the contract. One mmap holds the slots followed by the
// bookkeeping (free-slot stack, in-use flags), so the whole arena is one reservation and
// nothing here ever touches the heap after Create().
#include "arena/arena.h"

#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cassert>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <utility>

namespace zm {
namespace {

constexpr std::uint64_t kMiB = 1024ULL * 1024ULL;

std::uint64_t AlignUp(std::uint64_t v, std::uint64_t a) { return (v + a - 1) / a * a; }

std::string Mib(std::uint64_t bytes) {
  // Two decimals are enough to tell a limit from a request in an error message.
  const double mib = static_cast<double>(bytes) / static_cast<double>(kMiB);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.2f MiB", mib);
  return buf;
}

// The largest reservation this process can make: physical memory, and RLIMIT_AS if set.
std::uint64_t MachineLimitBytes(std::string* what) {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page = sysconf(_SC_PAGE_SIZE);
  std::uint64_t limit = std::numeric_limits<std::uint64_t>::max();
  *what = "unknown";
  if (pages > 0 && page > 0) {
    limit = static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page);
    *what = "physical memory";
  }
  rlimit rl{};
  if (getrlimit(RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY &&
      static_cast<std::uint64_t>(rl.rlim_cur) < limit) {
    limit = static_cast<std::uint64_t>(rl.rlim_cur);
    *what = "RLIMIT_AS";
  }
  return limit;
}

std::uint64_t PageBytes() {
  const long page = sysconf(_SC_PAGE_SIZE);
  return page > 0 ? static_cast<std::uint64_t>(page) : 4096;
}

// Writes one byte in every page of [p, p + bytes) that mincore() does not report resident, so
// the range is resident on return. MAP_POPULATE populates silently and only as far as it can
// (and qemu-user ignores it), so the arena checks instead of trusting it. Writing (not reading)
// matters: a read maps the shared zero page, which nobody is charged for. `vec` is a stack
// buffer: nothing is allocated.
void FaultInMissingPages(std::byte* p, std::uint64_t bytes, std::uint64_t page) {
  constexpr std::uint64_t kChunkPages = 1024;
  unsigned char vec[kChunkPages];
  for (std::uint64_t off = 0; off < bytes; off += kChunkPages * page) {
    const std::uint64_t len = std::min(bytes - off, kChunkPages * page);
    const std::uint64_t pages = (len + page - 1) / page;
    const bool known = mincore(p + off, static_cast<std::size_t>(len), vec) == 0;
    for (std::uint64_t i = 0; i < pages; ++i) {
      if (known && (vec[i] & 1U) != 0) continue;
      volatile std::byte* b = p + off + i * page;
      *b = *b;  // the page's own value: zero in a fresh page, unchanged otherwise
    }
  }
}

bool PoisonByDefault() {
#if defined(ZM_ARENA_POISON)
  return ZM_ARENA_POISON != 0;
#elif defined(NDEBUG)
  return false;
#else
  return true;
#endif
}

}  // namespace

std::uint64_t ArenaSlotBytes(std::uint64_t slot_bytes, bool release_to_os) {
  // A slot given back to the kernel must own whole pages, or releasing it would drop (or keep)
  // a neighbour's bytes.
  const std::uint64_t alignment = release_to_os
                                      ? std::max<std::uint64_t>(Arena::kSlotAlignment, PageBytes())
                                      : Arena::kSlotAlignment;
  return AlignUp(slot_bytes, alignment);
}

std::variant<ArenaPlan, ArenaError> PlanArena(const ArenaConfig& config) {
  if (config.slot_bytes == 0) {
    return ArenaError{ArenaErrorCode::kZeroSlotBytes, "arena: slot_bytes is 0; it must be at "
                                                      "least the largest keyframe payload"};
  }
  if (config.memory_thr_keyframes == 0 && config.budget_bytes == 0) {
    return ArenaError{ArenaErrorCode::kNoBudget,
                      "arena: no budget: give MemoryThr as a keyframe count, as bytes, or both"};
  }
  const std::uint64_t slot = ArenaSlotBytes(config.slot_bytes, config.release_to_os);
  if (config.budget_bytes != 0 && slot > config.budget_bytes) {
    return ArenaError{ArenaErrorCode::kSlotLargerThanBudget,
                      "arena: one slot (" + std::to_string(slot) +
                          " bytes) is larger than the byte budget (" +
                          std::to_string(config.budget_bytes) + " bytes)"};
  }
  std::uint64_t slots = std::numeric_limits<std::uint64_t>::max();
  if (config.memory_thr_keyframes != 0) slots = config.memory_thr_keyframes;
  if (config.budget_bytes != 0) slots = std::min(slots, config.budget_bytes / slot);
  if (slots == 0) {
    return ArenaError{ArenaErrorCode::kZeroSlots, "arena: the budget allows 0 slots"};
  }
  if (slots > std::numeric_limits<std::uint32_t>::max() - 1) {
    return ArenaError{ArenaErrorCode::kTooManySlots,
                      "arena: " + std::to_string(slots) + " slots exceed the limit of " +
                          std::to_string(std::numeric_limits<std::uint32_t>::max() - 1)};
  }
  if (slots > std::numeric_limits<std::uint64_t>::max() / slot) {
    return ArenaError{ArenaErrorCode::kExceedsMachine, "arena: slots * slot_bytes overflows"};
  }
  return ArenaPlan{static_cast<std::uint32_t>(slots), slot, slots * slot};
}

std::variant<Arena, ArenaError> Arena::Create(const ArenaConfig& config) {
  if (config.lock && config.release_to_os) {
    return ArenaError{ArenaErrorCode::kConflictingOptions,
                      "arena: lock and release_to_os conflict: locked pages cannot be given back "
                      "to the kernel (map.lock_arena with a policy whose arena holds the whole "
                      "map)"};
  }
  auto planned = PlanArena(config);
  if (auto* err = std::get_if<ArenaError>(&planned)) return std::move(*err);
  const ArenaPlan plan = std::get<ArenaPlan>(planned);

  const std::uint64_t stack_bytes = AlignUp(std::uint64_t{plan.slots} * 4, kSlotAlignment);
  const std::uint64_t flag_bytes = AlignUp(plan.slots, kSlotAlignment);
  const std::uint64_t total = plan.bytes + stack_bytes + flag_bytes;

  std::string limit_name;
  const std::uint64_t machine = MachineLimitBytes(&limit_name);
  if (total > machine) {
    return ArenaError{ArenaErrorCode::kExceedsMachine,
                      "arena: reservation of " + Mib(total) + " (" + std::to_string(plan.slots) +
                          " slots x " + std::to_string(plan.slot_bytes) + " bytes) exceeds " +
                          limit_name + " (" + Mib(machine) + ")"};
  }

  // With release_to_os the reservation starts empty: a slot's memory is taken when it is
  // acquired (prefault) or written, not at start-up.
  const bool populate = config.prefault && !config.release_to_os;
  int flags = MAP_PRIVATE | MAP_ANONYMOUS;
  if (populate) flags |= MAP_POPULATE;
  void* mem = mmap(nullptr, static_cast<std::size_t>(total), PROT_READ | PROT_WRITE, flags, -1, 0);
  if (mem == MAP_FAILED) {
    return ArenaError{ArenaErrorCode::kReserveFailed,
                      "arena: mmap of " + Mib(total) + " failed: " + std::strerror(errno)};
  }

  Arena arena;
  arena.base_ = static_cast<std::byte*>(mem);
  arena.mapping_bytes_ = static_cast<std::size_t>(total);
  arena.free_stack_ = reinterpret_cast<std::uint32_t*>(arena.base_ + plan.bytes);
  arena.in_use_flags_ = reinterpret_cast<std::uint8_t*>(arena.base_ + plan.bytes + stack_bytes);
  arena.capacity_ = plan.slots;
  arena.slot_bytes_ = plan.slot_bytes;
  arena.poison_ = PoisonByDefault();
  arena.release_to_os_ = config.release_to_os;
  arena.prefault_slots_ = config.prefault && config.release_to_os;
  arena.page_bytes_ = static_cast<std::uint32_t>(PageBytes());
  if (populate) FaultInMissingPages(arena.base_, plan.bytes, arena.page_bytes_);
  // Lowest index on top, so a fresh arena hands out slots 0, 1, 2, ... (predictable in tests
  // and touches memory front to back).
  for (std::uint32_t i = 0; i < plan.slots; ++i) arena.free_stack_[i] = plan.slots - 1 - i;
  arena.free_top_ = plan.slots;
  std::memset(arena.in_use_flags_, 0, plan.slots);

  if (config.lock) {
    if (mlock(mem, static_cast<std::size_t>(total)) != 0) {
      rlimit rl{};
      getrlimit(RLIMIT_MEMLOCK, &rl);
      const std::string lim = rl.rlim_cur == RLIM_INFINITY
                                  ? std::string("unlimited")
                                  : Mib(static_cast<std::uint64_t>(rl.rlim_cur));
      return ArenaError{ArenaErrorCode::kLockFailed,
                        "arena: mlock of " + Mib(total) + " failed (" + std::strerror(errno) +
                            "); RLIMIT_MEMLOCK is " + lim};
    }
    arena.locked_ = true;
  }
  return arena;
}

Arena::Arena(Arena&& other) noexcept { *this = std::move(other); }

Arena& Arena::operator=(Arena&& other) noexcept {
  if (this != &other) {
    Unmap();
    base_ = std::exchange(other.base_, nullptr);
    mapping_bytes_ = std::exchange(other.mapping_bytes_, 0);
    free_stack_ = std::exchange(other.free_stack_, nullptr);
    in_use_flags_ = std::exchange(other.in_use_flags_, nullptr);
    free_top_ = std::exchange(other.free_top_, 0);
    capacity_ = std::exchange(other.capacity_, 0);
    in_use_ = std::exchange(other.in_use_, 0);
    withheld_ = std::exchange(other.withheld_, 0);
    high_water_ = std::exchange(other.high_water_, 0);
    slot_bytes_ = std::exchange(other.slot_bytes_, 0);
    refused_ = std::exchange(other.refused_, 0);
    bad_releases_ = std::exchange(other.bad_releases_, 0);
    released_to_os_ = std::exchange(other.released_to_os_, 0);
    release_failures_ = std::exchange(other.release_failures_, 0);
    locked_ = std::exchange(other.locked_, false);
    poison_ = std::exchange(other.poison_, false);
    release_to_os_ = std::exchange(other.release_to_os_, false);
    prefault_slots_ = std::exchange(other.prefault_slots_, false);
    page_bytes_ = other.page_bytes_;
  }
  return *this;
}

Arena::~Arena() { Unmap(); }

void Arena::Unmap() noexcept {
  if (base_ == nullptr) return;
  if (locked_) munlock(base_, mapping_bytes_);
  munmap(base_, mapping_bytes_);
  base_ = nullptr;
}

std::optional<SlotIndex> Arena::TryAcquire() noexcept {
  if (free_top_ <= withheld_) {  // full, or every free slot withheld
    ++refused_;
    return std::nullopt;
  }
  const std::uint32_t idx = free_stack_[--free_top_];
  in_use_flags_[idx] = 1;
  ++in_use_;
  if (in_use_ > high_water_) high_water_ = in_use_;
  std::byte* p = base_ + std::uint64_t{idx} * slot_bytes_;
  if (poison_) {
    std::memset(p, std::to_integer<int>(kAcquiredPattern), slot_bytes_);
  } else if (prefault_slots_) {
    // One write per page: the slot's memory is taken now, not in the middle of its load.
    for (std::uint64_t off = 0; off < slot_bytes_; off += page_bytes_) {
      volatile std::byte* b = p + off;
      *b = std::byte{0};
    }
  }
  return SlotIndex{idx};
}

void Arena::Release(SlotIndex slot) noexcept {
  const std::uint32_t idx = slot.value;
  if (idx >= capacity_ || in_use_flags_[idx] == 0) {
    assert(false && "Arena::Release of a slot that is not in use");
    ++bad_releases_;
    return;
  }
  in_use_flags_[idx] = 0;
  --in_use_;
  free_stack_[free_top_++] = idx;
  std::byte* p = base_ + std::uint64_t{idx} * slot_bytes_;
  if (release_to_os_) {
    // The pages go back to the kernel at once (and uncharge the memory cgroup); the next touch
    // faults in zeroed pages. Not poisoned: that would fault them straight back in.
    if (madvise(p, static_cast<std::size_t>(slot_bytes_), MADV_DONTNEED) == 0) {
      ++released_to_os_;
    } else {
      ++release_failures_;
    }
  } else if (poison_) {
    std::memset(p, std::to_integer<int>(kReleasedPattern), slot_bytes_);
  }
}

std::span<std::byte> Arena::Slot(SlotIndex slot) noexcept {
  assert(slot.value < capacity_);
  return {base_ + std::uint64_t{slot.value} * slot_bytes_, static_cast<std::size_t>(slot_bytes_)};
}

std::span<const std::byte> Arena::Slot(SlotIndex slot) const noexcept {
  assert(slot.value < capacity_);
  return {base_ + std::uint64_t{slot.value} * slot_bytes_, static_cast<std::size_t>(slot_bytes_)};
}

std::uint32_t Arena::Withhold(std::uint32_t slots) noexcept {
  withheld_ = slots < free_top_ ? slots : free_top_;
  return withheld_;
}

bool Arena::InUse(SlotIndex slot) const noexcept {
  return slot.value < capacity_ && in_use_flags_[slot.value] != 0;
}

ArenaStats Arena::stats() const noexcept {
  ArenaStats s;
  s.capacity = capacity_;
  s.in_use = in_use_;
  s.available = available();
  s.withheld = withheld_;
  s.high_water = high_water_;
  s.refused = refused_;
  s.bad_releases = bad_releases_;
  s.slot_bytes = slot_bytes_;
  s.bytes_reserved = mapping_bytes_;
  s.released_to_os = released_to_os_;
  s.release_failures = release_failures_;
  s.release_to_os = release_to_os_;
  return s;
}

void Arena::ResetCounters() noexcept {
  high_water_ = in_use_;
  refused_ = 0;
}

}  // namespace zm
