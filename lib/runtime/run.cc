#include "runtime/run.h"

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

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double rank = std::ceil(p / 100.0 * static_cast<double>(values.size()));
  const std::size_t i = static_cast<std::size_t>(std::clamp(rank, 1.0, static_cast<double>(values.size()))) - 1;
  return values[i];
}

nlohmann::json LoopSummary(const TickLoop& loop, double frame_rate_hz, bool interrupted) {
  const LoopTotals& t = loop.totals();
  nlohmann::json s;
  s["policy"] = loop.config().policy.policy;
  s["k_max"] = loop.k_max();
  s["slot_bytes"] = loop.slot_bytes();
  s["arena_slots"] = loop.arena().capacity();
  s["arena_bytes_reserved"] = loop.arena().stats().bytes_reserved;
  s["ticks"] = t.ticks;
  s["interrupted"] = interrupted;
  s["update_rate_hz"] = t.simulated_s > 0 ? static_cast<double>(t.ticks) / t.simulated_s : 0.0;
  s["frame_rate_hz"] = frame_rate_hz;
  const std::vector<double>& ms = loop.tick_ms();
  const double mean = ms.empty() ? 0.0 : std::accumulate(ms.begin(), ms.end(), 0.0) / static_cast<double>(ms.size());
  s["tick_ms"] = {{"mean", mean},
                  {"p50", Percentile(ms, 50)},
                  {"p99", Percentile(ms, 99)},
                  {"max", ms.empty() ? 0.0 : *std::max_element(ms.begin(), ms.end())}};
  s["loop_closures"] = t.loop_closures;
  s["closures_rejected"] = t.closures_rejected;
  s["peak_resident_keyframes"] = t.peak_resident_keyframes;
  s["peak_resident_bytes"] = t.peak_resident_bytes;
  s["over_budget_ticks"] = t.over_budget_ticks;
  s["max_over_budget_keyframes"] = t.max_over_budget_keyframes;
  s["longest_over_budget_run_ticks"] = t.longest_over_budget_run;
  s["alloc_failures"] = loop.arena().stats().refused;
  s["stalled_ticks"] = t.stalled_ticks;
  s["step_errors"] = t.step_errors;
  if (!t.first_error.empty()) s["first_error"] = t.first_error;
  s["keyframes_loaded"] = t.keyframes_loaded;
  s["keyframes_unloaded"] = t.keyframes_unloaded;
  s["zone_loads"] = t.zone_loads;
  s["db_transactions"] = t.db_transactions;
  s["db_queries"] = t.db_queries;
  s["search_queries"] = t.search_queries;
  s["db_bytes_read"] = t.db_bytes_read;
  s["load_ms_total"] = t.load_ms;
  s["unload_ms_total"] = t.unload_ms;
  s["malformed_lines"] = loop.malformed_lines();

  return s;
}

Result<nlohmann::json> RunScenario(const RunRequest& request, const std::atomic<bool>* stop) {
  ZM_ASSIGN_OR_RETURN(sim::ScenarioInfo scenario, sim::LoadScenario(request.scenario_dir));
  std::error_code ec;
  std::filesystem::create_directories(request.out_dir, ec);
  if (ec) return IoError("cannot create run directory '" + request.out_dir + "': " + ec.message());

  ZM_ASSIGN_OR_RETURN(std::unique_ptr<MapDb> db,
                      MapDb::Open(scenario.map_db, {.verify_checksums = request.loop.verify_checksums}));
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
  config.expected_ticks = scenario.frames;
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<TickLoop> loop,
                      TickLoop::Create(config, *db, *frames, &telemetry, route, future,
                                       scenario.rate_hz));
  ZM_RETURN_IF_ERROR(loop->Start());
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
    if (request.on_tick) request.on_tick(*loop);
    if (request.pace_speedup > 0) {
      const double stamp = loop->last_record().stamp_s;
      if (stamp0 < 0) stamp0 = stamp;
      std::this_thread::sleep_until(
          wall0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                      std::chrono::duration<double>((stamp - stamp0) / request.pace_speedup)));
    }
  }
  telemetry.Flush();
  telemetry.Close();

  // Trajectory metrics: the estimate lives in the map frame, so ATE unaligned, and SE(3)-aligned
  // beside it (docs/evaluation.md).
  const LoopTotals& t = loop->totals();
  ZM_RETURN_IF_ERROR(WriteTrajectory(request.out_dir + "/estimate.tum", loop->estimate(),
                                     TrajectoryFormat::kTum));
  nlohmann::json s = LoopSummary(*loop, scenario.rate_hz, interrupted);
  s["profile"] = request.profile_name;
  s["scenario"] = scenario.dir;
  s["pace_speedup"] = request.pace_speedup;
  s["ate_rmse_m"] = nullptr;
  s["ate_se3_rmse_m"] = nullptr;
  s["rpe_trans_rmse_m"] = nullptr;
  s["rpe_rot_rmse_deg"] = nullptr;
  if (!scenario.localization_gt.empty() && t.ticks > 2) {
    ZM_ASSIGN_OR_RETURN(Trajectory gt, ReadTrajectory(scenario.localization_gt, TrajectoryFormat::kTum));
    auto none = Evaluate(gt, loop->estimate(), {.align = AlignMode::kNone});
    auto se3 = Evaluate(gt, loop->estimate(), {.align = AlignMode::kSe3});
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
