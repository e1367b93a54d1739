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

// The map process: the replay inside the device. Never returns (it _exits: the runner's objects,
// the device among them, are the runner's to destroy).
[[noreturn]] void MapProcess(const DeviceRunRequest& request, const LoopConfig& loop,
                             DeviceModel& device, SharedReadings* shared, int ready_fd, int go_fd,
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
    std::ofstream(request.out_dir + "/map_start.json") << LoopSummary(l, false).dump(2) << '\n';
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
  run.on_tick = [&, extra = std::array<char, 768>{}](
                    TickLoop& l, const TickClock& clock) mutable -> std::string_view {
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
  if (!summary.ok()) fail(summary.status());
  nlohmann::json s = std::move(summary).value();
  s["ledger_refusals"] = ledger_refusals;
  std::ofstream(request.out_dir + "/map_summary.json") << s.dump(2) << '\n';
  std::fflush(nullptr);
  _exit(0);
}

// Keys a complete run's summary has that a partial one must carry too (bench reads them).
void FillMissing(nlohmann::json& s) {
  const auto zero = [&s](const char* k) {
    if (!s.contains(k)) s[k] = 0;
  };
  for (const char* k : {"k_max",
                        "slot_bytes",
                        "arena_slots",
                        "ticks",
                        "loop_closures",
                        "closures_rejected",
                        "peak_resident_keyframes",
                        "peak_resident_bytes",
                        "over_budget_ticks",
                        "max_over_budget_keyframes",
                        "keyframes_loaded",
                        "keyframes_unloaded",
                        "zone_loads",
                        "db_transactions",
                        "db_queries",
                        "db_blob_reads",
                        "db_bytes_read",
                        "frames_dropped",
                        "frames_arrived",
                        "alloc_failures",
                        "stalled_ticks"}) {
    zero(k);
  }
  if (!s.contains("tick_ms")) {
    s["tick_ms"] = {{"mean", 0.0}, {"p50", 0.0}, {"p99", 0.0}, {"max", 0.0}, {"count", 0}};
  }
  if (!s.contains("startup")) s["startup"] = nlohmann::json::object();
  if (!s.contains("steady_state")) s["steady_state"] = nlohmann::json::object();
  if (!s.contains("loads")) s["loads"] = nlohmann::json::object();
  if (!s.contains("interrupted")) s["interrupted"] = false;
  for (const char* k :
       {"update_rate_hz", "ate_rmse_m", "ate_se3_rmse_m", "rpe_trans_rmse_m", "rpe_rot_rmse_deg"}) {
    if (!s.contains(k)) s[k] = nullptr;
  }
}

}  // namespace

