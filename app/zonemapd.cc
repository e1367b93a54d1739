// zonemapd: the on-device loop. Reads frames from the live line protocol (stdin or a loopback
// UDP port) or replays a recorded frames file, keeps the working set of a map database within the
// profile's budget, localizes on it, and writes telemetry. SIGINT/SIGTERM end it cleanly at a
// tick boundary: telemetry is flushed and summary.json written.
//
//   zonemapd --profile orin-nano-8gb --db map.db --stdin --out run/
//   zonemapd --profile host --db map.db --udp 7777 --out run/
//   zonemapd --profile host --db map.db --frames frames.bin --out run/     (a recorded run)
//
// It links the on-device core only (lib/ below lib/sim; tests/app checks): replaying a simulated
// scenario with trajectory metrics and a co-tenant is `zonemap run`'s job.
#include <CLI/CLI.hpp>
#include <opencv2/core/utility.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "runtime/estimate_writer.h"
#include "runtime/frame_source.h"
#include "runtime/memory_cap.h"
#include "runtime/profile.h"
#include "runtime/stop_signal.h"
#include "runtime/summary.h"
#include "runtime/telemetry.h"
#include "runtime/tick_loop.h"

namespace {
int Fail(const std::string& message) {
  std::fprintf(stderr, "zonemapd: %s\n", message.c_str());
  return 1;
}
}  // namespace

int main(int argc, char** argv) {
  cv::setNumThreads(0);  // single-threaded loop; OpenCV's pool spins forever under qemu-user
  CLI::App app{"zonemapd: the on-device zone-managed localization loop"};
  std::string profile_name = "host", db_path, frames_path, out, policy, memory_thr;
  int udp_port = -1;
  bool use_stdin = false;
  std::uint64_t max_ticks = 0;
  std::uint32_t max_features = 2048;
  app.add_option("--profile", profile_name, "device profile name or TOML path");
  app.add_option("--db", db_path, "map database")->required();
  app.add_option("--frames", frames_path, "replay a recorded frames file");
  app.add_flag("--stdin", use_stdin, "read the live line protocol from stdin");
  app.add_option("--udp", udp_port, "read the live line protocol from 127.0.0.1:PORT");
  app.add_option("--out", out, "run directory (ticks.jsonl, estimate.tum, summary.json)")->required();
  app.add_option("--policy", policy, "override the profile's policy");
  app.add_option("--memory-thr", memory_thr, "override MemoryThr: N, BYTES or N,BYTES");
  app.add_option("--max-ticks", max_ticks, "stop after this many ticks");
  app.add_option("--max-features", max_features, "largest frame accepted on live input");
  CLI11_PARSE(app, argc, argv);

  auto profile = zm::LoadProfile(profile_name);
  if (!profile.ok()) return Fail(profile.status().message());
  zm::ProfileOverrides ov;
  if (!policy.empty()) ov.policy = policy;
  if (!memory_thr.empty()) ov.memory_thr = memory_thr;
  if (auto s = zm::ApplyOverrides(ov, profile.value()); !s.ok()) return Fail(s.message());
  profile->loop.max_ticks = max_ticks;
  if (profile->map.process_cap_bytes != 0) {
    auto cap = zm::ApplyProcessCap(profile->map.process_cap_bytes);
    if (!cap.ok()) return Fail(cap.status().message());
  }
  zm::InstallStopSignals();

  const int inputs = (use_stdin ? 1 : 0) + (udp_port >= 0 ? 1 : 0) + (frames_path.empty() ? 0 : 1);
  if (inputs != 1) return Fail("give exactly one input: --stdin, --udp PORT or --frames FILE");
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
  if (ec) return Fail("cannot create run directory '" + out + "': " + ec.message());
  zm::TelemetryWriter telemetry;
  if (auto s = telemetry.Open(out + "/ticks.jsonl"); !s.ok()) return Fail(s.message());
  zm::EstimateWriter estimate;
  if (auto s = estimate.Open(out + "/estimate.tum"); !s.ok()) return Fail(s.message());
  auto loop = zm::TickLoop::Create(profile.value(), *db.value(), *source);
  if (!loop.ok()) return Fail(loop.status().message());
  const std::uint32_t flush_every = profile->telemetry.flush_ticks;
  bool interrupted = false;
  for (;;) {
    if (zm::StopRequested()) {
      interrupted = true;
      break;
    }
    auto more = loop.value()->Tick();
    if (!more.ok()) return Fail(more.status().message());
    if (!more.value()) {
      interrupted = zm::StopRequested();
      break;
    }
    const zm::TickRecord& rec = loop.value()->last_record();
    telemetry.Write(rec);
    estimate.Write(rec.stamp_s, rec.pose);
    if (flush_every != 0 && (rec.tick + 1) % flush_every == 0) {
      telemetry.Flush();
      estimate.Flush();
    }
    // The idle part: queued zone loads advance until the next frame is due or already waiting.
    (void)loop.value()->Idle();
  }
  telemetry.Close();
  estimate.Close();
  nlohmann::json s = zm::LoopSummary(*loop.value(), interrupted);
  s["profile"] = profile->source;
  std::ofstream(out + "/summary.json") << s.dump(2) << '\n';
  std::fprintf(stderr, "zonemapd: %llu ticks, %llu malformed lines skipped, peak resident %u of K_max %u\n",
               static_cast<unsigned long long>(loop.value()->totals().ticks),
               static_cast<unsigned long long>(loop.value()->malformed_lines()),
               loop.value()->totals().peak_resident_keyframes, loop.value()->k_max());
  return 0;
}
