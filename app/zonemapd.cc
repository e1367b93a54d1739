// zonemapd: the robot's localization service. Reads the live line protocol (frames, image
// frames, routes, budgets) on stdin or a loopback UDP port, or replays a recorded frames file or
// a TUM RGB-D folder; keeps the working
// set of a map database within the budget, localizes on it, and answers every processed frame
// with one pose line on stdout (and, for UDP, one datagram back to the sender). Diagnostics go to
// stderr only. SIGINT/SIGTERM end it cleanly at a tick boundary: telemetry is flushed and
// summary.json written. The protocol: README "Driving zonemapd from a robot"; the session:
// lib/runtime/daemon.h.
//
//   zonemapd --profile orin-nano-8gb --db map.db --stdin --out run/
//   zonemapd --profile host --db map.db --udp 7777 --out run/
//   zonemapd --profile host --db map.db --frames frames.bin --out run/     (a recorded run)
//   zonemapd --profile host --db map.db --tum rgbd_dataset_freiburg1_xyz --odom odom.txt --out run/
//
// It links the on-device core only (lib/ below lib/sim; tests/app checks): replaying a simulated
// scenario with trajectory metrics and a co-tenant is `zonemap run`'s job.
#include <CLI/CLI.hpp>
#include <opencv2/core/utility.hpp>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "param_options.h"
#include "runtime/daemon.h"
#include "runtime/memory_cap.h"
#include "runtime/profile.h"
#include "runtime/profile_reader.h"
#include "runtime/sqlite_heap.h"
#include "runtime/stop_signal.h"
#include "tum/tum_replay.h"

namespace {
int Fail(const std::string& message) {
  std::fprintf(stderr, "zonemapd: %s\n", message.c_str());
  return 1;
}
}  // namespace