Result<nlohmann::json> SummarizePartialRun(const std::string& scenario_dir,
                                           const std::string& out_dir, double time_compression) {
  nlohmann::json s = nlohmann::json::object();
  if (std::ifstream in(out_dir + "/map_start.json"); in) {
    try {
      s = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception&) {
      s = nlohmann::json::object();
    }
  }
  StreamingStats tick_ms;
  std::uint64_t ticks = 0, closures = 0, loaded = 0, unloaded = 0, over = 0, bytes_read = 0;
  std::uint64_t peak_kf = 0, peak_bytes = 0, dropped = 0, arrived = 0, tx = 0, q = 0;
  double wall_s = 0.0;
  double late_ms = 0.0, idle_load_ms = 0.0, startup_tick_ms = 0.0;
  bool has_startup = false;
  if (std::ifstream in(out_dir + "/ticks.jsonl"); in) {
    std::string line;
    while (std::getline(in, line)) {
      nlohmann::json t;
      try {
        t = nlohmann::json::parse(line);
      } catch (const nlohmann::json::exception&) {
        break;  // a line cut by the kill
      }
      ++ticks;
      if (t.value("startup", false)) {
        has_startup = true;
        startup_tick_ms = t.value("tick_ms", 0.0);
      } else {
        tick_ms.Add(t.value("tick_ms", 0.0));
        late_ms += t.value("late_ms", 0.0);
      }
      idle_load_ms += t.value("idle_load_ms", 0.0);
      if (t.value("loop_closure", false)) ++closures;
      loaded += t.value("loaded", 0ULL) + t.value("idle_loaded", 0ULL);
      unloaded += t.value("unloaded", 0ULL);
      over += t.value("over_budget", false) ? 1U : 0U;
      bytes_read += t.value("db_bytes_read", 0ULL);
      tx += t.value("db_transactions", 0ULL);
      q += t.value("db_queries", 0ULL);
      peak_kf = std::max<std::uint64_t>(peak_kf, t.value("resident_keyframes", 0ULL));
      peak_bytes = std::max<std::uint64_t>(peak_bytes, t.value("resident_bytes", 0ULL));
      dropped = t.value("frames_dropped", dropped);
      arrived = t.value("frames_arrived", arrived);
      wall_s = t.value("wall_s", wall_s);
    }
  }
  s["partial"] = true;
  s["ticks"] = ticks;
  s["loop_closures"] = closures;
  s["keyframes_loaded"] = loaded;
  s["keyframes_unloaded"] = unloaded;
  s["over_budget_ticks"] = over;
  s["db_bytes_read"] = bytes_read;
  s["db_transactions"] = tx;
  s["db_queries"] = q;
  s["peak_resident_keyframes"] = peak_kf;
  s["peak_resident_bytes"] = peak_bytes;
  s["frames_dropped"] = dropped;
  s["frames_arrived"] = arrived;
  s["wall_s"] = wall_s;
  s["time_compression"] = time_compression;
  s["tick_ms"] = {{"mean", tick_ms.mean()},
                  {"p50", tick_ms.Quantile(0.50)},
                  {"p99", tick_ms.Quantile(0.99)},
                  {"max", tick_ms.max()},
                  {"count", tick_ms.count()}};
  s["time_total_ms"] = TimeTotalJson({.steady_mean_ms = tick_ms.mean(),
                                      .steady_ticks = tick_ms.count(),
                                      .has_startup = has_startup,
                                      .startup_tick_ms = startup_tick_ms,
                                      .late_ms = late_ms,
                                      .idle_load_ms = idle_load_ms});
  if (has_startup && !s["startup"].is_object()) s["startup"] = nlohmann::json::object();
  if (has_startup) s["startup"]["tick_ms"] = startup_tick_ms;
  s["update_rate_hz"] = nullptr;
  if (time_compression > 0 && wall_s > 0) {
    s["update_rate_hz"] = static_cast<double>(ticks) / (wall_s * time_compression);
  }
  s["ate_rmse_m"] = nullptr;
  s["ate_se3_rmse_m"] = nullptr;
  s["rpe_trans_rmse_m"] = nullptr;
  s["rpe_rot_rmse_deg"] = nullptr;
  auto scenario = sim::LoadScenario(scenario_dir);
  auto est = ReadTrajectory(out_dir + "/estimate.tum", TrajectoryFormat::kTum);
  if (scenario.ok() && !scenario->localization_gt.empty() && est.ok() && est->poses.size() > 2) {
    auto gt = ReadTrajectory(scenario->localization_gt, TrajectoryFormat::kTum);
    if (gt.ok()) {
      if (auto none = Evaluate(*gt, *est, {.align = AlignMode::kNone}); none.ok()) {
        s["ate_rmse_m"] = none->ape_trans_m.rmse;
        s["rpe_trans_rmse_m"] = none->rpe_trans_m.rmse;
        s["rpe_rot_rmse_deg"] = none->rpe_rot_deg.rmse;
        s["associated_poses"] = none->associated;
      }
      if (auto se3 = Evaluate(*gt, *est, {.align = AlignMode::kSe3}); se3.ok()) {
        s["ate_se3_rmse_m"] = se3->ape_trans_m.rmse;
      }
    }
  }
  FillMissing(s);
  return s;
}

