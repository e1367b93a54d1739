// Fixed-slot keyframe arena: all keyframe payload memory of the process, reserved once.
//
// The arena is sized once from the budget, K_max = min(memory_thr_keyframes,
// budget_bytes / slot_bytes) slots of slot_bytes each (rounded up to 64-byte alignment), in one
// anonymous mapping. After Create() nothing here allocates: TryAcquire() pops a free-slot stack,
// Release() pushes onto it, both O(1). When every slot is in use TryAcquire() refuses (returns
// nullopt) and counts the refusal; it never grows and never falls back to the heap. That is
// what makes "resident keyframes <= MemoryThr" a property of memory, not only of bookkeeping.
//
// Invariants:
//   - 0 <= in_use <= capacity; high_water >= in_use; slots never overlap.
//   - in_use + withheld <= capacity: Withhold() holds back free slots only, and TryAcquire()
//     refuses rather than hand one out.
//   - Slot(i) is a view of exactly slot_bytes inside the reservation.
//   - Release() of a slot that is not in use is a programmer error (asserted; ignored and
//     counted in release builds, so a bug cannot corrupt the free stack).
//
// Memory the kernel sees. By default the whole reservation is one private anonymous mapping
// whose pages become resident as they are first written (or all at Create() with `prefault`:
// the bounded policies' guarantee that their budget is resident before anything else starts).
// With `release_to_os` (basic and unbounded, whose arena spans the whole map like RTAB-Map's
// heap), slots are page-aligned and Release() hands the slot's pages back to the kernel with
// madvise(MADV_DONTNEED), so the process's resident memory, and the memory cgroup it is charged
// to, rise when a keyframe lands in a slot and fall when it leaves. MADV_FREE would not do:
// lazily freed pages stay charged to the cgroup until reclaim (measured: docs/harness.md).
//
// This target depends on nothing else of zonemap's (docs/style.md §1).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <variant>

namespace zm {

// Index of a slot in an Arena. A strong type so that slot numbers cannot be mixed with
// keyframe or zone ids.
struct SlotIndex {
  std::uint32_t value = 0;
  friend constexpr bool operator==(SlotIndex, SlotIndex) = default;
  friend constexpr auto operator<=>(SlotIndex, SlotIndex) = default;
};

struct ArenaConfig {
  std::uint64_t memory_thr_keyframes = 0;  // MemoryThr as a count; 0 = no count limit
  std::uint64_t budget_bytes = 0;          // map share in bytes; 0 = no byte limit
  std::uint64_t slot_bytes = 0;            // largest keyframe payload; rounded up to 64
  bool lock = false;                       // mlock the reservation (no swap, no page faults)
  bool prefault = false;                   // MAP_POPULATE: touch every page up front; with
                                           // release_to_os, every page of a slot on acquire
  // Give a released slot's pages back to the kernel (MADV_DONTNEED): resident memory follows
  // the slots in use. Slots are then page-aligned; incompatible with `lock`. A released slot
  // reads as zeros (poisoning it would fault its pages back in).
  bool release_to_os = false;
};

struct ArenaStats {
  std::uint32_t capacity = 0;         // slots (K_max)
  std::uint32_t in_use = 0;           // slots acquired and not released
  std::uint32_t available = 0;        // capacity - in_use - withheld: what TryAcquire can give
  std::uint32_t withheld = 0;         // free slots held back (Withhold)
  std::uint32_t high_water = 0;       // largest in_use ever seen
  std::uint64_t refused = 0;          // TryAcquire() calls that found the arena full
  std::uint64_t bad_releases = 0;     // Release() of a slot not in use (programmer error)
  std::uint64_t slot_bytes = 0;       // bytes per slot (64-aligned)
  std::uint64_t bytes_reserved = 0;   // capacity * slot_bytes (+ bookkeeping)
  std::uint64_t released_to_os = 0;   // Release() calls that gave the slot's pages back
  std::uint64_t release_failures = 0;  // madvise refusals (the pages stayed resident)
  bool release_to_os = false;         // the arena's configuration, for reports
};

enum class ArenaErrorCode {
  kZeroSlots,         // the budget allows no slot at all
  kZeroSlotBytes,     // slot_bytes == 0
  kSlotLargerThanBudget,
  kNoBudget,          // neither a keyframe count nor a byte budget was given
  kTooManySlots,      // more slots than a 32-bit SlotIndex can name
  kExceedsMachine,    // reservation larger than physical memory or RLIMIT_AS
  kReserveFailed,     // mmap refused
  kLockFailed,        // mlock refused (RLIMIT_MEMLOCK)
  kConflictingOptions,  // lock with release_to_os: locked pages cannot be given back
};

struct ArenaError {
  ArenaErrorCode code;
  std::string message;  // names the quantity and the limit it broke
};

// Computes K_max and the aligned slot size without reserving anything. Shared by Create() and
// by callers (reports, profiles) that need the arithmetic alone.
// The slot size the arena uses for `slot_bytes`: rounded up to 64 bytes, or to a page with
// release_to_os (a slot given back to the kernel must own whole pages). The one alignment rule:
// PlanArena applies it and DeriveBudget (runtime/budget.h) reports it, so the arena a budget asks
// for (arena slots x aligned slot bytes) is exactly the arena made.
[[nodiscard]] std::uint64_t ArenaSlotBytes(std::uint64_t slot_bytes, bool release_to_os);

struct ArenaPlan {
  std::uint32_t slots = 0;
  std::uint64_t slot_bytes = 0;  // aligned (to a page with release_to_os)
  std::uint64_t bytes = 0;       // slots * slot_bytes
};
[[nodiscard]] std::variant<ArenaPlan, ArenaError> PlanArena(const ArenaConfig& config);

class Arena {
 public:
  static constexpr std::size_t kSlotAlignment = 64;
  static constexpr std::byte kAcquiredPattern{0xA5};
  static constexpr std::byte kReleasedPattern{0xDD};

