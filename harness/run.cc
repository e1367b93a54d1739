#include "harness/run.h"

#include "runtime/summary.h"

#include <algorithm>
#include <chrono>
#include <thread>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numeric>

#include "geometry/metrics.h"
#include "geometry/trajectory.h"
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
  TelemetryWriter telemetry;
  ZM_RETURN_IF_ERROR(telemetry.Open(request.out_dir + "/ticks.jsonl"));

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
      for (std::uint64_t f = v.first_frame; f <= v.last_frame && f < future.size(); ++f) future[f] = id;
    }
  }

  LoopConfig config = request.loop;
  config.loop.rate_hz = scenario.rate_hz;  // the recorded frames' own rate
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<TickLoop> loop,
                      TickLoop::Create(config, *db, *frames,
                                       {.route = std::move(route), .oracle_future = std::move(future)}));
  // The estimate: one pose per processed frame (a replay is finite: reserved for all of them).
  Trajectory estimate;
  estimate.stamps_s.reserve(scenario.frames);
  estimate.poses.reserve(scenario.frames);
  bool interrupted = false;
  const auto wall0 = std::chrono::steady_clock::now();
  double stamp0 = -1.0;
  for (;;) {
    if (stop != nullptr && stop->load()) {
      interrupted = true;
      break;
    }
    ZM_ASSIGN_OR_RETURN(bool more, loop->Tick());
    if (!more) break;
    const TickRecord& rec = loop->last_record();
    estimate.stamps_s.push_back(rec.stamp_s);
    estimate.poses.push_back(rec.pose);
    const std::string_view extra = request.on_tick ? request.on_tick(*loop) : std::string_view();
    telemetry.Write(rec, extra);
    if (request.telemetry.flush_ticks != 0 && (rec.tick + 1) % request.telemetry.flush_ticks == 0) {
      telemetry.Flush();
    }
    // The idle part of the tick (time-sliced loads): until the next frame is due on the
    // frames' clock (the frame period after this tick started), or on the paced clock.
    if (request.pace_speedup > 0) {
      const double stamp = loop->last_record().stamp_s;
      if (stamp0 < 0) stamp0 = stamp;
      const auto at = [&](double s) {
        return wall0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                           std::chrono::duration<double>((s - stamp0) / request.pace_speedup));
      };
      // This pacing starts the next tick at the paced time of this frame's stamp (one frame
      // period after this tick was due): that is when the next frame is due.
      (void)loop->Idle(at(stamp));
      std::this_thread::sleep_until(at(stamp));
    } else {
      (void)loop->Idle();
    }
  }
  telemetry.Flush();
  telemetry.Close();

  // Trajectory metrics: the estimate lives in the map frame, so ATE unaligned, and SE(3)-aligned
  // beside it (docs/evaluation.md).
  const LoopTotals& t = loop->totals();
  ZM_RETURN_IF_ERROR(WriteTrajectory(request.out_dir + "/estimate.tum", estimate,
                                     TrajectoryFormat::kTum));
  nlohmann::json s = LoopSummary(*loop, interrupted);
  s["profile"] = request.profile_name;
  s["scenario"] = scenario.dir;
  s["pace_speedup"] = request.pace_speedup;
  s["ate_rmse_m"] = nullptr;
  s["ate_se3_rmse_m"] = nullptr;
  s["rpe_trans_rmse_m"] = nullptr;
  s["rpe_rot_rmse_deg"] = nullptr;
  if (!scenario.localization_gt.empty() && t.ticks > 2) {
    ZM_ASSIGN_OR_RETURN(Trajectory gt, ReadTrajectory(scenario.localization_gt, TrajectoryFormat::kTum));
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