Result<nlohmann::json> RunOnDevice(const DeviceRunRequest& request, const std::atomic<bool>* stop) {
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
  // The map's files: every read of the run lands in the device (cold), or not (warm).
  const std::uint64_t dropped_file_bytes =
      request.cold_files ? DropFileCache(request.scenario_dir) : 0;
  dopt.ledger_path = !request.ledger_path.empty()
                         ? request.ledger_path
                         : request.out_dir + "/.ledger-" + std::to_string(getpid());
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<DeviceModel> device, OpenDeviceModel(dopt));
  if (request.on_device) request.on_device(*device);
  const Cgroup* device_cgroup = device->cgroup();
  const std::string swap_kind(device_cgroup != nullptr ? SwapKindName(device->swap().kind())
                                                       : "none");
  const std::string swap_reason = device_cgroup != nullptr
                                      ? device->swap().reason()
                                      : std::string("the ledger simulates no swap");
  const std::uint64_t swap_limit = device_cgroup != nullptr ? device_cgroup->swap_limit_bytes() : 0;
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
  std::uint64_t limit_min = device->limit_bytes();
  std::uint64_t charge_refusals = 0;
  std::uint64_t dram_peak = 0;  // usage + zram's compressed pages: the DRAM the device holds
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
    MapProcess(request, loop, *device, shared, ready[1], go[0], stop);
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

  // Monitor until the map process ends: the device's peak and OOM kills, the co-tenant's RSS.
  DeviceSample last = device->Sample();
  std::uint64_t peak = last.peak_bytes;
  std::uint64_t cotenant_peak_rss = 0, map_peak_rss = 0;
  ProcessSampler map_sampler;
  if (auto s = ProcessSampler::Open(map_pid); s.ok()) map_sampler = std::move(s).value();
  ProcessSampler co_sampler;
  pid_t co_pid = -1;
  int status = 0;
  rusage map_usage{};
  std::uint64_t swap_peak = 0, zram_mem_used_peak = 0, zram_orig_peak = 0, zram_compr_peak = 0;
  const auto sample_swap = [&](const DeviceSample& d) {
    if (d.ok) swap_peak = std::max(swap_peak, d.swap_bytes);
    const ZramSample z = device->SampleZram();
    if (z.ok) {
      zram_mem_used_peak = std::max(zram_mem_used_peak, z.mem_used_bytes);
      zram_orig_peak = std::max(zram_orig_peak, z.orig_data_bytes);
      zram_compr_peak = std::max(zram_compr_peak, z.compr_data_bytes);
    }
  };
  bool sent_term = false;
  for (;;) {
    // wait4: the map process's own rusage (its major faults) when it is reaped.
    const pid_t w = wait4(map_pid, &status, WNOHANG, &map_usage);
    if (w == map_pid) break;
    if (w < 0 && errno != EINTR) return Internal(std::string("waitpid: ") + std::strerror(errno));
    if (stop != nullptr && stop->load() && !sent_term) {
      kill(map_pid, SIGTERM);
      sent_term = true;
    }
    last = device->Sample();
    if (last.ok) peak = std::max({peak, last.peak_bytes, last.usage_bytes});
    sample_swap(last);
    if (charge_cgroup != nullptr) {
      const ZramSample z = device->SampleZram();
      if (z.ok) {
        shared->zram_mem_used_bytes.store(z.mem_used_bytes);
        if (last.ok) dram_peak = std::max(dram_peak, last.usage_bytes + z.mem_used_bytes);
        // Floor: a quarter of the device; zram holds at most swap_bytes (half the memory) of
        // swapped pages, so only a broken mm_stat could ask for less.
        const std::uint64_t target = ChargedLimit(charge_cgroup->limit_bytes(), z.mem_used_bytes,
                                                  kZramChargeStepBytes,
                                                  charge_cgroup->limit_bytes() / 4);
        if (target != charge_cgroup->current_limit_bytes()) {
          if (Status s = charge_cgroup->SetMemoryLimit(target); !s.ok()) {
            // The kernel could not reclaim down to it (v1 EBUSY): the device is over its DRAM
            // for now; the next sample tries again. Said once, counted always.
            if (charge_refusals++ == 0) std::fprintf(stderr, "device: %s\n", s.ToString().c_str());
          }
          limit_min = std::min(limit_min, charge_cgroup->current_limit_bytes());
          shared->device_limit_bytes.store(charge_cgroup->current_limit_bytes());
        }
      }
    }
    const ProcessSample m = map_sampler.Sample();
    if (m.alive) map_peak_rss = std::max(map_peak_rss, m.rss_bytes);
    if (cotenant_started) {
      const pid_t p = supervisor.child_pid();
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
      cotenant_peak_rss = std::max(cotenant_peak_rss, rss);
    }
    SleepS(0.05);
  }
  const ChildExit exit = DescribeWaitStatus(status);

  // Requests still in flight may finish (the same grace for every run), then the co-tenant stops.
  nlohmann::json cotenant = nullptr;
  if (cotenant_started) {
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
      cotenant["peak_rss_bytes"] = cotenant_peak_rss;
      std::ofstream(request.out_dir + "/cotenant.json") << ToJson(c).dump(2) << '\n';
    } else {
      cotenant = {{"outcome", "failed_to_start"}, {"reason", r.status().message()}};
    }
  } else if (request.with_cotenant) {
    cotenant = {
        {"outcome", "failed_to_start"},
        {"requests_completed", 0},
        {"restarts", 0},
        {"reason", !cotenant_error.ok() ? cotenant_error.message()
                                        : std::string("the map process never became ready")},
        {"note", std::string(kCotenantNote)}};
  }
  if (!cotenant.is_null()) {
    cotenant["events_file"] = "cotenant.jsonl";
    cotenant["request_period_s"] = period_s;
    cotenant["requests_planned"] = request.cotenant_requests;
    cotenant["stand_in"] = true;
  }

  const DeviceSample final_sample = device->Sample();
  if (final_sample.ok) peak = std::max(peak, final_sample.peak_bytes);
  sample_swap(final_sample);

  // The map process's summary, or what its ticks say.
  nlohmann::json s;
  std::string map_outcome;
  std::string map_error;
  if (std::ifstream e(request.out_dir + "/map_error.txt"); e) std::getline(e, map_error);
  if (exit.exited && exit.code == 0 && fs::exists(request.out_dir + "/map_summary.json")) {
    std::ifstream in(request.out_dir + "/map_summary.json");
    s = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
    map_outcome = s.value("interrupted", false) ? "interrupted" : "completed";
  }
  if (s.is_discarded() || s.is_null()) {
    ZM_ASSIGN_OR_RETURN(
        s, SummarizePartialRun(request.scenario_dir, request.out_dir, request.time_compression));
    map_outcome = exit.signaled && exit.signal == SIGKILL ? "killed"
                  : exit.signaled                         ? "crashed"
                                                          : "failed";
  }
  FillMissing(s);
  s["map"] = {{"outcome", map_outcome},
              {"pid", map_pid},
              {"exit_code", exit.exited ? exit.code : -1},
              {"signal", exit.signaled ? exit.signal : 0},
              {"peak_rss_bytes", map_peak_rss},
              {"major_faults", static_cast<std::uint64_t>(map_usage.ru_majflt)},
              {"arena_locked", s.value("arena_locked", false)},
              {"lock_arena_requested", loop.map.lock_arena},
              {"cold_files", request.cold_files},
              {"files_dropped_bytes", dropped_file_bytes}};
  if (!map_error.empty()) s["map"]["error"] = map_error;
  s["time_compression"] = request.time_compression;
  s["device_scale"] = request.device_scale;
  s["device"] = {{"kind", std::string(DeviceKindName(device->kind()))},
                 {"simulated", device->simulated()},
                 {"description", device->Describe()},
                 {"fallback_reason", device->fallback_reason()},
                 {"limit_bytes", device->limit_bytes()},
                 {"peak_bytes", peak},
                 {"oom_kills", final_sample.oom_kills},
                 {"limit_hits", final_sample.limit_hits},
                 {"scale", request.device_scale},
                 {"name", loop.device.name},
                 {"memory_bytes", loop.device.memory_bytes},
                 {"os_reserve_bytes", loop.device.os_reserve_bytes},
                 {"map_peak_rss_bytes", map_peak_rss},
                 {"cotenant_peak_rss_bytes", cotenant_peak_rss},
                 {"swap",
                  {{"kind", swap_kind},
                   {"requested", loop.device.swap},
                   {"reason", swap_reason},
                   {"description", device->swap().Describe()},
                   {"limit_bytes", swap_limit},
                   {"peak_bytes", swap_peak},
                   {"swappiness", dopt.cgroup.swappiness},
                   {"comp_algorithm", device->swap().comp_algorithm()},
                   {"zram_orig_peak_bytes", zram_orig_peak},
                   {"zram_compr_peak_bytes", zram_compr_peak},
                   {"zram_mem_used_peak_bytes", zram_mem_used_peak},
                   {"zram_charged", charge_cgroup != nullptr}}},
                 {"limit_min_bytes", limit_min},
                 {"dram_peak_bytes", charge_cgroup != nullptr ? dram_peak : peak},
                 {"limit_charge_refusals", charge_refusals}};
  s["oom_events"] = final_sample.oom_kills;  // the memory table's column (simulated for the ledger)
  if (!cotenant.is_null()) s["cotenant"] = cotenant;
  {
    std::ofstream out(request.out_dir + "/summary.json");
    out << s.dump(2) << '\n';
    if (!out) return IoError("cannot write '" + request.out_dir + "/summary.json'");
  }
  if (Status r = device->Remove(); !r.ok()) {
    std::fprintf(stderr, "device: %s\n", r.ToString().c_str());
  }
  if (map_outcome == "failed" && !map_error.empty() && s.value("ticks", 0) == 0) {
    return Internal("map process: " + map_error);
  }
  return s;
}

}  // namespace zm
