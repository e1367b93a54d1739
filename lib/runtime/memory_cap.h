// Process memory caps and the allocation-failure boundary.
//
// ApplyProcessCap() caps the calling process with setrlimit so that the map process cannot take
// more than its share of the device, then proves the cap is enforced by asking for a mapping
// larger than the cap (the probe must be refused). Which limit:
//   - RLIMIT_AS (address space) by default: counts every mapping, so the cap is exact for a
//     plain build.
//   - RLIMIT_DATA under AddressSanitizer: ASan reserves terabytes of virtual address space for
//     its shadow and allocator at start-up, so any RLIMIT_AS a device could want is already
//     exceeded and every later mmap would fail. RLIMIT_DATA (private writable mappings, Linux
//     >= 4.7) is set to the data already mapped plus the cap, i.e. it caps growth.
//   - Some environments accept setrlimit but do not enforce it (qemu-user ignores RLIMIT_AS and
//     RLIMIT_DATA because they would also limit the emulator): the probe detects that and the
//     report says enforced = false with the reason. Nothing is faked.
//
// Allocation failures (std::bad_alloc, a null malloc, a refused mmap) are caught at boundary
// helpers and counted process-wide as out-of-memory events; the caller carries on.
//
// Invariants: CountAllocFailure()/AllocFailureCount() are lock-free and allocation-free;
// GuardAllocation() never lets std::bad_alloc escape.
#pragma once

#include <cstddef>
#include <cstdint>
#include <new>
#include <string>

#include "common/status.h"

namespace zm {

enum class CapResource { kNone, kAddressSpace, kData };

[[nodiscard]] const char* CapResourceName(CapResource r);  // "none", "RLIMIT_AS", "RLIMIT_DATA"

struct CapReport {
  CapResource resource = CapResource::kNone;
  std::uint64_t cap_bytes = 0;       // what the caller asked for
  std::uint64_t baseline_bytes = 0;  // already mapped when RLIMIT_DATA caps growth
  std::uint64_t limit_bytes = 0;     // the value given to setrlimit
  bool enforced = false;             // the probe mapping beyond the cap was refused
  bool sanitizer = false;            // built with AddressSanitizer
  std::string note;                  // one line: what was done and why
};

enum class CapMode { kAuto, kAddressSpace, kData };

// Caps the process at cap_bytes (0 = no cap: report only). kAuto picks RLIMIT_AS, or
// RLIMIT_DATA under AddressSanitizer (see above). Errors: the kernel refused setrlimit, or the
// cap is below what the process already uses.
[[nodiscard]] Result<CapReport> ApplyProcessCap(std::uint64_t cap_bytes,
                                                CapMode mode = CapMode::kAuto);

// True when this build has AddressSanitizer.
[[nodiscard]] bool BuiltWithAddressSanitizer() noexcept;

// Current VmSize / VmData of this process from /proc/self/status (0 if unavailable).
[[nodiscard]] std::uint64_t ProcessAddressSpaceBytes();
[[nodiscard]] std::uint64_t ProcessDataBytes();

// Process-wide out-of-memory event counter (allocation failures caught at a boundary).
void CountAllocFailure() noexcept;
[[nodiscard]] std::uint64_t AllocFailureCount() noexcept;

// Runs fn(); if it throws std::bad_alloc, counts one failure and returns kResourceExhausted
// naming `what`. Allocation-free when fn succeeds.
template <class Fn>
[[nodiscard]] Status GuardAllocation(const char* what, Fn&& fn) {
  try {
    fn();
    return Status::Ok();
  } catch (const std::bad_alloc&) {
    CountAllocFailure();
    return ResourceExhausted(std::string("allocation failed: ") + what);
  }
}

// malloc that counts a null result as a failure. bytes == 0 returns nullptr without counting.
[[nodiscard]] void* TryMalloc(std::size_t bytes) noexcept;

// An anonymous private read-write mapping of `bytes` (rounded up to pages), or nullptr (counted
// as a failure) when the kernel refuses it, e.g. under a process cap. Release with UnmapBytes.
[[nodiscard]] void* TryMapBytes(std::size_t bytes) noexcept;
void UnmapBytes(void* p, std::size_t bytes) noexcept;

}  // namespace zm
