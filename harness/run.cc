#include "harness/run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numeric>

#include "geometry/metrics.h"
#include "geometry/trajectory.h"
#include "harness/cotenant.h"
#include "harness/realtime_frames.h"
#include "runtime/tick_publisher.h"
#include "runtime/input_gate.h"
#include "runtime/summary.h"
#include "sim/scenario.h"

namespace zm {
namespace {

// Zone ids of the database by name; a zone split at annotation ("Ward3" -> "Ward3/1", ...) is
// found by its first part.
ZoneId FindZone(const ZoneSet& zones, const std::string& name) {
  ZoneId prefix_match = kNoZone;
  for (const Zone& z : zones.zones()) {
    if (z.name == name) return z.id;
    if (prefix_match == kNoZone && z.name.rfind(name + "/", 0) == 0) prefix_match = z.id;
  }
  return prefix_match;
}

}  // namespace

Result<nlohmann::json> RunScenario(const RunRequest& request, const std::atomic<bool>* stop) {
  ZM_ASSIGN_OR_RETURN(sim::ScenarioInfo scenario, sim::LoadScenario(request.scenario_dir));
  std::error_code ec;
  std::filesystem::create_directories(request.out_dir, ec);
  if (ec) return IoError("cannot create run directory '" + request.out_dir + "': " + ec.message());

  ZM_ASSIGN_OR_RETURN(std::unique_ptr<MapDb> db,
                      MapDb::Open(scenario.map_db, {.verify_checksums = request.verify_checksums}));
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<FrameSource> frames, OpenReplaySource(scenario.frames_bin));

  // Planned route (predictive) and the per-tick future (oracle), from the patrol's tasks.
  std::vector<ZoneId> route;
  std::vector<ZoneId> future;
  ZM_ASSIGN_OR_RETURN(std::vector<ZoneRecord> zone_records, db->Zones());
  ZM_ASSIGN_OR_RETURN(std::vector<ZoneMember> members, db->ZoneMembers());
  ZM_ASSIGN_OR_RETURN(ZoneSet zone_set, ZoneSetFromRecords(zone_records, members));
  if (!scenario.route_json.empty() && std::filesystem::exists(scenario.route_json)) {
    ZM_ASSIGN_OR_RETURN(sim::Route r, sim::LoadRoute(scenario.route_json));
    future.assign(scenario.frames, kNoZone);
    for (const sim::RouteVisit& v : r.zones) {
      const ZoneId id = FindZone(zone_set, v.zone);
      if (id == kNoZone) continue;
      if (route.empty() || route.back() != id) route.push_back(id);
      for (std::uint64_t f = v.first_frame; f <= v.last_frame && f < future.size(); ++f)
        future[f] = id;
    }
  }

