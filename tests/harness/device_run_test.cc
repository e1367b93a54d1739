// The experiment's run (harness/device_run.h) end to end at a small scale: the map process forked
// into the device, the co-tenant beside it, the runner outside writing summary.json whatever was
// killed. Cases that need a memory cgroup say so and skip where none can be made.
#include "harness/device_run.h"

#include <doctest/doctest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "harness/cgroup.h"
#include "harness/device_scale.h"
#include "harness/swap_device.h"
#include "tests/support/cotenant_test_support.h"
#include "tests/support/small_scenario.h"

namespace zm {
namespace {

namespace fs = std::filesystem;

// Everything the cases write under the temporary directory, removed when the process exits.
struct TempPaths {
  std::vector<std::string> paths;
  ~TempPaths() {
    std::error_code ec;
    for (const std::string& p : paths) fs::remove_all(p, ec);
  }
};
TempPaths& Temps() {
  static TempPaths t;
  return t;
}

// One small scenario for every case (generated once per test process): a 300 m2 floor, two
// patrol tasks, keyframes of ~100-200 KB resident, frames at 1 Hz.
const std::string& Scenario() {
  static const std::string dir = [] {
    const fs::path p = fs::temp_directory_path() /
                       ("zm_device_run_scenario_" + std::to_string(static_cast<long>(getpid())));
    fs::remove_all(p);
    Temps().paths.push_back(p.string());
    auto b = sim::GenerateHospital(test::SmallHospital(11));
    REQUIRE(b.ok());
    sim::ScenarioOptions o = test::SmallReplayScenario(11, 2);
    // The device run's memory accounting is under test: the oracle's features, named (issue 26).
    o.features = sim::FeatureSource::kOracle;
    auto r = sim::WriteScenario(*b, o, p.string());
    REQUIRE_MESSAGE(r.ok(), r.status().ToString());
    return p.string();
  }();
  return dir;
}

std::string RunDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() /
                     ("zm_device_run_" + name + "_" + std::to_string(static_cast<long>(getpid())));
  fs::remove_all(p);
  Temps().paths.push_back(p.string());
  return p.string();
}

std::vector<nlohmann::json> Ticks(const std::string& run_dir) {
  std::vector<nlohmann::json> out;
  std::ifstream in(run_dir + "/ticks.jsonl");
  for (std::string line; std::getline(in, line);) out.push_back(nlohmann::json::parse(line));
  return out;
}

nlohmann::json ReadJson(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// The experiment's profile with a small device: orin-nano-8gb at `scale` and a policy.
DeviceRunRequest Request(const std::string& name, const std::string& policy, double scale) {
  auto p = LoadExperimentProfile("orin-nano-8gb");
  REQUIRE(p.ok());
  ProfileOverrides ov;
  ov.policy = policy;
  ov.memory_thr = "12";
  REQUIRE(ApplyOverrides(ov, p->core).ok());
  p->core.map.process_cap_bytes = 0;  // ASan reserves terabytes; the device is the cgroup
  DeviceRunRequest r;
  r.scenario_dir = Scenario();
  r.out_dir = RunDir(name);
  r.profile = std::move(p).value();
  r.device_scale = scale;
  r.cgroup.prefix = "zm-test-run";
  r.cotenant_executable = ZM_TEST_COTENANT_EXE;
  r.profile.cotenant.weights_dir = test::TestWeightsDir();
  return r;
}

// Whether a memory cgroup can be made here (says why not, once per case).
bool CgroupOrSkip() {
  CgroupOptions o;
  o.limit_bytes = 16 << 20;
  o.prefix = "zm-test-probe";
  auto cg = Cgroup::Create(o);
  if (!cg.ok()) {
    MESSAGE("SKIPPED: no memory cgroup can be created here: " << cg.status().message());
    return false;
  }
  (void)cg->Remove();
  return true;
}

const std::vector<std::string> kTickKeys = {
    "wall_s",         "device_usage_bytes", "map_rss_bytes",  "cotenant_rss_bytes",
    "map_majflt",     "map_minflt",         "oom_kills",      "frames_dropped",
    "frames_arrived", "device_swap_bytes",  "map_swap_bytes", "map_majflt_tick",
    "device_limit_bytes", "zram_mem_used_bytes"};

TEST_CASE(
    "device run (ledger): simulated in the summary, frames dropped on an overrun, every key") {
  test::EmulatorLauncher launcher;
  DeviceRunRequest r = Request("ledger_overrun", "semantic", 1.0 / 64);
  r.device = DeviceKind::kLedger;
  r.device_explicit = true;
  // 20x: a frame every 50 ms of wall time; every fourth tick is made 130 ms slow, so at least
  // two frames arrive while it runs and at least one of them is dropped.
  r.time_compression = 20.0;
  r.map_tick_hook = [](const TickLoop& l) {
    if (l.last_record().tick % 4 == 1) std::this_thread::sleep_for(std::chrono::milliseconds(130));
  };
  auto s = RunOnDevice(r);
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  const nlohmann::json j = ToJson(*s);
  // summary.json is the typed summary's codec output, versioned.
  CHECK(ReadJson(r.out_dir + "/summary.json") == j);
  CHECK(j["schema_version"] == kSummarySchemaVersion);
  CHECK(j["device"]["kind"] == "ledger");
  CHECK(j["device"]["simulated"] == true);
  CHECK(j["device"]["description"].get<std::string>().find("simulated") != std::string::npos);
  CHECK(j["map"]["outcome"] == "completed");
  CHECK(j["time_compression"] == 20.0);
  const auto ticks = j["ticks"].get<std::uint64_t>();
  const auto dropped = j["frames_dropped"].get<std::uint64_t>();
  CHECK(ticks > 2);
  // At least one per slow tick (ticks 1, 5, 9, ...) that another tick followed.
  CHECK(dropped + 1 >= (ticks + 2) / 4);
  CHECK(dropped > 0);
  CHECK(j["frames_arrived"].get<std::uint64_t>() == ticks + dropped);
  CHECK(j["update_rate_hz"].get<double>() < 1.0);  // the frames' clock ran faster than the loop
  const auto t = Ticks(r.out_dir);
  REQUIRE(t.size() == ticks);
  for (const std::string& k : kTickKeys) CHECK_MESSAGE(t.back().contains(k), k);
  CHECK(t.back()["frames_dropped"].get<std::uint64_t>() == dropped);
  for (std::size_t i = 1; i < t.size(); ++i) CHECK(t[i]["wall_s"] >= t[i - 1]["wall_s"]);
  CHECK(fs::exists(r.out_dir + "/estimate.tum"));
  CHECK(ReadJson(r.out_dir + "/summary.json")["device"]["kind"] == "ledger");
  MESSAGE(ticks << " ticks, " << dropped << " frames dropped at 20x, " << (ticks + 2) / 4
                << " slow ticks");
}

TEST_CASE("device run (ledger): a refused map grant means those keyframes are not loaded") {
  test::EmulatorLauncher launcher;
  DeviceRunRequest r = Request("ledger_refused", "basic", 1.0 / 64);
  r.device = DeviceKind::kLedger;
  r.device_explicit = true;
  std::optional<LedgerTenant> other;
  // Another tenant holds all but the map process's overhead (4 MiB at this scale) and 1 MiB.
  r.on_device = [&other](DeviceModel& d) {
    REQUIRE(d.ledger() != nullptr);
    auto t = d.ledger()->Register("other", d.limit_bytes() - (5 << 20));
    REQUIRE(t.ok());
    other.emplace(std::move(t).value());
  };
  r.with_cotenant = true;  // its weights cannot be granted either: it fails to start
  r.cotenant_requests = 2;
  r.cotenant_period_s = 0.2;
  r.cotenant_drain_s = 2.0;
  r.profile.cotenant.restart_delay_s = 0.2;
  auto s = RunOnDevice(r);
  other.reset();
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  const nlohmann::json j = ToJson(*s);
  CHECK(j["map"]["outcome"] == "completed");
  CHECK(j.value("ledger_refusals", 0ULL) > 0);
  // Loads that would have exceeded the grant found no slot: keyframes not loaded.
  CHECK(j["alloc_failures"].get<std::uint64_t>() > 0);
  CHECK(j["cotenant"]["outcome"] == "failed_to_start");
  CHECK(j["cotenant"]["requests_completed"] == 0);
  CHECK(j["device"]["oom_kills"].get<std::uint64_t>() > 0);  // the ledger's simulated events
}

TEST_CASE("device run (ledger): a killed run's summary rebuilt from its ticks matches its own") {
  // SummarizePartialRun reads what the map process left (map_start.json, ticks.jsonl,
  // estimate.tum): on a completed run's directory it must give the counts the run's own summary
  // has, through the same typed summary.
  test::EmulatorLauncher launcher;
  DeviceRunRequest r = Request("ledger_partial", "semantic", 1.0 / 64);
  r.device = DeviceKind::kLedger;
  r.device_explicit = true;
  auto s = RunOnDevice(r);
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  auto p = SummarizePartialRun(r.scenario_dir, r.out_dir, r.time_compression);
  REQUIRE_MESSAGE(p.ok(), p.status().ToString());
  const RunSummary& whole = s->run;
  CHECK(p->partial);
  CHECK_FALSE(whole.partial);
  CHECK(p->ticks == whole.ticks);
  CHECK(p->k_max == whole.k_max);  // from map_start.json
  CHECK(p->closures_accepted == whole.closures_accepted);
  CHECK(p->frames_localized == whole.frames_localized);
  CHECK(p->tick_ms.count == whole.tick_ms.count);
  // The stages from ticks.jsonl's stages_ms (4 decimals there): the same statistics.
  const auto memory = static_cast<std::size_t>(LoopStage::kMemory);
  CHECK(whole.stages[memory].p50_ms > 0.0);
  CHECK(p->stages[memory].p50_ms == doctest::Approx(whole.stages[memory].p50_ms).epsilon(0.05));
  REQUIRE(p->replay.has_value());
  REQUIRE(whole.replay.has_value());
  CHECK(p->replay->frames_arrived == whole.replay->frames_arrived);
  REQUIRE(p->replay->trajectory.ate_rmse_m.has_value());
  // The estimate file holds the poses at TUM's printed precision.
  CHECK(*p->replay->trajectory.ate_rmse_m ==
        doctest::Approx(*whole.replay->trajectory.ate_rmse_m).epsilon(1e-3));
  CHECK(ToJson(*p)["partial"] == true);
}

TEST_CASE("device run: a map made at full footprint on a scaled device names the footprint") {
  // basic's arena holds the whole map: at --device-scale 1/2 a full-footprint map's arena
  // outgrows a map process cap the device scale did not shrink. The run refuses before anything
  // runs, naming the scales and the numbers, instead of the arena's "exceeds RLIMIT_AS".
  DeviceRunRequest r = Request("footprint", "basic", 0.5);
  r.device = DeviceKind::kLedger;
  r.device_explicit = true;
  r.profile.core.map.process_cap_bytes = 1 << 20;
  auto s = RunOnDevice(r);
  REQUIRE_FALSE(s.ok());
  const std::string m = s.status().message();
  CHECK(m.find("footprint scale 1") != std::string::npos);
  CHECK(m.find("--device-scale 0.5") != std::string::npos);
  CHECK(m.find("--footprint-scale 0.5") != std::string::npos);
  CHECK(m.find("map.process_cap_bytes") != std::string::npos);
  CHECK(m.find("RLIMIT_AS") == std::string::npos);
  // A matching footprint, or no cap, runs as before.
  r.profile.core.map.process_cap_bytes = 0;
  r.out_dir = RunDir("footprint_nocap");
  r.profile.core.loop.max_ticks = 3;
  test::EmulatorLauncher launcher;
  auto ok = RunOnDevice(r);
  CHECK_MESSAGE(ok.ok(), ok.status().ToString());
}

TEST_CASE("device run (cgroup): the map's residency is visible in the cgroup" *
          doctest::test_suite("slow")) {
  if (!CgroupOrSkip()) return;
  test::EmulatorLauncher launcher;
  for (const std::string policy : {"basic", "semantic"}) {
    CAPTURE(policy);
    DeviceRunRequest r = Request("residency_" + policy, policy, 1.0 / 16);
    r.device = DeviceKind::kCgroup;
    r.device_explicit = true;
    r.profile.core.map.prefault_arena = true;
    auto s = RunOnDevice(r);
    REQUIRE_MESSAGE(s.ok(), s.status().ToString());
    const nlohmann::json j = ToJson(*s);
    CHECK(j["device"]["kind"] == "cgroup");
    CHECK(j["device"]["simulated"] == false);
    CHECK(j["map"]["outcome"] == "completed");
    // The device's swap (JetPack's zram, scaled) and what the run reports of it.
    const nlohmann::json& sw = j["device"]["swap"];
    const std::string kind = sw["kind"];
    CHECK((kind == "zram" || kind == "existing" || kind == "none"));
    if (kind == "none") {
      MESSAGE("SKIPPED (swap): the device has no swap here: " << sw["reason"]);
    } else {
      CHECK(sw["limit_bytes"].get<std::uint64_t>() ==
            ScaleBytes(3886ULL << 20, 1.0 / 16) / 4096 * 4096);
    }
    if (kind == "zram") {
      // zram's store is charged to the device (the default): the limit in force is the device's
      // less what zram holds, never above the device, reported per tick and at its lowest.
      CHECK(sw["zram_charged"] == true);
      const std::uint64_t limit = j["device"]["limit_bytes"];
      CHECK(j["device"]["limit_min_bytes"].get<std::uint64_t>() <= limit);
      CHECK(j["device"]["limit_min_bytes"].get<std::uint64_t>() >= limit / 4);
      CHECK(j["device"]["dram_peak_bytes"].get<std::uint64_t>() >=
            sw["zram_mem_used_peak_bytes"].get<std::uint64_t>());
      for (const auto& x : Ticks(r.out_dir)) {
        const std::uint64_t in_force = x["device_limit_bytes"];
        CHECK(in_force <= limit);
        CHECK(in_force >= limit / 4);  // ChargedLimit's floor
      }
    } else {
      CHECK(sw["zram_charged"] == false);
    }
    if (kind == "zram") {
      // Removed after the run: no swap of ours remains.
      std::ifstream swaps("/proc/swaps");
      std::string line, all;
      while (std::getline(swaps, line)) all += line + "\n";
      CHECK(ParseProcSwaps(all).count == 0);
    }
    CHECK(j["map"].contains("major_faults"));
    CHECK(j["map"]["arena_locked"] == false);  // the profile's lock_arena = false
    CHECK(j["map"]["cold_files"] == true);
    CHECK(j["map"]["files_dropped_bytes"].get<std::uint64_t>() > 0);
    const auto t = Ticks(r.out_dir);
    REQUIRE(t.size() > 3);
    std::uint64_t max_usage = 0;
    for (const auto& x : t)
      max_usage = std::max(max_usage, x["device_usage_bytes"].get<std::uint64_t>());
    const std::uint64_t first = t.front()["device_usage_bytes"];
    const std::uint64_t last_usage = t.back()["device_usage_bytes"];
    const std::uint64_t slot = j["slot_bytes"];
    MESSAGE(policy << ": slot " << slot << " B, K_max " << j["k_max"]
                   << ", cgroup usage first tick " << first << " B, max " << max_usage
                   << " B, last " << last_usage << " B; resident first "
                   << t.front()["resident_bytes"] << " B, last " << t.back()["resident_bytes"]
                   << " B; peak " << j["device"]["peak_bytes"]);
    CHECK(j["device"]["peak_bytes"].get<std::uint64_t>() >= max_usage);
    if (policy == "semantic") {
      // The arena (K_max slots) is resident from the first tick on and the usage never grows by
      // more than a slot's worth beyond it (the arena does not grow).
      const std::uint64_t arena = j["k_max"].get<std::uint64_t>() * slot;
      CHECK(first >= arena);
      CHECK(max_usage <= first + arena / 2 + (4u << 20));
    } else {
      // Basic starts with its whole working memory, transfers down towards MemoryThr, then
      // retrieves again: the cgroup's usage falls and rises with it (released slots' pages go
      // back to the kernel; retrieved ones are taken).
      std::size_t lo = 0;
      for (std::size_t i = 0; i < t.size(); ++i) {
        if (t[i]["resident_bytes"] < t[lo]["resident_bytes"]) lo = i;
      }
      std::size_t hi = lo;
      for (std::size_t i = lo; i < t.size(); ++i) {
        if (t[i]["resident_bytes"] > t[hi]["resident_bytes"]) hi = i;
      }
      const auto res = [&t](std::size_t i) { return t[i]["resident_bytes"].get<std::int64_t>(); };
      const auto use = [&t](std::size_t i) {
        return t[i]["device_usage_bytes"].get<std::int64_t>();
      };
      MESSAGE("basic: resident " << res(0) << " -> " << res(lo) << " (tick " << lo << ") -> "
                                 << res(hi) << " (tick " << hi << "); cgroup " << use(0) << " -> "
                                 << use(lo) << " -> " << use(hi));
      const auto s64 = static_cast<std::int64_t>(slot);
      REQUIRE(res(0) - res(lo) >= 4 * s64);
      CHECK(use(0) - use(lo) >= (res(0) - res(lo)) / 2);
      if (res(hi) - res(lo) >= 2 * s64) {
        CHECK(use(hi) - use(lo) >= (res(hi) - res(lo)) / 2);
      } else {
        MESSAGE("basic did not retrieve enough after its low point to check the rise");
      }
    }
  }
}

TEST_CASE("device run (cgroup): the map process OOM-killed by the kernel, the runner's summary") {
  if (!CgroupOrSkip()) return;
  test::EmulatorLauncher launcher;
  DeviceRunRequest r = Request("map_killed", "semantic", 1.0 / 32);  // ~200 MiB device
  // No swap: the kill is what this case is about (with JetPack's zram the allocation fills the
  // swap first, and a short replay may end before the kill).
  r.profile.core.device.swap = "none";
  r.profile.core.device.swap_bytes = 0;
  r.device = DeviceKind::kCgroup;
  r.device_explicit = true;
  // 2x, not faster: the kill ends the run soon after the hog starts, so a long replay costs
  // nothing when all goes well and leaves room when the machine is loaded (at 10x a replay whose
  // map process started slowly, ASan at load 5 on two cores, once ended before the kill).
  r.time_compression = 2.0;
  // Once the map process has written kPoses poses (estimate.tum is streamed, and RunOnDevice
  // removes an old one before the run), it starts allocating (and touching) memory until the
  // kernel kills it. Not after a fixed delay: under load a short replay could end first (it did,
  // once, at load 5.5). kPoses, not the first pose: the trajectory metrics checked below need
  // at least 3 associated poses, and at 2x the kill can come before a third one.
  constexpr int kPoses = 10;
  const std::string estimate = r.out_dir + "/estimate.tum";
  r.map_child_hook = [estimate] {
    std::thread([estimate] {
      for (int i = 0; i < 12000; ++i) {  // at most a minute; the run's own checks follow
        std::ifstream in(estimate);
        const auto lines = std::count(std::istreambuf_iterator<char>(in),
                                      std::istreambuf_iterator<char>(), '\n');
        if (lines >= kPoses) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
      for (;;) {
        void* p =
            mmap(nullptr, 4 << 20, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (p == MAP_FAILED) continue;
        std::fill_n(static_cast<volatile char*>(p), 4 << 20, 1);
      }
    }).detach();
  };
  auto s = RunOnDevice(r);
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  const nlohmann::json j = ToJson(*s);
  // REQUIRE: a run that completed has no signal to read further down.
  REQUIRE(j["map"]["outcome"] == "killed");
  CHECK(j["map"]["signal"] == 9);
  CHECK(j["partial"] == true);
  CHECK(j["device"]["oom_kills"].get<std::uint64_t>() >= 1);
  CHECK(j["ticks"].get<std::uint64_t>() > 0);
  CHECK(j["k_max"].get<std::uint64_t>() > 0);  // from the map's start (map_start.json)
  CHECK(j["tick_ms"]["count"].get<std::uint64_t>() + 1 == j["ticks"].get<std::uint64_t>());
  // The trajectory metrics over the poses it produced (estimate.tum is streamed).
  REQUIRE(j["ate_rmse_m"].is_number());  // (then associated_poses is there to read)
  // (a pose reaches the disk before its tick: the kill may leave one pose more than ticks)
  CHECK(j["associated_poses"].get<std::uint64_t>() >= j["ticks"].get<std::uint64_t>());
  CHECK(j["associated_poses"].get<std::uint64_t>() <= j["ticks"].get<std::uint64_t>() + 1);
  const nlohmann::json on_disk = ReadJson(r.out_dir + "/summary.json");
  CHECK(on_disk["map"]["outcome"] == "killed");
  MESSAGE("map killed after " << j["ticks"] << " ticks; OOM kills " << j["device"]["oom_kills"]);
}

TEST_CASE("device run (cgroup): the co-tenant OOM-killed and restarted inside the device" *
          doctest::test_suite("slow")) {
  if (!CgroupOrSkip()) return;
  test::EmulatorLauncher launcher;
  DeviceRunRequest r = Request("cotenant_killed", "semantic", 1.0 / 32);  // ~200 MiB device
  r.profile.core.device.swap = "none";  // the kill, not the swap, is what this case is about
  r.profile.core.device.swap_bytes = 0;
  r.device = DeviceKind::kCgroup;
  r.device_explicit = true;
  r.time_compression = 4.0;  // ~10 s
  r.with_cotenant = true;
  r.cotenant_requests = 8;
  r.cotenant_drain_s = 2.0;
  // Each request's KV cache (8 MiB per token at this scale, 16 tokens a prefill batch) outgrows
  // the device in its second batch: the kernel kills the co-tenant in every request, and the
  // supervisor restarts it.
  CotenantOptions& c = r.profile.cotenant;
  c.prompt_tokens = 240;
  c.answer_tokens = 4;
  c.prompt_batch_tokens = 16;
  c.context_tokens = 256;
  c.kv_bytes_per_token = 256ULL << 20;  // x 1/32 = 8 MiB per token
  c.watchdog_s = 0.0;
  c.restart_delay_s = 0.2;
  // The per-request KV growth is what kills it: not a pinned n_ctx cache (which would fail at
  // start-up).
  c.weights = CotenantWeights::kMmap;
  // The victim must be the co-tenant for this test: the map process is protected.
  r.map_child_hook = [] { std::ofstream("/proc/self/oom_score_adj") << "-1000\n"; };
  auto s = RunOnDevice(r);
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  const nlohmann::json j = ToJson(*s);
  CHECK(j["map"]["outcome"] == "completed");
  REQUIRE(j.contains("cotenant"));
  const nlohmann::json& ct = j["cotenant"];
  CHECK(ct["outcome"] == "killed");
  CHECK(ct["kills"].get<std::uint64_t>() >= 1);
  CHECK(ct["restarts"].get<std::uint64_t>() >= 1);
  CHECK(j["device"]["oom_kills"].get<std::uint64_t>() >= 1);
  CHECK(fs::exists(r.out_dir + "/cotenant.jsonl"));
  // The co-tenant's resident memory reached the ticks.
  std::uint64_t co_rss = 0;
  for (const auto& x : Ticks(r.out_dir))
    co_rss = std::max(co_rss, x["cotenant_rss_bytes"].get<std::uint64_t>());
  CHECK(co_rss > 0);
  MESSAGE("co-tenant: " << ct["kills"] << " kills, " << ct["restarts"]
                        << " restarts; device OOM kills " << j["device"]["oom_kills"]);
}

}  // namespace
}  // namespace zm
