// zonemapd: the on-device loop. Reads frames from the live line protocol (stdin or a loopback
// UDP port) or replays a frames file, keeps the working set of a map database within the
// profile's budget, localizes on it, and writes telemetry. SIGINT/SIGTERM end it cleanly at a
// tick boundary: telemetry is flushed and summary.json written.
//
//   zonemapd --profile orin-nano-8gb --db map.db --stdin --out run/
//   zonemapd --profile host --db map.db --udp 7777 --out run/
//   zonemapd --profile host --scenario DIR --out run/        (replay, with trajectory metrics)
#include <CLI/CLI.hpp>
#include <opencv2/core/utility.hpp>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "runtime/device_run.h"
#include "runtime/frame_source.h"
#include "runtime/memory_cap.h"
#include "runtime/profile.h"
#include "runtime/run.h"

namespace {
std::atomic<bool> g_stop{false};
extern "C" void OnStop(int) { g_stop.store(true); }

int Fail(const std::string& message) {
  std::fprintf(stderr, "zonemapd: %s\n", message.c_str());
  return 1;
}
}  // namespace

int main(int argc, char** argv) {
  cv::setNumThreads(0);  // single-threaded loop; OpenCV's pool spins forever under qemu-user
  CLI::App app{"zonemapd: the on-device zone-managed localization loop"};
  std::string profile_name = "host", db_path, scenario, frames_path, out, policy, memory_thr,
              cotenant;
  int udp_port = -1;
  bool use_stdin = false;
  std::uint64_t max_ticks = 0;
  std::uint32_t max_features = 2048;
  app.add_option("--profile", profile_name, "device profile name or TOML path");
  app.add_option("--db", db_path, "map database (live or frames-file input)");
  app.add_option("--scenario", scenario, "replay a simulated scenario directory instead");
  app.add_option("--frames", frames_path, "replay a frames file against --db");
  app.add_flag("--stdin", use_stdin, "read the live line protocol from stdin");
  app.add_option("--udp", udp_port, "read the live line protocol from 127.0.0.1:PORT");
  app.add_option("--out", out, "run directory (ticks.jsonl, summary.json)")->required();
  app.add_option("--policy", policy, "override the profile's policy");
  app.add_option("--memory-thr", memory_thr, "override MemoryThr: N, BYTES or N,BYTES");
  app.add_option("--cotenant", cotenant, "start the VLM stand-in beside the loop (replay only)");
  app.add_option("--max-ticks", max_ticks, "stop after this many ticks");
  app.add_option("--max-features", max_features, "largest frame accepted on live input");
  CLI11_PARSE(app, argc, argv);

  auto profile = zm::LoadProfile(profile_name);
  if (!profile.ok()) return Fail(profile.status().message());
  zm::ProfileOverrides ov;
  if (!policy.empty()) ov.policy = policy;
  if (!memory_thr.empty()) ov.memory_thr = memory_thr;
  if (!cotenant.empty()) ov.cotenant = cotenant;
  if (auto s = zm::ApplyOverrides(ov, profile.value()); !s.ok()) return Fail(s.message());
  if (profile->map.process_cap_bytes != 0) {
    auto cap = zm::ApplyProcessCap(profile->map.process_cap_bytes);
    if (!cap.ok()) return Fail(cap.status().message());
  }
  struct sigaction sa {};
  sa.sa_handler = OnStop;  // no SA_RESTART: a blocking read returns EINTR and the loop ends
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  if (!scenario.empty()) {
    zm::DeviceRunRequest req;
    req.scenario_dir = scenario;
    req.out_dir = out;
    req.profile = profile.value();
    req.with_cotenant = !cotenant.empty();
    req.max_ticks = max_ticks;
    auto s = zm::RunOnDevice(req, &g_stop);
    if (!s.ok()) return Fail(s.status().message());
    std::printf("zonemapd: %llu ticks, peak resident %u of K_max %u, %llu loop closures\n",
                static_cast<unsigned long long>(s.value()["ticks"].get<std::uint64_t>()),
                s.value()["peak_resident_keyframes"].get<unsigned>(),
                s.value()["k_max"].get<unsigned>(),
                static_cast<unsigned long long>(s.value()["loop_closures"].get<std::uint64_t>()));
    return 0;
  }

  if (db_path.empty()) return Fail("give --db MAP.db (or --scenario DIR)");
  const int inputs = (use_stdin ? 1 : 0) + (udp_port >= 0 ? 1 : 0) + (frames_path.empty() ? 0 : 1);
  if (inputs != 1) return Fail("give exactly one input: --stdin, --udp PORT or --frames FILE");
  auto loop_config = zm::LoopConfigFromProfile(profile.value());
  if (!loop_config.ok()) return Fail(loop_config.status().message());
  loop_config->max_ticks = max_ticks;
  auto db = zm::MapDb::Open(db_path);
  if (!db.ok()) return Fail(db.status().message());

  std::unique_ptr<zm::FrameSource> source;
  if (!frames_path.empty()) {
    auto r = zm::OpenReplaySource(frames_path);
    if (!r.ok()) return Fail(r.status().message());
    source = std::move(r).value();
  } else if (use_stdin) {
    source = std::make_unique<zm::LineFrameSource>(0, max_features);
  } else {
    if (udp_port > 65535) return Fail("--udp port " + std::to_string(udp_port) + " is above 65535");
    auto r = zm::UdpFrameSource::Bind(static_cast<std::uint16_t>(udp_port), max_features);
    if (!r.ok()) return Fail(r.status().message());
    std::fprintf(stderr, "zonemapd: listening on 127.0.0.1:%u\n", r.value()->port());
    source = std::move(r).value();
  }
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  zm::TelemetryWriter telemetry;
  if (auto s = telemetry.Open(out + "/ticks.jsonl"); !s.ok()) return Fail(s.message());
  auto loop = zm::TickLoop::Create(loop_config.value(), *db.value(), *source, &telemetry, {}, {},
                                   profile->loop.rate_hz);
  if (!loop.ok()) return Fail(loop.status().message());
  bool interrupted = false;
  for (;;) {
    if (g_stop.load()) {
      interrupted = true;
      break;
    }
    auto more = loop.value()->Tick();
    if (!more.ok()) return Fail(more.status().message());
    if (!more.value()) {
      interrupted = g_stop.load();
      break;
    }
  }
  telemetry.Close();
  nlohmann::json s = zm::LoopSummary(*loop.value(), profile->loop.rate_hz, interrupted);
  s["profile"] = profile->source;
  std::ofstream(out + "/summary.json") << s.dump(2) << '\n';
  (void)zm::WriteTrajectory(out + "/estimate.tum", loop.value()->estimate(), zm::TrajectoryFormat::kTum);
  std::printf("zonemapd: %llu ticks, %llu malformed lines skipped, peak resident %u of K_max %u\n",
              static_cast<unsigned long long>(loop.value()->totals().ticks),
              static_cast<unsigned long long>(loop.value()->malformed_lines()),
              loop.value()->totals().peak_resident_keyframes, loop.value()->k_max());
  return 0;
}
