// The experiment's run (issue 17 §1, §4): a replay on a device, beside the co-tenant.
//
//   runner (this process, outside the device: samples, supervises, writes summary.json)
//     ├─ map process: a forked child inside the device, running the tick loop over the
//     │  scenario's frames (real-time frames with --time-compression); writes ticks.jsonl
//     │  (with the device readings of each tick) and estimate.tum, streamed
//     └─ co-tenant: zonemap-cotenant under CotenantSupervisor, entered into the device between
//        fork and exec, restarted after a kill; its event lines go to cotenant.jsonl
//
// Device: a memory cgroup limited to the profile's device memory less its OS reserve (scaled by
// --device-scale), where out of memory is the kernel's (OOM kills, SIGKILL); or, where no cgroup
// can be made (or --device ledger), the device ledger, whose refusals stand in for out of memory
// and whose every report says "simulated". In the ledger a refused map grant means the keyframes
// it would have held are not loaded; a refused co-tenant grant fails that request.
//
// Order: the map process builds its loop first (the bounded policies' arena reserved and
// pre-faulted: their budget is resident before the co-tenant starts), then the co-tenant starts,
// and the first frame arrives at the co-tenant supervisor's origin: the one clock (CLOCK_MONOTONIC
// seconds since it) of ticks.jsonl's wall_s and the co-tenant's per-request times.
//
// Swap: the profile's device.swap (JetPack: zram of half the memory, scaled) is made for the run
// and removed after it (harness/swap_device.h); the device cgroup may swap that much, at JetPack's
// swappiness. Where it cannot be had the run says why in one line and summary.json's
// device.swap.kind is "none".
//
// Whichever process inside is killed, the runner writes summary.json: map.outcome says whether
// the map process completed or was killed, with the metrics over the ticks it managed.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <nlohmann/json.hpp>
#include <string>

#include "common/status.h"
#include "harness/cgroup.h"
#include "harness/device_model.h"
#include "harness/experiment_profile.h"
#include "harness/run.h"
#include "runtime/summary.h"

