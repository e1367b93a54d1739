// A child memory cgroup the size of the device under test (design.md, "The device under test").
//
// The experiment creates one child of the cgroup it runs in, limits it to the profile's device
// memory less its OS reserve, moves the map process and the co-tenant into it, and removes it
// afterwards; out of memory is then the kernel's (an OOM kill, counted by the cgroup). Both
// hierarchies are handled: v1 (`N:memory:/path`, memory.limit_in_bytes, memory.memsw.*,
// memory.oom_control) and v2 (`0::/path` with memory in cgroup.controllers, memory.max,
// memory.swap.max, memory.events). Swap is limited too where the kernel accounts it, so pressure
// cannot hide in swap.
//
// Invariants:
//   - A child is named <prefix>-<pid>-<start>-<n> (the creating process's pid and start time in
//     clock ticks, so a reused pid is not mistaken for the creator); RemoveStaleCgroups() removes
//     the children whose creator is gone.
//   - Remove() (and the destructor) kills what is still inside and removes the directory; the
//     process that created the cgroup is never inside it.
//   - Sample() and EnterSelf() never allocate (files are opened at Create(), read with pread into
//     a stack buffer); EnterSelf() is async-signal-safe, for a child between fork() and exec().
//   - Every error names the file and the value or limit involved.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"

namespace zm {

enum class CgroupVersion { kV1, kV2 };
[[nodiscard]] std::string_view CgroupVersionName(CgroupVersion version);  // "v1", "v2"

// Where a memory cgroup lives in the mounted hierarchy.
struct CgroupLocation {
  CgroupVersion version = CgroupVersion::kV1;
  std::string dir;  // absolute directory, e.g. /sys/fs/cgroup/memory/process_api/<id>
};

// From the text of /proc/<pid>/cgroup and /proc/<pid>/mountinfo, without touching the file
// system: v1's memory line (hybrid machines mount v2 without the memory controller) else v2's
// `0::` line. NotFound, saying which, when there is none or its hierarchy is not mounted.
[[nodiscard]] Result<CgroupLocation> LocateMemoryCgroup(std::string_view proc_cgroup,
                                                        std::string_view mountinfo);
// This process's memory cgroup; for v2, also checks that cgroup.controllers lists memory.
[[nodiscard]] Result<CgroupLocation> LocateOwnMemoryCgroup();

struct CgroupOptions {
  std::string prefix = "zm-device";  // child names: <prefix>-<pid>-<start>-<n>; no '/'
  std::uint64_t limit_bytes = 0;     // memory limit of the child (> 0)
  // Swap the child may use (the device's swap, harness/swap_device.h); 0 = none. v1:
  // memory.memsw.limit_in_bytes = limit + swap (set after the memory limit: memsw may never be
  // below it); v2: memory.swap.max = swap.
  std::uint64_t swap_bytes = 0;
  // v1 memory.swappiness of the child (v2 has none: the machine's vm.swappiness applies); < 0 =
  // inherited. The device's is JetPack's, the kernel default 60 (device_run.cc).
  int swappiness = -1;
  std::string parent_dir;    // "" = the cgroup this process runs in
  bool remove_stale = true;  // first remove children left by crashed earlier runs
};

// One reading of a cgroup's counters. Allocation-free.
struct CgroupSample {
  std::uint64_t usage_bytes = 0;  // v1 memory.usage_in_bytes, v2 memory.current
  std::uint64_t peak_bytes = 0;   // v1 memory.max_usage_in_bytes, v2 memory.peak; where the
                                  // kernel keeps no peak, the highest usage sampled
  std::uint64_t oom_kills = 0;    // processes the kernel OOM-killed in it (v1 memory.oom_control
                                  // oom_kill, v2 memory.events oom_kill)
  std::uint64_t swap_bytes = 0;   // swapped out of it now: v1 memory.memsw.usage_in_bytes -
                                  // memory.usage_in_bytes, v2 memory.swap.current
  std::uint64_t limit_hits = 0;   // times a charge met the limit (v1 memory.failcnt +
                                  // memory.memsw.failcnt, v2 memory.events max); best
                                  // effort: Linux 6.18's v1 failcnt stays 0 through OOM kills
  bool under_oom = false;         // v1 under_oom: an OOM is being handled right now
  bool ok = false;                // every counter was read
};

class Cgroup {
 public:
  // Finds the parent (options.parent_dir or this process's cgroup), removes stale children,
  // creates a uniquely named child and sets its limits. Errors: no memory cgroup here, no
  // permission, a limit the kernel refused or the parents' limits (or the machine) cannot honour.
  [[nodiscard]] static Result<Cgroup> Create(const CgroupOptions& options);

