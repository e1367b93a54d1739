// The device under test, as the experiment sees it (design.md, "The device under test"): one
// memory pool of the profile's device memory less its OS reserve, shared by the map process and
// the co-tenant. Two implementations:
//   - cgroup: a child memory cgroup (harness/cgroup.h). Out of memory is the kernel's: an OOM
//     kill counted by the cgroup, the victim's SIGKILL.
//   - ledger: the shared device ledger (harness/device_ledger.h), a portable simulation where no
//     cgroup can be made. Processes register their grants themselves; a refused grant stands in
//     for out of memory. Everything it reports is labelled "simulated".
//
// OpenDeviceModel() makes the cgroup when it can and, unless told not to, falls back to the
// ledger, keeping the reason. Children go in with SpawnInDevice()/ForkInDevice(), which move
// the child between fork() and exec(), before it allocates anything.
//
// Invariants: Sample() and EnterSelf() never allocate; EnterSelf() is async-signal-safe; the
// process that opened the device is never inside it, so it outlives any OOM kill and writes the
// summary; Remove() (or destruction) leaves nothing behind.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "harness/cgroup.h"
#include "harness/device_ledger.h"
#include "harness/swap_device.h"

namespace zm {

enum class DeviceKind { kCgroup, kLedger };
[[nodiscard]] std::string_view DeviceKindName(DeviceKind kind);  // "cgroup", "ledger"
// "cgroup" or "ledger" (--device); an error names the value and the choices.
[[nodiscard]] Result<DeviceKind> ParseDeviceKind(std::string_view text);

// One reading of the device. For the ledger, usage is the sum of grants and oom_kills counts
// refused grants (simulated out-of-memory events).
struct DeviceSample {
  std::uint64_t usage_bytes = 0;
  std::uint64_t peak_bytes = 0;
  std::uint64_t oom_kills = 0;
  std::uint64_t swap_bytes = 0;  // the device's pages in swap now (cgroup; 0 for the ledger)
  std::uint64_t limit_hits = 0;  // times usage met the limit (cgroup failcnt / events max)
  bool under_oom = false;
  bool ok = false;
};

class DeviceModel {
 public:
  virtual ~DeviceModel() = default;

  [[nodiscard]] virtual DeviceKind kind() const noexcept = 0;
  // True for the ledger: its out-of-memory is a rule, not the kernel's. Reports say "simulated".
  [[nodiscard]] bool simulated() const noexcept { return kind() == DeviceKind::kLedger; }
  [[nodiscard]] virtual std::uint64_t limit_bytes() const noexcept = 0;
  // One line for reports: what the device is, where, its limit; "simulated" and the reason the
  // cgroup could not be made for the ledger.
  [[nodiscard]] virtual std::string Describe() const = 0;
  // Why a cgroup was asked for and not made (empty when none was or it was made).
  [[nodiscard]] const std::string& fallback_reason() const noexcept { return fallback_reason_; }

  // Puts a running process in the device (cgroup: its memory touched from now on; ledger:
  // nothing to do, tenants register their own grants).
  [[nodiscard]] virtual Status AddProcess(pid_t pid) = 0;
  // Moves the calling process in: 0 or an errno. Async-signal-safe (between fork and exec).
  [[nodiscard]] virtual int EnterSelf() const noexcept = 0;
  // Allocation-free.
  [[nodiscard]] virtual DeviceSample Sample() noexcept = 0;
  // Removes the device (cgroup: kills what is left inside, removes the directory; ledger:
  // removes its file). Idempotent.
  [[nodiscard]] virtual Status Remove() = 0;

  // The device's swap (kind none for the ledger, and where none could be had: reason() says why).
  [[nodiscard]] virtual const DeviceSwap& swap() const noexcept { return no_swap_; }
  // Allocation-free: the zram device's mm_stat (ok = false unless the swap is a zram of this run).
  [[nodiscard]] ZramSample SampleZram() const noexcept { return swap().Sample(); }

  // The implementation behind it, for what only one has (nullptr for the other).
  [[nodiscard]] virtual Cgroup* cgroup() noexcept { return nullptr; }
  [[nodiscard]] virtual DeviceLedger* ledger() noexcept { return nullptr; }

 protected:
  std::string fallback_reason_;  // set by the implementation that stands in

 private:
  DeviceSwap no_swap_;  // kind none: what a device without swap (the ledger) reports
};

struct DeviceModelOptions {
  DeviceKind kind = DeviceKind::kCgroup;
  // When a cgroup is asked for and cannot be made: the ledger (true, the default of --device)
  // or the error (false: --device cgroup given explicitly).
  bool fall_back_to_ledger = true;
  std::uint64_t limit_bytes = 0;  // DeviceLimitBytes() of the (scaled) device; > 0
  CgroupOptions cgroup;           // prefix, parent, swappiness; limit and swap set from here
  // The device's swap (cgroup only: made before the cgroup, whose swap limit is its size).
  SwapOptions swap;
  std::string ledger_path;  // "" = DeviceLedger::DefaultLedgerPath() + "-<pid>"
};

[[nodiscard]] Result<std::unique_ptr<DeviceModel>> OpenDeviceModel(
    const DeviceModelOptions& options);

struct SpawnRequest {
  std::vector<std::string> argv;  // argv[0] is looked up in PATH
  int stdin_fd = -1;              // becomes the child's stdin when >= 0
  int stdout_fd = -1;             // becomes the child's stdout when >= 0
  int stderr_fd = -1;             // becomes the child's stderr when >= 0
};

// fork(), move the child into `device`, redirect its standard streams, exec. The child never
// runs a single instruction of the program outside the device: if it cannot enter (or exec), it
// exits (127), is reaped, and the error names why.
[[nodiscard]] Result<pid_t> SpawnInDevice(const SpawnRequest& request, const DeviceModel& device);

// fork() with the child moved into `device` before fork returns in it: 0 in the child, the
// child's pid in the parent. For work that needs no exec (tests, a forked replay).
[[nodiscard]] Result<pid_t> ForkInDevice(const DeviceModel& device);

// How a child ended, from waitpid's status.
struct ChildExit {
  bool exited = false;  // normal exit with `code`
  int code = 0;
  bool signaled = false;  // killed by `signal` (SIGKILL: the OOM killer, or a Remove())
  int signal = 0;
};
[[nodiscard]] ChildExit DescribeWaitStatus(int wait_status) noexcept;

}  // namespace zm
