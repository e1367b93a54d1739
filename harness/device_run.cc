#include "harness/device_run.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <vector>

#include "geometry/metrics.h"
#include "geometry/trajectory.h"
#include "harness/cotenant.h"
#include "harness/cotenant_supervisor.h"
#include "harness/device_scale.h"
#include "harness/process_sample.h"
#include "runtime/memory_cap.h"
#include "runtime/streaming_stats.h"
#include "runtime/summary.h"
#include "sim/scenario.h"

namespace zm {
namespace {

// What the runner publishes to the map process (a shared page: written by the runner's monitor,
// read by the map process at each tick, no allocation, no lock).
struct SharedReadings {
  std::atomic<std::uint64_t> cotenant_rss_bytes{0};
  std::atomic<std::int64_t> cotenant_pid{-1};
  std::atomic<std::uint64_t> device_limit_bytes{0};   // in force now (charge_zram lowers it)
  std::atomic<std::uint64_t> zram_mem_used_bytes{0};  // DRAM zram's compressed pages occupy
};

// The charged limit moves in steps of this much, so a few pages in or out of zram do not rewrite
// the cgroup's limit at every sample.
constexpr std::uint64_t kZramChargeStepBytes = 1ull << 20;

// The device cgroup's swappiness: JetPack's. L4T (Ubuntu) sets no vm.swappiness of its own and
// nvzramconfig only makes the zram devices, so it is the kernel default, 60 (check on a Jetson:
// cat /proc/sys/vm/swappiness).
constexpr int kJetPackSwappiness = 60;

double NowS() { return MonotonicSeconds(); }

// fsync + POSIX_FADV_DONTNEED on every regular file of `dir` (not recursive: a scenario's files
// are at its top): their clean pages leave the page cache, so the map process's reads are
// charged to the device it runs in. Returns the bytes of the files dropped.
std::uint64_t DropFileCache(const std::string& dir) {
  namespace fs = std::filesystem;
  std::uint64_t bytes = 0;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file(ec)) continue;
    const int fd = open(e.path().c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) continue;
    (void)fsync(fd);  // dirty pages cannot be dropped
    if (posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED) == 0) bytes += e.file_size(ec);
    close(fd);
  }
  return bytes;
}

void SleepS(double s) {
  timespec ts{static_cast<time_t>(s), static_cast<long>((s - std::floor(s)) * 1e9)};
  (void)nanosleep(&ts, nullptr);
}