namespace zm {

struct DeviceRunRequest {
  std::string scenario_dir;
  std::string out_dir;
  ExperimentProfile profile;  // at full size: the run applies device_scale
  // --device: cgroup (falls back to the ledger unless device_explicit) or ledger.
  DeviceKind device = DeviceKind::kCgroup;
  bool device_explicit = false;
  double device_scale = 1.0;  // --device-scale S, 0 < S <= 1
  bool with_cotenant = false;
  // --time-compression X (> 0: real-time frames at the profile's rate, X frames-clock seconds
  // per wall second; 0: every frame as fast as the loop goes). The same for every compared run.
  double time_compression = 0.0;
  // Co-tenant requests, paced identically for every policy: `cotenant_requests` of them spread
  // over the patrol (one every duration / N of the frames' clock, i.e. duration / (N X) wall s);
  // cotenant_period_s > 0 sets the wall period instead (unpaced replays: 1 s by default).
  std::uint32_t cotenant_requests = 30;
  double cotenant_period_s = 0.0;
  // After the map process ends, how long (wall s) requests still in flight may finish.
  double cotenant_drain_s = 30.0;
  bool verify_checksums = false;
  // Before the run, fsync and drop (POSIX_FADV_DONTNEED) the page cache of every file of the
  // scenario directory (map.db, frames.bin, ...), so every read the map process makes is charged
  // to the device. false: a warm start (whatever is cached stays, charged where it was read).
  bool cold_files = true;
  // With a zram swap made for the run: the cgroup's memory limit follows the DRAM that zram's
  // compressed pages occupy (limit - mm_stat mem_used, sampled every 50 ms), because on the
  // Jetson they live in the same 8 GB while here they live on the host, outside the cgroup.
  // false: zram is free memory beside the device (more forgiving than the Jetson).
  bool charge_zram = true;
  // A progress line on stderr about once a second (frames, rate, ETA), rewritten in place:
  // `zonemap run` sets it when stderr is a terminal.
  bool progress = false;
  // Tests and tools: where the device is made.
  CgroupOptions cgroup;             // prefix, parent (limit_bytes is set from the profile)
  SwapSystem swap_system;           // where the device's zram is made (tests: a fake sysfs)
  std::string ledger_path;          // "" = RUNDIR/.ledger-<pid>
  std::string cotenant_executable;  // "" = FindCotenantExecutable()
  // Runs in the map process, inside the device, before its loop is built (tests: make it
  // allocate until the kernel kills it). Empty: none.
  std::function<void()> map_child_hook;
  // Runs in the map process after each tick (tests: a deliberately slow tick). Empty: none.
  std::function<void(const TickLoop&)> map_tick_hook;
  // Called once the device is open, before anything runs in it (tests: another ledger tenant).
  std::function<void(DeviceModel&)> on_device;
};

// summary.json of a device run: the map process's RunSummary (runtime/summary.h) with what the
// runner adds (docs/harness.md, "summary.json: the keys this adds"). Written once, by the runner.
struct MapProcessSummary {
  std::string outcome;  // completed | interrupted | killed | crashed | failed
  std::int64_t pid = -1;
  int exit_code = -1;
  int signal = 0;
  std::uint64_t peak_rss_bytes = 0;
  std::uint64_t major_faults = 0;
  bool arena_locked = false;
  bool lock_arena_requested = false;
  bool cold_files = true;
  std::uint64_t files_dropped_bytes = 0;
  std::optional<std::string> error;  // map_error.txt's line, when it wrote one
};

struct DeviceSwapSummary {
  std::string kind;  // zram | existing | none
  std::string requested;
  std::string reason;
  std::string description;
  std::uint64_t limit_bytes = 0;
  std::uint64_t peak_bytes = 0;
  int swappiness = -1;
  std::string comp_algorithm;
  std::uint64_t zram_orig_peak_bytes = 0;
  std::uint64_t zram_compr_peak_bytes = 0;
  std::uint64_t zram_mem_used_peak_bytes = 0;
  bool zram_charged = false;
};

struct DeviceSummary {
  std::string kind;  // cgroup | ledger
  bool simulated = false;
  std::string description;
  std::string fallback_reason;
  std::uint64_t limit_bytes = 0;
  std::uint64_t peak_bytes = 0;
  std::uint64_t oom_kills = 0;
  std::uint64_t limit_hits = 0;
  double scale = 1.0;
  std::string name;
  std::uint64_t memory_bytes = 0;
  std::uint64_t os_reserve_bytes = 0;
  std::uint64_t map_peak_rss_bytes = 0;
  std::uint64_t cotenant_peak_rss_bytes = 0;
  DeviceSwapSummary swap;
  std::uint64_t limit_min_bytes = 0;
  std::uint64_t dram_peak_bytes = 0;
  std::uint64_t limit_charge_refusals = 0;
};

struct DeviceRunSummary {
  RunSummary run;  // the map process's own summary, or the one rebuilt from its ticks
  MapProcessSummary map;
  DeviceSummary device;
  double device_scale = 1.0;
  // The co-tenant's report (harness/cotenant.h's ToJson(CotenantResult), its own codec) with the
  // run's pacing (requests_planned, request_period_s, ...); null without a co-tenant.
  nlohmann::json cotenant;
};
// summary.json: RunSummary's keys with `map`, `device`, `device_scale`, `oom_events`
// (= device.oom_kills, the memory table's column) and `cotenant`.
[[nodiscard]] nlohmann::json ToJson(const DeviceRunSummary& summary);

[[nodiscard]] Result<DeviceRunSummary> RunOnDevice(const DeviceRunRequest& request,
                                                   const std::atomic<bool>* stop = nullptr);

// The summary of a map process that did not finish (killed): the metrics over the ticks it
// managed, from RUNDIR/ticks.jsonl, RUNDIR/estimate.tum and RUNDIR/map_start.json (0 where
// nothing was measured; `partial` set). Exposed for tests.
[[nodiscard]] Result<RunSummary> SummarizePartialRun(const std::string& scenario_dir,
                                                     const std::string& out_dir,
                                                     double time_compression);

}  // namespace zm