  Cgroup() = default;
  Cgroup(Cgroup&& other) noexcept;
  Cgroup& operator=(Cgroup&& other) noexcept;
  Cgroup(const Cgroup&) = delete;
  Cgroup& operator=(const Cgroup&) = delete;
  ~Cgroup();  // Remove(), errors dropped

  // Moves a running process in. Memory it touched before stays charged where it was (v2
  // never moves charges, v1 only with the deprecated move_charge_at_immigrate): start children
  // inside with EnterSelf() instead (harness/device_model.h SpawnInDevice).
  [[nodiscard]] Status AddProcess(pid_t pid) const;
  // Moves the calling process in: 0 or an errno. Async-signal-safe (one write to a file opened at
  // Create()), for a child between fork() and exec(), before it allocates.
  [[nodiscard]] int EnterSelf() const noexcept;
  // Reads the counters. Allocation-free; `ok` false when a file could not be read.
  [[nodiscard]] CgroupSample Sample() noexcept;
  // Sets the child's memory limit to `bytes` (<= the limit it was created with; v1
  // memory.limit_in_bytes, v2 memory.max): what the device's DRAM has left for the processes
  // when something outside the cgroup occupies part of it (zram's compressed pages,
  // ChargedLimit below). v1's memsw limit stays limit + swap as created, which is above. A lower
  // limit than the usage makes the kernel reclaim (swap) inside the write; where it cannot, v1
  // refuses (EBUSY) and the limit stays: the error says so. Not for the tick loop (allocates).
  [[nodiscard]] Status SetMemoryLimit(std::uint64_t bytes);
  // The limit in force now (limit_bytes() is the one the device was created with).
  [[nodiscard]] std::uint64_t current_limit_bytes() const noexcept { return current_limit_bytes_; }
  // The processes inside now (cgroup.procs).
  [[nodiscard]] Result<std::vector<pid_t>> Processes() const;
  // Kills what is still inside (SIGKILL), waits for it to leave, removes the directory.
  // Idempotent.
  [[nodiscard]] Status Remove();

  [[nodiscard]] const std::string& dir() const noexcept { return dir_; }
  [[nodiscard]] CgroupVersion version() const noexcept { return version_; }
  [[nodiscard]] std::uint64_t limit_bytes() const noexcept { return limit_bytes_; }  // as set
  [[nodiscard]] bool swap_limited() const noexcept { return swap_limited_; }
  [[nodiscard]] std::uint64_t swap_limit_bytes() const noexcept { return swap_limit_bytes_; }
  [[nodiscard]] bool active() const noexcept { return !dir_.empty(); }

 private:
  void CloseFiles() noexcept;

  std::string dir_;
  CgroupVersion version_ = CgroupVersion::kV1;
  std::uint64_t limit_bytes_ = 0;
  std::uint64_t current_limit_bytes_ = 0;
  std::uint64_t sampled_peak_ = 0;
  bool swap_limited_ = false;
  std::uint64_t swap_limit_bytes_ = 0;
  int procs_fd_ = -1;  // cgroup.procs, O_WRONLY (EnterSelf)
  int usage_fd_ = -1;
  int peak_fd_ = -1;           // -1 where the kernel keeps no peak (v2 before 5.19)
  int events_fd_ = -1;         // v1 memory.oom_control, v2 memory.events
  int failcnt_fd_ = -1;        // v1 memory.failcnt
  int memsw_failcnt_fd_ = -1;  // v1 memory.memsw.failcnt: with swap limited, memsw meets it first
  int swap_fd_ = -1;           // v1 memory.memsw.usage_in_bytes, v2 memory.swap.current
};

// The device's memory limit with `outside_bytes` of its DRAM taken by something the cgroup is
// not charged for (zram's compressed store: on the Jetson it lives in the same 8 GB, here on the
// host outside the cgroup): `limit - outside`, the outside part rounded UP to `granularity_bytes`
// (so that small changes do not rewrite the limit at every sample), never below `floor_bytes`.
[[nodiscard]] std::uint64_t ChargedLimit(std::uint64_t limit_bytes, std::uint64_t outside_bytes,
                                         std::uint64_t granularity_bytes,
                                         std::uint64_t floor_bytes) noexcept;

// Removes the children of `parent_dir` named <prefix>-<pid>-<start>-<n> whose creator no longer
// runs (killing what is left inside them); returns how many were removed.
[[nodiscard]] Result<std::uint32_t> RemoveStaleCgroups(const std::string& parent_dir,
                                                       std::string_view prefix);

// Whether the parts of a child's name say it belongs to a live process; exposed for tests.
struct CgroupChildName {
  pid_t pid = 0;
  std::uint64_t start_ticks = 0;
  std::uint64_t sequence = 0;
};
[[nodiscard]] bool ParseCgroupChildName(std::string_view name, std::string_view prefix,
                                        CgroupChildName* out);

}  // namespace zm
