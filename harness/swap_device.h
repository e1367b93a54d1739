// The device's swap, as JetPack sets it (issue 27 §2): a zram device of the profile's
// swap_bytes (nvzramconfig: half the memory), made for the run and removed after it.
//
// OpenDeviceSwap() first removes zram devices that earlier runs of this harness made and never
// removed (their owner is dead: a crash, a SIGKILL), then:
//   - where a swap is already active (a real Jetson: JetPack's own zram), uses it: kind existing;
//   - else hot-adds a zram device (/sys/class/zram-control/hot_add), lz4 when the kernel offers
//     it (else its default compressor), disksize = swap_bytes, writes the swap header itself and
//     swapon(2)s it at priority 5 (nvzramconfig's `swapon -p 5`): kind zram;
//   - where neither can be had (no zram module, not root, swapon refused), kind none, with the
//     reason in one line; whatever was half made is removed first.
// The cgroup's swap limit and swappiness are the cgroup's (harness/cgroup.h CgroupOptions).
//
// Invariants:
//   - Every zram device this module made has an owner record <owner_dir>/zram-<id> holding the
//     maker's pid and start time (clock ticks), written right after hot_add; a record whose
//     process is gone (or whose pid was reused) marks a stale device: swapoff, reset,
//     hot_remove, record removed. Devices without a record (zram0, JetPack's) are never touched.
//   - Remove() (and the destructor) leaves no swap, zram device or record of this run behind.
//   - Sample() never allocates (mm_stat opened once, read with pread).
//   - The system is reached through SwapSystem, whose paths and swapon/swapoff tests replace (a
//     fake sysfs root directory), so the stale-owner and fault paths are tested without root.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "common/status.h"

namespace zm {

enum class SwapKind { kNone, kZram, kExisting };
[[nodiscard]] std::string_view SwapKindName(SwapKind kind);  // "none", "zram", "existing"

// Where the swap machinery is. The defaults are the machine's.
struct SwapSystem {
  std::string sysfs_root = "/sys";  // class/zram-control/{hot_add,hot_remove}, block/zram<N>/
  std::string dev_root = "/dev";    // zram<N> block devices
  std::string owner_dir = "/run/zonemap";
  std::string proc_swaps = "/proc/swaps";
  // swapon(2) at the given priority / swapoff(2): 0 or an errno. Empty = the system calls.
  std::function<int(const std::string& path, int priority)> swap_on;
  std::function<int(const std::string& path)> swap_off;
};

struct SwapOptions {
  std::string requested = "none";  // the profile's device.swap: "none" or "zram"
  std::uint64_t bytes = 0;         // device.swap_bytes at the device scale (> 0 for zram)
  SwapSystem system;
};

// zram's memory accounting (/sys/block/zram<N>/mm_stat): what the compressed pages cost.
struct ZramSample {
  std::uint64_t orig_data_bytes = 0;  // uncompressed bytes swapped in to it
  std::uint64_t compr_data_bytes = 0;
  std::uint64_t mem_used_bytes = 0;  // memory the compressed pages occupy (with zsmalloc's slack)
  bool ok = false;
};

class DeviceSwap {
 public:
  DeviceSwap() = default;
  DeviceSwap(DeviceSwap&& other) noexcept;
  DeviceSwap& operator=(DeviceSwap&& other) noexcept;
  DeviceSwap(const DeviceSwap&) = delete;
  DeviceSwap& operator=(const DeviceSwap&) = delete;
  ~DeviceSwap();  // Remove(), errors dropped

  [[nodiscard]] SwapKind kind() const noexcept { return kind_; }
  // The swap the device may use: swap_bytes for zram and existing, 0 for none.
  [[nodiscard]] std::uint64_t bytes() const noexcept { return bytes_; }
  // Why the kind is not the one asked for (empty when it is); one line.
  [[nodiscard]] const std::string& reason() const noexcept { return reason_; }
  [[nodiscard]] const std::string& device_path() const noexcept { return device_path_; }
  [[nodiscard]] int zram_id() const noexcept { return zram_id_; }
  [[nodiscard]] const std::string& comp_algorithm() const noexcept { return comp_algorithm_; }
  // One line for reports.
  [[nodiscard]] std::string Describe() const;

  // The zram device's mm_stat (ok = false for kinds other than zram). Allocation-free.
  [[nodiscard]] ZramSample Sample() const noexcept;
  // swapoff, reset, hot_remove, owner record removed. Idempotent.
  [[nodiscard]] Status Remove();

 private:
  friend DeviceSwap OpenDeviceSwap(const SwapOptions& options);

  SwapKind kind_ = SwapKind::kNone;
  std::uint64_t bytes_ = 0;
  std::string reason_;
  std::string device_path_;
  std::string comp_algorithm_;
  int zram_id_ = -1;
  bool swapped_on_ = false;
  int mm_stat_fd_ = -1;
  SwapSystem system_;
};

// Never fails: what cannot be had is kind none with the reason (and nothing left behind).
[[nodiscard]] DeviceSwap OpenDeviceSwap(const SwapOptions& options);

// Removes the zram devices whose owner record names a process that is gone; returns how many.
// Errors name the device and the step (swapoff, reset, hot_remove) that failed.
[[nodiscard]] Result<std::uint32_t> RemoveStaleZramDevices(const SwapSystem& system);

// The active swaps of /proc/swaps' text: their device paths and total bytes.
struct ActiveSwaps {
  std::uint32_t count = 0;
  std::uint64_t total_bytes = 0;
  std::string first;  // the first one's path
};
[[nodiscard]] ActiveSwaps ParseProcSwaps(std::string_view text);
[[nodiscard]] bool ProcSwapsContains(std::string_view text, std::string_view path);

// The swap header (version 1, "SWAPSPACE2") for a device of `bytes` with `page_bytes` pages:
// the first page, as mkswap writes it (no bad blocks, a random UUID). Exposed for tests.
[[nodiscard]] Result<std::string> SwapHeaderPage(std::uint64_t bytes, std::uint32_t page_bytes);

}  // namespace zm