  LoopConfig config = request.loop;
  const bool realtime = request.time_compression > 0.0;
  // Real-time frames come at the profile's rate (RTAB-Map's detection rate); an unpaced replay
  // takes every recorded frame, at the recording's own rate.
  if (!realtime) config.loop.rate_hz = scenario.rate_hz;
  std::unique_ptr<RealtimeFrameSource> rt;
  FrameSource* source = frames.get();
  if (realtime) {
    ZM_ASSIGN_OR_RETURN(
        rt, RealtimeFrameSource::Create(*frames, {.rate_hz = config.loop.rate_hz,
                                                  .time_compression = request.time_compression}));
    source = rt.get();
  }
  // The input gate in front of the loop, as in zonemapd (input_gate.h): a recorded frame that
  // breaks a rule is counted and skipped.
  GatedFrameSource gated(*source);
  ZM_ASSIGN_OR_RETURN(
      std::unique_ptr<TickLoop> loop,
      TickLoop::Create(config, *db, gated,
                       {.route = std::move(route), .oracle_future = std::move(future)}));
  gated.Attach(request.input, ExtentOf(loop->map_index()), &loop->map_from_odom());
  // Each tick's record to ticks.jsonl and estimate.tum (streamed: a process killed mid-run
  // leaves the poses it produced), as zonemapd publishes it (tick_publisher.h).
  TickPublisher publisher;
  ZM_RETURN_IF_ERROR(publisher.Open(
      {.telemetry_path = request.out_dir + "/ticks.jsonl",
       .estimate_path = request.out_dir + "/estimate.tum",
       .flush_ticks = std::max<std::uint32_t>(1, request.telemetry.flush_ticks)}));
  // The estimate: one pose per processed frame (a replay is finite: reserved for all of them).
  Trajectory estimate;
  estimate.stamps_s.reserve(scenario.frames);
  estimate.poses.reserve(scenario.frames);
  bool interrupted = false;
  double origin = MonotonicSeconds();
  if (request.on_ready) {
    ZM_ASSIGN_OR_RETURN(origin, request.on_ready(*loop));
  }
  if (rt) rt->set_origin_mono_s(origin);
  for (;;) {
    if (stop != nullptr && stop->load()) {
      interrupted = true;
      break;
    }
    if (rt) {
      // Wait for the next frame outside the tick: a robot's loop sleeps there too.
      ZM_RETURN_IF_ERROR(rt->WaitForFrame());
      if (!rt->FrameWaiting()) {
        ZM_ASSIGN_OR_RETURN(double at, rt->NextArrival());
        if (std::isfinite(at)) continue;  // woken early (a signal): check the stop flag again
      }
    }
    ZM_ASSIGN_OR_RETURN(bool more, loop->Tick());
    if (!more) break;
    const TickRecord& rec = loop->last_record();
    estimate.stamps_s.push_back(rec.stamp_s);
    estimate.poses.push_back(rec.pose);
    TickClock clock;
    clock.wall_s = MonotonicSeconds() - origin;
    clock.frames_arrived = rt ? rt->frames_arrived() : rec.tick + 1;
    clock.frames_dropped = rt ? rt->frames_dropped() : 0;
    const std::string_view extra =
        request.on_tick ? request.on_tick(*loop, clock) : std::string_view();
    (void)publisher.Publish(rec, extra);
    // The idle part of the tick (time-sliced loads): until the next frame arrives (real-time
    // frames; it also stops as soon as one is waiting), else one frame period after this tick
    // started.
    if (rt) {
      ZM_ASSIGN_OR_RETURN(double at, rt->NextArrival());
      if (std::isfinite(at)) {
        (void)loop->Idle(std::chrono::steady_clock::time_point(
            std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                std::chrono::duration<double>(at))));
      }
    } else {
      (void)loop->Idle();
    }
  }
  const double wall_s = MonotonicSeconds() - origin;
  publisher.Close();

  // Trajectory metrics: the estimate lives in the map frame, so ATE unaligned, and SE(3)-aligned
  // beside it (docs/evaluation.md).
  const LoopTotals& t = loop->totals();
  nlohmann::json s = LoopSummary(*loop, interrupted);
  s["profile"] = request.profile_name;
  s["scenario"] = scenario.dir;
  // Frames: real time or not, stated in every summary (issue 17 §4).
  s["time_compression"] = request.time_compression;
  s["realtime_frames"] = realtime;
  s["frames_arrived"] = rt ? rt->frames_arrived() : t.ticks;
  s["frames_dropped"] = rt ? rt->frames_dropped() : 0;
  s["frames_not_taken"] = rt ? rt->frames_not_taken() : 0;
  s["frames_refused"] = gated.rejects().total;  // by the input gate
  s["wall_s"] = wall_s;
  s["wall_origin_mono_s"] = origin;
  if (realtime) {
    // What the robot got: frames processed per second of the frames' clock.
    s["update_rate_model_hz"] = s["update_rate_hz"];
    const double frames_clock_s = wall_s * request.time_compression;
    s["update_rate_hz"] = frames_clock_s > 0 ? static_cast<double>(t.ticks) / frames_clock_s : 0.0;
  }
  s["ate_rmse_m"] = nullptr;
  s["ate_se3_rmse_m"] = nullptr;
  s["rpe_trans_rmse_m"] = nullptr;
  s["rpe_rot_rmse_deg"] = nullptr;
  if (!scenario.localization_gt.empty() && t.ticks > 2) {
    ZM_ASSIGN_OR_RETURN(Trajectory gt,
                        ReadTrajectory(scenario.localization_gt, TrajectoryFormat::kTum));
    auto none = Evaluate(gt, estimate, {.align = AlignMode::kNone});
    auto se3 = Evaluate(gt, estimate, {.align = AlignMode::kSe3});
    if (none.ok()) {
      s["ate_rmse_m"] = none->ape_trans_m.rmse;
      s["rpe_trans_rmse_m"] = none->rpe_trans_m.rmse;
      s["rpe_rot_rmse_deg"] = none->rpe_rot_deg.rmse;
      s["associated_poses"] = none->associated;
    }
    if (se3.ok()) s["ate_se3_rmse_m"] = se3->ape_trans_m.rmse;
  }

  std::ofstream out(request.out_dir + "/summary.json");
  out << s.dump(2) << '\n';
  if (!out) return IoError("cannot write '" + request.out_dir + "/summary.json'");
  return s;
}

}  // namespace zm