int main(int argc, char** argv) {
  cv::setNumThreads(0);  // single-threaded loop; OpenCV's pool spins forever under qemu-user
  CLI::App app{"zonemapd: the on-device zone-managed localization service"};
  std::string profile_name = "host", db_path, frames_path, out, policy, memory_thr;
  std::string sqlite_heap = "64MiB";
  int udp_port = -1;
  bool use_stdin = false;
  bool no_hello = false;
  std::uint64_t max_ticks = 0;
  std::uint32_t max_features = 0;
  std::string tum_dir, images_mode = "auto", image_size;
  zm::TumReplayOptions tum;
  app.add_option("--profile", profile_name, "device profile name or TOML path");
  app.add_option("--db", db_path, "map database")->required();
  app.add_option("--frames", frames_path, "replay a recorded frames file");
  app.add_flag("--stdin", use_stdin, "read the live line protocol from stdin");
  app.add_option("--udp", udp_port, "read the live line protocol from 127.0.0.1:PORT (0 = any)");
  app.add_option("--tum", tum_dir,
                 "replay a TUM RGB-D folder (rgb.txt + depth.txt, or associations.txt) as image "
                 "frames, as fast as the loop ticks");
  app.add_option("--images", images_mode,
                 "image lines on --stdin/--udp: auto (when the map has a vocabulary), on or off")
      ->capture_default_str();
  app.add_option("--image-size", image_size,
                 "WxH of the image lines' images (default: the map camera's; a plain scale of it)");
  app.add_option("--out", out, "run directory (ticks.jsonl, estimate.tum, summary.json)")->required();
  app.add_option("--policy", policy, "override the profile's policy");
  zm::app::AddParamOption(app, zm::kMemoryThrParam, &memory_thr);
  app.add_option("--max-ticks", max_ticks, "stop after this many ticks");
  zm::app::AddParamOption(app, zm::kMaxFeaturesParam, &max_features);
  app.add_flag("--no-hello", no_hello, "do not write the hello line first");
  CLI::Option_group* tum_group = app.add_option_group("TUM replay", "with --tum");
  tum_group->add_option("--odom", tum.odom_path,
                        "odometry: a TUM trajectory of the colour camera (default: none, each "
                        "frame predicted at the previous estimate)");
  tum_group
      ->add_option("--odom-max-dt", tum.max_odom_difference_s,
                   "frame-odometry association tolerance, seconds")
      ->capture_default_str();
  tum_group
      ->add_option("--max-dt", tum.folder.max_stamp_difference_s,
                   "colour-depth association tolerance, seconds")
      ->capture_default_str();
  tum_group->add_option("--fx", tum.folder.camera.fx, "focal length x, pixels (freiburg1)")
      ->capture_default_str();
  tum_group->add_option("--fy", tum.folder.camera.fy, "focal length y, pixels")
      ->capture_default_str();
  tum_group->add_option("--cx", tum.folder.camera.cx, "principal point x, pixels")
      ->capture_default_str();
  tum_group->add_option("--cy", tum.folder.camera.cy, "principal point y, pixels")
      ->capture_default_str();
  tum_group->add_option("--width", tum.folder.camera.width, "image width, pixels")
      ->capture_default_str();
  tum_group->add_option("--height", tum.folder.camera.height, "image height, pixels")
      ->capture_default_str();
  app.add_option("--sqlite-heap", sqlite_heap,
                 "SQLite's fixed heap, reserved at start (0 = SQLite's default: malloc)");
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
  // A robot that closes its end of the pipe must not kill the map process: the write fails
  // (EPIPE), is counted, and zonemapd keeps localizing until its input ends.
  std::signal(SIGPIPE, SIG_IGN);

  const int inputs = (use_stdin ? 1 : 0) + (udp_port >= 0 ? 1 : 0) + (frames_path.empty() ? 0 : 1) +
                     (tum_dir.empty() ? 0 : 1);
  if (inputs != 1) {
    return Fail("give exactly one input: --stdin, --udp PORT, --frames FILE or --tum DIR");
  }
  if (udp_port > 65535) return Fail("--udp port " + std::to_string(udp_port) + " is above 65535");
  if (tum_dir.empty()) {
    for (const char* o : {"--odom", "--odom-max-dt", "--max-dt", "--fx", "--fy", "--cx", "--cy",
                          "--width", "--height"}) {
      if (app.count(o) > 0) return Fail(std::string(o) + " is an option of --tum DIR");
    }
  }
  const bool live = use_stdin || udp_port >= 0;
  zm::DaemonOptions options;
  if (images_mode == "auto") {
    options.images = zm::DaemonImages::kAuto;
  } else if (images_mode == "on") {
    options.images = zm::DaemonImages::kOn;
  } else if (images_mode == "off") {
    options.images = zm::DaemonImages::kOff;
  } else {
    return Fail("--images " + images_mode + ": expected auto, on or off");
  }
  if (!live && (app.count("--images") > 0 || !image_size.empty())) {
    return Fail(
        "--images and --image-size are options of --stdin and --udp (a recording says "
        "what its images are)");
  }
  if (!image_size.empty()) {
    unsigned w = 0, h = 0;
    char end = 0;
    if (std::sscanf(image_size.c_str(), "%ux%u%c", &w, &h, &end) != 2 || w == 0 || h == 0) {
      return Fail("--image-size " + image_size + ": expected WxH, e.g. 320x240");
    }
    options.image_width = w;
    options.image_height = h;
  }
  // SQLite's memory from one reservation made now: no malloc inside SQLite in any warm tick
  // (lib/runtime/sqlite_heap.h). Declared before the database, so it outlives it.
  std::unique_ptr<zm::SqliteHeap> heap;
  if (sqlite_heap != "0") {
    auto bytes = zm::ParseBytes(sqlite_heap);
    if (!bytes.ok()) return Fail("--sqlite-heap: " + bytes.status().message());
    auto h = zm::SqliteHeap::Install(bytes.value());
    if (!h.ok()) return Fail(h.status().message());
    heap = std::move(h).value();
  }
  auto db = zm::MapDb::Open(db_path);
  if (!db.ok()) return Fail(db.status().message());

  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) return Fail("cannot create run directory '" + out + "': " + ec.message());
  zm::DaemonInput input;
  std::unique_ptr<zm::TumReplay> tum_replay;
  if (!frames_path.empty()) {
    input.kind = zm::DaemonInput::Kind::kReplay;
    input.frames_path = frames_path;
  } else if (!tum_dir.empty()) {
    // Without odometry the replay starts where the map's recording did: its first keyframe.
    auto keyframes = db.value()->Keyframes();
    if (!keyframes.ok()) return Fail(keyframes.status().message());
    if (!keyframes->empty()) tum.start = keyframes->front().pose;
    auto r = zm::TumReplay::Open(tum_dir, tum, db.value()->metadata().camera);
    if (!r.ok()) return Fail(r.status().message());
    tum_replay = std::move(r).value();
    const zm::TumFolder& f = tum_replay->folder();
    const std::string odometry =
        tum.odom_path.empty()
            ? "none (each frame predicted at the previous estimate)"
            : tum.odom_path + " (" + std::to_string(tum_replay->odometry_poses()) + " poses)";
    std::fprintf(stderr,
                 "zonemapd: --tum %s (%s): %zu frames, %u with depth, %u gaps, %u malformed lines; "
                 "odometry %s\n",
                 tum_dir.c_str(), f.listing.c_str(), tum_replay->frame_count(),
                 static_cast<unsigned>(f.frames.size()), f.gaps, f.malformed_lines,
                 odometry.c_str());
    for (const std::string& p : tum_replay->listing_problems()) {
      std::fprintf(stderr, "zonemapd: --tum %s: %s\n", tum_dir.c_str(), p.c_str());
    }
    input.kind = zm::DaemonInput::Kind::kCameraFiles;
    input.camera_files = tum_replay.get();
  } else if (use_stdin) {
    input.kind = zm::DaemonInput::Kind::kFd;
    input.fd = 0;
  } else {
    input.kind = zm::DaemonInput::Kind::kUdp;
    input.udp_port = static_cast<std::uint16_t>(udp_port);
  }
  options.max_features = max_features;
  options.telemetry_path = out + "/ticks.jsonl";
  options.estimate_path = out + "/estimate.tum";
  auto daemon = zm::Daemon::Create(profile.value(), *db.value(), input, options);
  if (!daemon.ok()) return Fail(daemon.status().message());
  zm::Daemon& d = *daemon.value();
  if (input.kind == zm::DaemonInput::Kind::kUdp) {
    std::fprintf(stderr, "zonemapd: listening on 127.0.0.1:%u\n", d.udp_port());
  }
  if (!no_hello) d.Hello();

  bool interrupted = false;
  for (;;) {
    if (zm::StopRequested()) {
      interrupted = true;
      break;
    }
    auto more = d.Step();
    if (!more.ok()) return Fail(more.status().message());
    if (!more.value()) {
      interrupted = zm::StopRequested();
      break;
    }
  }
  d.Flush();
  nlohmann::json s = d.Summary(interrupted);
  s["profile"] = profile->source;
  std::ofstream(out + "/summary.json") << s.dump(2) << '\n';
  const zm::TickLoop& loop = d.loop();
  std::fprintf(stderr,
               "zonemapd: %llu ticks, %llu input lines refused, %llu image frames on odometry, "
               "peak resident %u, K_max %u, %llu loop closures accepted\n",
               static_cast<unsigned long long>(loop.totals().ticks),
               static_cast<unsigned long long>(d.rejects().total),
               static_cast<unsigned long long>(d.image_refusals().total),
               loop.totals().peak_resident_keyframes, loop.k_max(),
               static_cast<unsigned long long>(loop.totals().closures_accepted));
  return 0;
}