bool WriteAll(int fd, const void* p, std::size_t n) {
  const char* c = static_cast<const char*>(p);
  while (n > 0) {
    const ssize_t w = write(fd, c, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    c += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

bool ReadAll(int fd, void* p, std::size_t n) {
  char* c = static_cast<char*>(p);
  while (n > 0) {
    const ssize_t r = read(fd, c, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    c += r;
    n -= static_cast<std::size_t>(r);
  }
  return true;
}

// "\rrun: frame 812 of 4128 (20 %), 2.0 frames/s, ETA 27:38" on stderr, in place. A stack buffer
// and one write(2): a warm tick allocates nothing.
void WriteProgress(const TickClock& clock, std::uint64_t frames_total) {
  const double rate = clock.wall_s > 0 ? static_cast<double>(clock.frames_arrived) / clock.wall_s
                                       : 0.0;
  const std::uint64_t left =
      frames_total > clock.frames_arrived ? frames_total - clock.frames_arrived : 0;
  const auto eta_s = static_cast<std::uint64_t>(rate > 0 ? static_cast<double>(left) / rate : 0.0);
  std::array<char, 160> line{};
  const int n = std::snprintf(
      line.data(), line.size(), "\rrun: frame %llu of %llu (%.0f %%), %.1f frames/s, ETA %llu:%02llu ",
      static_cast<unsigned long long>(clock.frames_arrived),
      static_cast<unsigned long long>(frames_total),
      frames_total > 0 ? 100.0 * static_cast<double>(clock.frames_arrived) /
                             static_cast<double>(frames_total)
                       : 0.0,
      rate, static_cast<unsigned long long>(eta_s / 60), static_cast<unsigned long long>(eta_s % 60));
  if (n > 0) (void)WriteAll(STDERR_FILENO, line.data(), std::min<std::size_t>(static_cast<std::size_t>(n), line.size() - 1));
}

// The map process: the replay inside the device. Never returns (it _exits: the runner's objects,
// the device among them, are the runner's to destroy).
[[noreturn]] void MapProcess(const DeviceRunRequest& request, const LoopConfig& loop,
                             std::uint64_t frames_total, DeviceModel& device,
                             SharedReadings* shared, int ready_fd, int go_fd,
                             const std::atomic<bool>* stop) {
  const std::string err_path = request.out_dir + "/map_error.txt";
  const auto fail = [&](const Status& s) {
    std::ofstream(err_path) << s.ToString() << '\n';
    std::fprintf(stderr, "map process: %s\n", s.ToString().c_str());
    _exit(2);
  };
  if (loop.map.process_cap_bytes != 0) {
    if (auto cap = ApplyProcessCap(loop.map.process_cap_bytes); !cap.ok()) fail(cap.status());
  }
  if (request.map_child_hook) request.map_child_hook();

  // Ledger: the map process is a tenant; its grant follows its memory (below).
  std::optional<LedgerTenant> tenant;
  if (DeviceLedger* ledger = device.ledger(); ledger != nullptr) {
    auto t = ledger->Register("map", loop.map.overhead_bytes);
    if (!t.ok()) fail(t.status());
    tenant.emplace(std::move(t).value());
  }
  ProcessSampler self;
  if (auto s = ProcessSampler::Open(getpid()); s.ok()) self = std::move(s).value();
  std::uint64_t ledger_refusals = 0;

  RunRequest run;
  run.scenario_dir = request.scenario_dir;
  run.out_dir = request.out_dir;
  run.loop = loop;
  // Every tick reaches the disk: a process the kernel kills leaves every tick it made.
  run.telemetry.flush_ticks = 1;
  run.verify_checksums = request.verify_checksums;
  run.profile_name = request.profile.core.source;
  run.input = request.profile.core.input;  // the input gate, as zonemapd applies it
  run.time_compression = request.time_compression;
  run.on_ready = [&](const TickLoop& l) -> Result<double> {
    // What a summary needs if this process does not live to write one (the budget, the arena).
    std::ofstream(request.out_dir + "/map_start.json") << ToJson(LoopSummary(l, false)).dump(2)
                                                       << '\n';
    // Ready: the loop is built (the arena reserved and pre-faulted). The runner starts the
    // co-tenant, then sends the clock's origin.
    const char byte = 1;
    if (!WriteAll(ready_fd, &byte, 1)) return IoError("map process: the runner is gone");
    double origin = 0.0;
    if (!ReadAll(go_fd, &origin, sizeof origin))
      return IoError("map process: no start from the runner");
    close(ready_fd);
    close(go_fd);
    return origin;
  };
  // The ledger's grant of the map process, and what a refusal does: the arena's free slots are
  // withheld (TickLoop::WithholdSlots) so no keyframe loads until a later grant succeeds.
  std::uint64_t last_majflt = SampleRusage().self_major_faults;
  double next_progress_s = 0.0;
  run.on_tick = [&, extra = std::array<char, 768>{}](
                    TickLoop& l, const TickClock& clock) mutable -> std::string_view {
    if (request.progress && clock.wall_s >= next_progress_s) {
      next_progress_s = clock.wall_s + 1.0;
      WriteProgress(clock, frames_total);
    }
    if (tenant) {
      const Arena& arena = l.arena();
      const std::uint64_t slots = l.bounded() ? arena.capacity() : arena.in_use();
      const std::uint64_t want = l.config().map.overhead_bytes + slots * l.slot_bytes();
      if (want == tenant->bytes() || tenant->TryUpdate(want)) {
        (void)l.WithholdSlots(0);
      } else {
        ++ledger_refusals;
        (void)l.WithholdSlots(arena.capacity());  // every free slot
      }
    }
    if (request.map_tick_hook) request.map_tick_hook(l);
    const DeviceSample d = device.Sample();
    const ProcessSample me = self.Sample();
    const RusageSample ru = SampleRusage();
    // map_majflt is cumulative (getrusage); map_majflt_tick is this tick's share of it.
    const std::uint64_t majflt_tick =
        ru.self_major_faults - std::min(ru.self_major_faults, last_majflt);
    last_majflt = ru.self_major_faults;
    const int n = std::snprintf(
        extra.data(), extra.size(),
        "\"wall_s\":%.4f,\"device_usage_bytes\":%llu,\"device_swap_bytes\":%llu,"
        "\"map_rss_bytes\":%llu,\"map_swap_bytes\":%llu,\"cotenant_rss_bytes\":%llu,"
        "\"map_majflt\":%llu,\"map_majflt_tick\":%llu,\"map_minflt\":%llu,\"oom_kills\":%llu,"
        "\"frames_dropped\":%llu,\"frames_arrived\":%llu,\"ledger_refusals\":%llu,"
        "\"device_limit_bytes\":%llu,\"zram_mem_used_bytes\":%llu",
        clock.wall_s, static_cast<unsigned long long>(d.usage_bytes),
        static_cast<unsigned long long>(d.swap_bytes),
        static_cast<unsigned long long>(me.rss_bytes),
        static_cast<unsigned long long>(me.swap_bytes),
        static_cast<unsigned long long>(shared->cotenant_rss_bytes.load()),
        static_cast<unsigned long long>(ru.self_major_faults),
        static_cast<unsigned long long>(majflt_tick),
        static_cast<unsigned long long>(ru.self_minor_faults),
        static_cast<unsigned long long>(d.oom_kills),
        static_cast<unsigned long long>(clock.frames_dropped),
        static_cast<unsigned long long>(clock.frames_arrived),
        static_cast<unsigned long long>(ledger_refusals),
        static_cast<unsigned long long>(shared->device_limit_bytes.load()),
        static_cast<unsigned long long>(shared->zram_mem_used_bytes.load()));
    return n > 0 && static_cast<std::size_t>(n) < extra.size()
               ? std::string_view(extra.data(), static_cast<std::size_t>(n))
               : std::string_view();
  };
  auto summary = RunScenario(run, stop);
  if (request.progress) std::fputs("\n", stderr);  // past the progress line
  if (!summary.ok()) fail(summary.status());
  RunSummary s = std::move(summary).value();
  s.ledger_refusals = ledger_refusals;
  std::ofstream(request.out_dir + "/map_summary.json") << ToJson(s).dump(2) << '\n';
  std::fflush(nullptr);
  _exit(0);
}

}  // namespace

namespace {

// The device's peaks and the map process's end, as the runner's monitor saw them.
struct DeviceWatch {
  std::uint64_t peak = 0;
  std::uint64_t swap_peak = 0;
  std::uint64_t zram_mem_used_peak = 0, zram_orig_peak = 0, zram_compr_peak = 0;
  std::uint64_t dram_peak = 0;  // usage + zram's compressed pages: the DRAM the device holds
  std::uint64_t limit_min = 0;
  std::uint64_t charge_refusals = 0;
  std::uint64_t map_peak_rss = 0;
  std::uint64_t cotenant_peak_rss = 0;
  int wait_status = 0;
  rusage map_usage{};
  DeviceSample final_sample;

  void SampleSwap(DeviceModel& device, const DeviceSample& d) {
    if (d.ok) swap_peak = std::max(swap_peak, d.swap_bytes);
    const ZramSample z = device.SampleZram();
    if (z.ok) {
      zram_mem_used_peak = std::max(zram_mem_used_peak, z.mem_used_bytes);
      zram_orig_peak = std::max(zram_orig_peak, z.orig_data_bytes);
      zram_compr_peak = std::max(zram_compr_peak, z.compr_data_bytes);
    }
  }
};

// zram's compressed pages charged to the device (DeviceRunRequest::charge_zram): the cgroup's
// limit follows the DRAM they occupy. One sample's step.
void ChargeZram(DeviceModel& device, Cgroup& cgroup, const DeviceSample& last,
                SharedReadings* shared, DeviceWatch& w) {
  const ZramSample z = device.SampleZram();
  if (!z.ok) return;
  shared->zram_mem_used_bytes.store(z.mem_used_bytes);
  if (last.ok) w.dram_peak = std::max(w.dram_peak, last.usage_bytes + z.mem_used_bytes);
  // Floor: a quarter of the device; zram holds at most swap_bytes (half the memory) of swapped
  // pages, so only a broken mm_stat could ask for less.
  const std::uint64_t target = ChargedLimit(cgroup.limit_bytes(), z.mem_used_bytes,
                                            kZramChargeStepBytes, cgroup.limit_bytes() / 4);
  if (target == cgroup.current_limit_bytes()) return;
  if (Status s = cgroup.SetMemoryLimit(target); !s.ok()) {
    // The kernel could not reclaim down to it (v1 EBUSY): the device is over its DRAM for now;
    // the next sample tries again. Said once, counted always.
    if (w.charge_refusals++ == 0) std::fprintf(stderr, "device: %s\n", s.ToString().c_str());
  }
  w.limit_min = std::min(w.limit_min, cgroup.current_limit_bytes());
  shared->device_limit_bytes.store(cgroup.current_limit_bytes());
}

// Monitors until the map process ends (every 50 ms): the device's peak and OOM kills, zram's
// store (charged to the limit when `charge_cgroup`), the map process's and the co-tenant's RSS
// (published to the map process through `shared`).
Result<DeviceWatch> WatchUntilMapExits(DeviceModel& device, pid_t map_pid, SharedReadings* shared,
                                       Cgroup* charge_cgroup, CotenantSupervisor* cotenant,
                                       const std::atomic<bool>* stop) {
  DeviceWatch w;
  w.limit_min = device.limit_bytes();
  DeviceSample last = device.Sample();
  w.peak = last.peak_bytes;
  ProcessSampler map_sampler;
  if (auto s = ProcessSampler::Open(map_pid); s.ok()) map_sampler = std::move(s).value();
  ProcessSampler co_sampler;
  pid_t co_pid = -1;
  bool sent_term = false;
  for (;;) {
    // wait4: the map process's own rusage (its major faults) when it is reaped.
    const pid_t r = wait4(map_pid, &w.wait_status, WNOHANG, &w.map_usage);
    if (r == map_pid) break;
    if (r < 0 && errno != EINTR) return Internal(std::string("waitpid: ") + std::strerror(errno));
    if (stop != nullptr && stop->load() && !sent_term) {
      kill(map_pid, SIGTERM);
      sent_term = true;
    }
    last = device.Sample();
    if (last.ok) w.peak = std::max({w.peak, last.peak_bytes, last.usage_bytes});
    w.SampleSwap(device, last);
    if (charge_cgroup != nullptr) ChargeZram(device, *charge_cgroup, last, shared, w);
    const ProcessSample m = map_sampler.Sample();
    if (m.alive) w.map_peak_rss = std::max(w.map_peak_rss, m.rss_bytes);
    if (cotenant != nullptr) {
      const pid_t p = cotenant->child_pid();
      if (p != co_pid) {
        co_pid = p;
        co_sampler = ProcessSampler();
        if (p > 0) {
          if (auto s = ProcessSampler::Open(p); s.ok()) co_sampler = std::move(s).value();
        }
        shared->cotenant_pid.store(p);
      }
      const ProcessSample c = co_sampler.Sample();
      const std::uint64_t rss = c.alive ? c.rss_bytes : 0;
      shared->cotenant_rss_bytes.store(rss);
      w.cotenant_peak_rss = std::max(w.cotenant_peak_rss, rss);
    }
    SleepS(0.05);
  }
  return w;
}

// Requests still in flight may finish (the same grace for every run), then the co-tenant stops;
// its report with the run's pacing (null without a co-tenant).
nlohmann::json FinishCotenant(const DeviceRunRequest& request, CotenantSupervisor& supervisor,
                              bool started, const Status& start_error, double period_s,
                              std::uint64_t peak_rss, const std::atomic<bool>* stop) {
  nlohmann::json cotenant = nullptr;
  if (started) {
    const double drain_until = NowS() + request.cotenant_drain_s;
    while (NowS() < drain_until && !(stop != nullptr && stop->load())) {
      const CotenantResult c = supervisor.Snapshot();
      if (c.requests + c.requests_failed >= request.cotenant_requests) break;
      SleepS(0.1);
    }
    auto r = supervisor.Stop();
    if (r.ok()) {
      const CotenantResult& c = r.value();
      cotenant = ToJson(c);
      cotenant["outcome"] = std::string(CotenantOutcomeName(c.outcome));
      cotenant["symbol"] = std::string(CotenantOutcomeSymbol(c.outcome));
      cotenant["requests_completed"] = c.requests;
      cotenant["restarts"] = c.restarts;
      cotenant["peak_rss_bytes"] = peak_rss;
      std::ofstream(request.out_dir + "/cotenant.json") << ToJson(c).dump(2) << '\n';
    } else {
      cotenant = {{"outcome", "failed_to_start"}, {"reason", r.status().message()}};
    }
  } else if (request.with_cotenant) {
    cotenant = {{"outcome", "failed_to_start"},
                {"requests_completed", 0},
                {"restarts", 0},
                {"reason", !start_error.ok() ? start_error.message()
                                             : std::string("the map process never became ready")},
                {"note", std::string(kCotenantNote)}};
  }
  if (!cotenant.is_null()) {
    cotenant["events_file"] = "cotenant.jsonl";
    cotenant["request_period_s"] = period_s;
    cotenant["requests_planned"] = request.cotenant_requests;
    cotenant["stand_in"] = true;
  }
  return cotenant;
}

// The map process's own summary (map_summary.json, when it exited cleanly), or the one rebuilt
// from its ticks; and how it ended.
Result<RunSummary> MapSummaryOrPartial(const DeviceRunRequest& request, const ChildExit& exit,
                                       std::string& outcome) {
  const std::string path = request.out_dir + "/map_summary.json";
  if (exit.exited && exit.code == 0) {
    if (std::ifstream in(path); in) {
      const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
      if (auto s = RunSummaryFromJson(j); !j.is_discarded() && s.ok()) {
        outcome = s->interrupted ? "interrupted" : "completed";
        return std::move(s).value();
      }
    }
  }
  outcome = exit.signaled && exit.signal == SIGKILL ? "killed"
            : exit.signaled                         ? "crashed"
                                                    : "failed";
  return SummarizePartialRun(request.scenario_dir, request.out_dir, request.time_compression);
}

// A map generated at a larger footprint than the device's scale (a full-size map at --device-scale
// 1/8): the arena the map process would reserve for it can exceed its process cap (RLIMIT_AS),
// and the kernel's "arena reservation exceeds RLIMIT_AS" would not say why. Said here, with the
// numbers and the fix, before anything runs. `loop` is already scaled.
Status CheckFootprintScale(const sim::ScenarioInfo& scenario, double device_scale,
                           const LoopConfig& loop) {
  if (loop.map.process_cap_bytes == 0 || scenario.footprint_scale <= device_scale) {
    return Status::Ok();
  }
  auto budget = DeriveBudget(BudgetInputsFor(loop.device, loop.model, loop.map,
                                             loop.policy.kind, scenario.resident_bytes_max,
                                             scenario.keyframes));
  if (!budget.ok()) return Status::Ok();  // the map process says what is wrong with the budget
  const std::uint64_t arena_bytes = std::uint64_t{budget->arena_slots} * budget->slot_bytes;
  if (arena_bytes <= loop.map.process_cap_bytes) return Status::Ok();
  char scale[32];
  std::snprintf(scale, sizeof scale, "%g", device_scale);
  char made[32];
  std::snprintf(made, sizeof made, "%g", scenario.footprint_scale);
  return FailedPrecondition(
      "the map '" + scenario.dir + "' was generated at footprint scale " + made +
      " (largest keyframe " + FormatBytes(scenario.resident_bytes_max) + ") but the device runs at " +
      "--device-scale " + scale + ": " + std::string(PolicyName(loop.policy.kind)) + "'s arena of " +
      std::to_string(budget->arena_slots) + " slots x " + FormatBytes(budget->slot_bytes) + " = " +
      FormatBytes(arena_bytes) + " exceeds the map process's cap map.process_cap_bytes " +
      FormatBytes(loop.map.process_cap_bytes) + "; generate the map with `zonemap sim ... " +
      "--footprint-scale " + scale + "` (or run it at --device-scale " + made + ")");
}

// The device's options for a run of `loop` (already scaled): cgroup or ledger, its limit, its
// swap at JetPack's swappiness.
Result<DeviceModelOptions> DeviceOptionsFor(const DeviceRunRequest& request,
                                            const LoopConfig& loop) {
  ZM_ASSIGN_OR_RETURN(std::uint64_t limit, DeviceLimitBytes(loop.device));
  DeviceModelOptions dopt;
  dopt.kind = request.device;
  dopt.fall_back_to_ledger = !request.device_explicit;
  dopt.limit_bytes = limit;
  dopt.cgroup = request.cgroup;
  dopt.swap.requested = loop.device.swap;
  dopt.swap.bytes = loop.device.swap_bytes;  // scaled with the device
  dopt.swap.system = request.swap_system;
  if (loop.device.swap != "none" && dopt.cgroup.swappiness < 0) {
    dopt.cgroup.swappiness = kJetPackSwappiness;
  }
  dopt.ledger_path = !request.ledger_path.empty()
                         ? request.ledger_path
                         : request.out_dir + "/.ledger-" + std::to_string(getpid());
  return dopt;
}

}  // namespace

nlohmann::json ToJson(const DeviceRunSummary& d) {
  nlohmann::json s = ToJson(d.run);
  const MapProcessSummary& m = d.map;
  s["map"] = {{"outcome", m.outcome},
              {"pid", m.pid},
              {"exit_code", m.exit_code},
              {"signal", m.signal},
              {"peak_rss_bytes", m.peak_rss_bytes},
              {"major_faults", m.major_faults},
              {"arena_locked", m.arena_locked},
              {"lock_arena_requested", m.lock_arena_requested},
              {"cold_files", m.cold_files},
              {"files_dropped_bytes", m.files_dropped_bytes}};
  if (m.error) s["map"]["error"] = *m.error;
  s["device_scale"] = d.device_scale;
  const DeviceSummary& v = d.device;
  const DeviceSwapSummary& w = v.swap;
  s["device"] = {{"kind", v.kind},
                 {"simulated", v.simulated},
                 {"description", v.description},
                 {"fallback_reason", v.fallback_reason},
                 {"limit_bytes", v.limit_bytes},
                 {"peak_bytes", v.peak_bytes},
                 {"oom_kills", v.oom_kills},
                 {"limit_hits", v.limit_hits},
                 {"scale", v.scale},
                 {"name", v.name},
                 {"memory_bytes", v.memory_bytes},
                 {"os_reserve_bytes", v.os_reserve_bytes},
                 {"map_peak_rss_bytes", v.map_peak_rss_bytes},
                 {"cotenant_peak_rss_bytes", v.cotenant_peak_rss_bytes},
                 {"swap",
                  {{"kind", w.kind},
                   {"requested", w.requested},
                   {"reason", w.reason},
                   {"description", w.description},
                   {"limit_bytes", w.limit_bytes},
                   {"peak_bytes", w.peak_bytes},
                   {"swappiness", w.swappiness},
                   {"comp_algorithm", w.comp_algorithm},
                   {"zram_orig_peak_bytes", w.zram_orig_peak_bytes},
                   {"zram_compr_peak_bytes", w.zram_compr_peak_bytes},
                   {"zram_mem_used_peak_bytes", w.zram_mem_used_peak_bytes},
                   {"zram_charged", w.zram_charged}}},
                 {"limit_min_bytes", v.limit_min_bytes},
                 {"dram_peak_bytes", v.dram_peak_bytes},
                 {"limit_charge_refusals", v.limit_charge_refusals}};
  s["oom_events"] = v.oom_kills;  // the memory table's column (simulated for the ledger)
  if (!d.cotenant.is_null()) s["cotenant"] = d.cotenant;
  return s;
}

Result<DeviceRunSummary> RunOnDevice(const DeviceRunRequest& request,
                                     const std::atomic<bool>* stop) {
  namespace fs = std::filesystem;
  ZM_RETURN_IF_ERROR(ValidateDeviceScale(request.device_scale));
  if (!(request.time_compression >= 0.0)) {
    return InvalidArgument("--time-compression must be >= 0 (0 = no real-time frames)");
  }
  std::error_code ec;
  fs::create_directories(request.out_dir, ec);
  if (ec) return IoError("cannot create run directory '" + request.out_dir + "': " + ec.message());
  for (const char* f : {"summary.json", "map_summary.json", "map_start.json", "map_error.txt",
                        "ticks.jsonl", "estimate.tum", "cotenant.jsonl", "cotenant.json"}) {
    fs::remove(request.out_dir + "/" + f, ec);
  }
  ZM_ASSIGN_OR_RETURN(sim::ScenarioInfo scenario, sim::LoadScenario(request.scenario_dir));

  // The device at scale S: memory, OS reserve, model and the map's bytes together.
  LoopConfig loop = request.profile.core;
  ZM_RETURN_IF_ERROR(ApplyDeviceScale(request.device_scale, loop.device, loop.model, loop.map));
  ZM_RETURN_IF_ERROR(CheckFootprintScale(scenario, request.device_scale, loop));
  ZM_ASSIGN_OR_RETURN(DeviceModelOptions dopt, DeviceOptionsFor(request, loop));
  // The map's files: every read of the run lands in the device (cold), or not (warm).
  const std::uint64_t dropped_file_bytes =
      request.cold_files ? DropFileCache(request.scenario_dir) : 0;
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<DeviceModel> device, OpenDeviceModel(dopt));
  if (request.on_device) request.on_device(*device);
  const Cgroup* device_cgroup = device->cgroup();
  const std::string swap_kind(device_cgroup != nullptr ? SwapKindName(device->swap().kind())
                                                       : "none");
  const std::string swap_reason = device_cgroup != nullptr
                                      ? device->swap().reason()
                                      : std::string("the ledger simulates no swap");
  if (loop.device.swap != "none" && swap_kind == "none") {
    // Never silent: the device asked for swap and has none.
    std::fprintf(stderr, "device swap: none: %s\n", swap_reason.c_str());
  }

  auto* shared = static_cast<SharedReadings*>(mmap(
      nullptr, sizeof(SharedReadings), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0));
  if (shared == MAP_FAILED) return IoError(std::string("mmap: ") + std::strerror(errno));
  new (shared) SharedReadings();
  shared->device_limit_bytes.store(device->limit_bytes());
  // zram's compressed pages charged to the device (DeviceRunRequest::charge_zram): only for a
  // zram made for the run; an existing swap (a real Jetson's) is already in the device's DRAM.
  Cgroup* const charge_cgroup =
      request.charge_zram && device->swap().kind() == SwapKind::kZram ? device->cgroup() : nullptr;
  struct Unmap {
    SharedReadings* p;
    ~Unmap() { munmap(p, sizeof(SharedReadings)); }
  } unmap{shared};

  int ready[2], go[2];
  if (pipe2(ready, O_CLOEXEC) != 0) return IoError(std::string("pipe: ") + std::strerror(errno));
  if (pipe2(go, O_CLOEXEC) != 0) {
    close(ready[0]);
    close(ready[1]);
    return IoError(std::string("pipe: ") + std::strerror(errno));
  }
  std::fflush(nullptr);  // nothing buffered is written twice by the child
  // Forked before any thread exists (the co-tenant supervisor's comes later): the child is a
  // plain copy of this process, inside the device before it returns.
  auto forked = ForkInDevice(*device);
  if (!forked.ok()) {
    for (int fd : {ready[0], ready[1], go[0], go[1]}) close(fd);
    return forked.status();
  }
  const pid_t map_pid = *forked;
  if (map_pid == 0) {
    close(ready[0]);
    close(go[1]);
    const std::uint64_t frames_total =
        loop.loop.max_ticks != 0 ? std::min<std::uint64_t>(loop.loop.max_ticks, scenario.frames)
                                 : scenario.frames;
    MapProcess(request, loop, frames_total, *device, shared, ready[1], go[0], stop);
  }
  close(ready[1]);
  close(go[0]);

  // Wait until the map process is ready (its loop built) or gone.
  bool map_ready = false;
  for (;;) {
    pollfd p{ready[0], POLLIN, 0};
    const int r = poll(&p, 1, 200);
    if (r > 0) {
      char b = 0;
      map_ready = read(ready[0], &b, 1) == 1;
      break;
    }
    if (r < 0 && errno != EINTR) break;
    if (stop != nullptr && stop->load()) kill(map_pid, SIGTERM);
  }
  close(ready[0]);

  // The co-tenant, inside the device, on the request schedule every policy gets.
  const double duration_s =
      scenario.rate_hz > 0 ? static_cast<double>(scenario.frames) / scenario.rate_hz : 0.0;
  double period_s = request.cotenant_period_s;
  if (period_s <= 0) {
    period_s = request.time_compression > 0 && request.cotenant_requests > 0
                   ? duration_s / (request.cotenant_requests * request.time_compression)
                   : 1.0;
  }
  CotenantSupervisor supervisor;
  bool cotenant_started = false;
  Status cotenant_error;
  if (request.with_cotenant && map_ready) {
    CotenantSupervisorOptions so;
    so.config = CotenantConfigFromProfile(request.profile);  // full size; scaled below
    so.config.device_scale = request.device_scale;
    if (device->ledger() != nullptr) so.config.ledger_path = dopt.ledger_path;
    so.executable = request.cotenant_executable;
    if (device->cgroup() != nullptr) so.device = device.get();
    so.restart_delay_s = request.profile.cotenant.restart_delay_s;
    so.request_period_s = period_s;
    so.max_requests = request.cotenant_requests;
    so.events_path = request.out_dir + "/cotenant.jsonl";
    cotenant_error = supervisor.Start(std::move(so));
    cotenant_started = cotenant_error.ok();
  }
  // The run's clock: the co-tenant supervisor's origin (its request times are relative to it).
  const double origin = cotenant_started ? supervisor.Snapshot().origin_mono_s : NowS();
  if (map_ready && !WriteAll(go[1], &origin, sizeof origin)) map_ready = false;
  close(go[1]);

  ZM_ASSIGN_OR_RETURN(DeviceWatch watch,
                      WatchUntilMapExits(*device, map_pid, shared, charge_cgroup,
                                         cotenant_started ? &supervisor : nullptr, stop));
  const ChildExit exit = DescribeWaitStatus(watch.wait_status);
  DeviceRunSummary out;
  out.cotenant = FinishCotenant(request, supervisor, cotenant_started, cotenant_error, period_s,
                                watch.cotenant_peak_rss, stop);
  const DeviceSample final_sample = device->Sample();
  if (final_sample.ok) watch.peak = std::max(watch.peak, final_sample.peak_bytes);
  watch.SampleSwap(*device, final_sample);

  // The map process's summary, or what its ticks say.
  std::string map_error;
  if (std::ifstream e(request.out_dir + "/map_error.txt"); e) std::getline(e, map_error);
  MapProcessSummary& m = out.map;
  ZM_ASSIGN_OR_RETURN(out.run, MapSummaryOrPartial(request, exit, m.outcome));
  if (!out.run.replay) out.run.replay.emplace();
  out.run.replay->time_compression = request.time_compression;
  m.pid = map_pid;
  m.exit_code = exit.exited ? exit.code : -1;
  m.signal = exit.signaled ? exit.signal : 0;
  m.peak_rss_bytes = watch.map_peak_rss;
  m.major_faults = static_cast<std::uint64_t>(watch.map_usage.ru_majflt);
  m.arena_locked = out.run.arena_locked;
  m.lock_arena_requested = loop.map.lock_arena;
  m.cold_files = request.cold_files;
  m.files_dropped_bytes = dropped_file_bytes;
  if (!map_error.empty()) m.error = map_error;
  out.device_scale = request.device_scale;
  DeviceSummary& v = out.device;
  v.kind = std::string(DeviceKindName(device->kind()));
  v.simulated = device->simulated();
  v.description = device->Describe();
  v.fallback_reason = device->fallback_reason();
  v.limit_bytes = device->limit_bytes();
  v.peak_bytes = watch.peak;
  v.oom_kills = final_sample.oom_kills;
  v.limit_hits = final_sample.limit_hits;
  v.scale = request.device_scale;
  v.name = loop.device.name;
  v.memory_bytes = loop.device.memory_bytes;
  v.os_reserve_bytes = loop.device.os_reserve_bytes;
  v.map_peak_rss_bytes = watch.map_peak_rss;
  v.cotenant_peak_rss_bytes = watch.cotenant_peak_rss;
  v.swap = {.kind = swap_kind,
            .requested = loop.device.swap,
            .reason = swap_reason,
            .description = device->swap().Describe(),
            .limit_bytes = device_cgroup != nullptr ? device_cgroup->swap_limit_bytes() : 0,
            .peak_bytes = watch.swap_peak,
            .swappiness = dopt.cgroup.swappiness,
            .comp_algorithm = device->swap().comp_algorithm(),
            .zram_orig_peak_bytes = watch.zram_orig_peak,
            .zram_compr_peak_bytes = watch.zram_compr_peak,
            .zram_mem_used_peak_bytes = watch.zram_mem_used_peak,
            .zram_charged = charge_cgroup != nullptr};
  v.limit_min_bytes = watch.limit_min;
  v.dram_peak_bytes = charge_cgroup != nullptr ? watch.dram_peak : watch.peak;
  v.limit_charge_refusals = watch.charge_refusals;
  ZM_RETURN_IF_ERROR(WriteSummaryFile(request.out_dir + "/summary.json", ToJson(out)));
  if (Status r = device->Remove(); !r.ok()) {
    std::fprintf(stderr, "device: %s\n", r.ToString().c_str());
  }
  if (m.outcome == "failed" && !map_error.empty() && out.run.ticks == 0) {
    return Internal("map process: " + map_error);
  }
  return out;
}

}  // namespace zm
