// A killed map process's summary, rebuilt from what it had written: the budget it started with
// (map_start.json) and its ticks (ticks.jsonl, up to the last whole line), through the same
// derivations as a finished run's (TickMsSummaryOf, StageSummaryOf, TimeTotalOf).
#include <algorithm>
#include <cstdint>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "geometry/metrics.h"
#include "geometry/trajectory.h"
#include "harness/device_run.h"
#include "runtime/streaming_stats.h"
#include "runtime/summary.h"
#include "sim/scenario.h"

namespace zm {

Result<RunSummary> SummarizePartialRun(const std::string& scenario_dir, const std::string& out_dir,
                                       double time_compression) {
  // The budget and the arena, as the map process saw them when its loop was built.
  RunSummary s;
  if (std::ifstream in(out_dir + "/map_start.json"); in) {
    const nlohmann::json start = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (auto read = RunSummaryFromJson(start); read.ok()) s = std::move(read).value();
  }
  StreamingStats tick_ms;
  // The stages' times of the same ticks (28 KB each: on the heap, not this stack).
  std::vector<StreamingStats> stage_ms(kLoopStageCount);
  std::uint64_t ticks = 0, localized = 0, loaded = 0, unloaded = 0, over = 0, bytes_read = 0;
  std::uint64_t images_refused = 0;
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
        const nlohmann::json stages = t.value("stages_ms", nlohmann::json::object());
        for (int i = 0; i < kLoopStageCount; ++i) {
          stage_ms[static_cast<std::size_t>(i)].Add(
              stages.value(LoopStageName(static_cast<LoopStage>(i)), 0.0));
        }
      }
      idle_load_ms += t.value("idle_load_ms", 0.0);
      if (t.value("loop_closure", false)) ++localized;
      if (t.value("image_refused", false)) ++images_refused;
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
  s.partial = true;
  s.ticks = ticks;
  // A tick's record says whether a closure was accepted on it, and the localizer accepts at
  // most one a frame: both counts are the frames localized.
  s.frames_localized = localized;
  s.closures_accepted = localized;
  s.images_refused = images_refused;
  s.keyframes_loaded = loaded;
  s.keyframes_unloaded = unloaded;
  s.over_budget_ticks = over;
  s.db_bytes_read = bytes_read;
  s.db_transactions = tx;
  s.db_queries = q;
  s.peak_resident_keyframes = peak_kf;
  s.peak_resident_bytes = peak_bytes;
  s.tick_ms = TickMsSummaryOf(tick_ms);
  for (std::size_t i = 0; i < s.stages.size(); ++i) s.stages[i] = StageSummaryOf(stage_ms[i]);
  s.time_total_ms = TimeTotalOf({.steady_mean_ms = tick_ms.mean(),
                                 .steady_ticks = tick_ms.count(),
                                 .has_startup = has_startup,
                                 .startup_tick_ms = startup_tick_ms,
                                 .late_ms = late_ms,
                                 .idle_load_ms = idle_load_ms});
  if (has_startup) s.startup.tick_ms = startup_tick_ms;
  s.update_rate_hz.reset();
  if (time_compression > 0 && wall_s > 0) {
    s.update_rate_hz = static_cast<double>(ticks) / (wall_s * time_compression);
  }
  ReplaySummary& r = s.replay.emplace();
  r.time_compression = time_compression;
  r.realtime_frames = time_compression > 0;
  r.frames_dropped = dropped;
  r.frames_arrived = arrived;
  r.wall_s = wall_s;
  auto scenario = sim::LoadScenario(scenario_dir);
  if (scenario.ok()) r.scenario = scenario->dir;
  auto est = ReadTrajectory(out_dir + "/estimate.tum", TrajectoryFormat::kTum);
  if (scenario.ok() && !scenario->localization_gt.empty() && est.ok() && est->poses.size() > 2) {
    auto gt = ReadTrajectory(scenario->localization_gt, TrajectoryFormat::kTum);
    if (gt.ok()) r.trajectory = EvaluateEstimate(*gt, *est);
  }
  return s;
}

}  // namespace zm
