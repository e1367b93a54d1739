// Device ledger: a simulation of one device's memory shared by several processes (the map, the
// co-tenant, the OS reserve), kept in a small file mapped MAP_SHARED (by default under /dev/shm)
// with lock-free atomic counters, so every process sees the same totals.
//
// Each tenant holds a grant (bytes it owns now) and a demand (bytes it last asked for). A
// registration or update that would make the sum of grants exceed the device total is refused,
// like an allocation failure: the grant stays as it was, the demand records what was wanted,
// and an out-of-memory event is counted (device-wide and for the tenant). The device is
// "over-committed" while the sum of demands exceeds the total, i.e. until the refused tenant
// shrinks its demand or gets its grant.
//
// Invariants:
//   - sum of grants <= device total, always (checked with one compare-and-swap on the sum).
//   - peak_sum is the largest sum ever granted; oom_events only grows.
//   - Update() and Release() never allocate and never block (safe inside the tick loop);
//     Open() and Register() allocate and take a file lock (start-up only).
//   - A tenant slot is freed by Release() or by the LedgerTenant destructor; slots of processes
//     that died without releasing are reclaimed by ReapDeadTenants().
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"

namespace zm {

namespace ledger_internal {
struct Mapping;
struct TenantRecord;
}  // namespace ledger_internal

inline constexpr std::uint32_t kLedgerMaxTenants = 16;
inline constexpr std::size_t kLedgerNameBytes = 48;  // including the terminating NUL

struct LedgerTenantInfo {
  std::string name;
  std::int32_t pid = 0;
  std::uint64_t bytes = 0;       // granted now
  std::uint64_t demand_bytes = 0;  // last requested (== bytes unless a request was refused)
  std::uint64_t peak_bytes = 0;
  std::uint64_t oom_events = 0;
};

struct LedgerSnapshot {
  std::uint64_t device_bytes = 0;
  std::uint64_t sum_bytes = 0;     // sum of grants now
  std::uint64_t peak_sum_bytes = 0;
  std::uint64_t demand_bytes = 0;  // sum of demands now
  std::uint64_t oom_events = 0;
  std::vector<LedgerTenantInfo> tenants;
};

class DeviceLedger;

// One registered tenant. Movable, not copyable; releases its grant when destroyed. Keeps the
// ledger's mapping alive, so it may outlive the DeviceLedger it came from.
class LedgerTenant {
 public:
  LedgerTenant() = default;
  LedgerTenant(LedgerTenant&& other) noexcept;
  LedgerTenant& operator=(LedgerTenant&& other) noexcept;
  LedgerTenant(const LedgerTenant&) = delete;
  LedgerTenant& operator=(const LedgerTenant&) = delete;
  ~LedgerTenant();

  // Sets this tenant's grant to `bytes`. Growing beyond the device total is refused with
  // kResourceExhausted (grant unchanged, demand = bytes, one OOM event counted); shrinking
  // always succeeds. Allocation-free.
  [[nodiscard]] Status Update(std::uint64_t bytes) noexcept;
  // Same as Update() but returns only whether it was granted (no Status, for the hot path).
  [[nodiscard]] bool TryUpdate(std::uint64_t bytes) noexcept;
  // Gives the grant back and frees the slot. Idempotent.
  void Release() noexcept;

  [[nodiscard]] bool registered() const noexcept { return record_ != nullptr; }
  [[nodiscard]] std::uint64_t bytes() const noexcept;
  [[nodiscard]] std::uint64_t oom_events() const noexcept;

 private:
  friend class DeviceLedger;
  std::shared_ptr<ledger_internal::Mapping> mapping_;
  ledger_internal::TenantRecord* record_ = nullptr;
};

class DeviceLedger {
 public:
  // Opens the ledger file at `path`, creating and initialising it with device_bytes if it does
  // not exist or is empty. When it exists, device_bytes must be 0 (attach) or equal to its
  // total. Default path: DefaultLedgerPath().
  [[nodiscard]] static Result<DeviceLedger> Open(const std::string& path,
                                                 std::uint64_t device_bytes);
  // Removes the ledger file (the mapping of open handles stays valid).
  [[nodiscard]] static Status Remove(const std::string& path);
  // "/dev/shm/zonemap-ledger-<uid>" (or $TMPDIR when /dev/shm is absent).
  [[nodiscard]] static std::string DefaultLedgerPath();

  // Registers a tenant named `name` (at most kLedgerNameBytes-1 bytes) with an initial grant.
  // kResourceExhausted (and one OOM event) when the grant does not fit beside the others; the
  // slot is then not kept. kOutOfRange when all kLedgerMaxTenants slots are taken.
  [[nodiscard]] Result<LedgerTenant> Register(std::string_view name, std::uint64_t bytes);

  // Frees slots whose owning process no longer exists; returns how many. Start-up/reporting.
  std::uint32_t ReapDeadTenants();

  [[nodiscard]] std::uint64_t device_bytes() const noexcept;
  [[nodiscard]] std::uint64_t sum_bytes() const noexcept;
  [[nodiscard]] std::uint64_t peak_sum_bytes() const noexcept;
  [[nodiscard]] std::uint64_t oom_events() const noexcept;
  [[nodiscard]] std::uint64_t free_bytes() const noexcept;  // device - sum
  // Sum of demands > device total: someone wants memory the device does not have. Allocation
  // free, O(kLedgerMaxTenants).
  [[nodiscard]] bool OverCommitted() const noexcept;
  // Forgets the peak (sets it to the current sum); events are never reset.
  void ResetPeak() noexcept;
  [[nodiscard]] LedgerSnapshot Snapshot() const;
  [[nodiscard]] const std::string& path() const noexcept { return path_; }

 private:
  DeviceLedger() = default;
  std::shared_ptr<ledger_internal::Mapping> mapping_;
  std::string path_;
};

}  // namespace zm