  // Reserves the whole arena. The only allocating call.
  [[nodiscard]] static std::variant<Arena, ArenaError> Create(const ArenaConfig& config);

  Arena(Arena&& other) noexcept;
  Arena& operator=(Arena&& other) noexcept;
  Arena(const Arena&) = delete;
  Arena& operator=(const Arena&) = delete;
  ~Arena();

  // O(1). nullopt when full: the caller must free a slot first. Never allocates. With
  // release_to_os and prefault, writes one byte per page so the slot is resident on return.
  [[nodiscard]] std::optional<SlotIndex> TryAcquire() noexcept;
  // O(1). The slot's bytes must not be used afterwards. With release_to_os, one madvise call.
  void Release(SlotIndex slot) noexcept;
  // Holds back `slots` of the free slots from TryAcquire (clamped to those free now; the count
  // is set, not added; 0 gives them all back) and returns how many are held. A gate for a
  // caller that must stop loads without touching a slot, e.g. the device ledger refusing the
  // map process's grant (harness/device_run.cc). Slots released afterwards are not held back.
  // O(1), touches no slot memory.
  std::uint32_t Withhold(std::uint32_t slots) noexcept;

  // The slot's memory: exactly slot_bytes(), 64-byte aligned. slot must be < capacity().
  [[nodiscard]] std::span<std::byte> Slot(SlotIndex slot) noexcept;
  [[nodiscard]] std::span<const std::byte> Slot(SlotIndex slot) const noexcept;
  [[nodiscard]] bool InUse(SlotIndex slot) const noexcept;

  [[nodiscard]] std::uint32_t capacity() const noexcept { return capacity_; }
  [[nodiscard]] std::uint32_t in_use() const noexcept { return in_use_; }
  [[nodiscard]] std::uint32_t available() const noexcept {
    return capacity_ - in_use_ - withheld_;
  }
  [[nodiscard]] std::uint32_t withheld() const noexcept { return withheld_; }
  [[nodiscard]] std::uint64_t slot_bytes() const noexcept { return slot_bytes_; }
  [[nodiscard]] bool poisoning() const noexcept { return poison_; }
  [[nodiscard]] bool releases_to_os() const noexcept { return release_to_os_; }
  [[nodiscard]] bool locked() const noexcept { return locked_; }
  [[nodiscard]] ArenaStats stats() const noexcept;
  // Forgets the high-water mark and refusal count (e.g. after warm-up); occupancy is kept.
  void ResetCounters() noexcept;

 private:
  Arena() = default;
  void Unmap() noexcept;

  std::byte* base_ = nullptr;         // slot memory, capacity_ * slot_bytes_
  std::size_t mapping_bytes_ = 0;     // whole mapping incl. bookkeeping
  std::uint32_t* free_stack_ = nullptr;  // capacity_ entries; top at free_top_
  std::uint8_t* in_use_flags_ = nullptr;  // one byte per slot
  std::uint32_t free_top_ = 0;        // number of free entries on the stack
  std::uint32_t capacity_ = 0;
  std::uint32_t in_use_ = 0;
  std::uint32_t withheld_ = 0;        // <= free_top_ (Withhold)
  std::uint32_t high_water_ = 0;
  std::uint64_t slot_bytes_ = 0;
  std::uint64_t refused_ = 0;
  std::uint64_t bad_releases_ = 0;
  std::uint64_t released_to_os_ = 0;
  std::uint64_t release_failures_ = 0;
  bool locked_ = false;
  bool poison_ = false;
  bool release_to_os_ = false;
  bool prefault_slots_ = false;  // release_to_os + prefault: fault each slot in on acquire
  std::uint32_t page_bytes_ = 4096;  // the kernel's page size (release_to_os granularity)
};

}  // namespace zm
