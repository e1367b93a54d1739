// summary.json: the run's totals, one typed and versioned struct (RunSummary) with one JSON codec
// (ToJson / RunSummaryFromJson). zonemapd writes it at exit; a replay (harness/run.h) fills its
// replay part (frames, wall clock, trajectory metrics); the evaluation's device run
// (harness/device_run.h) wraps it with the device, the map process and the co-tenant. Every
// reader (`zonemap run`, `zonemap bench`, the public API's stats, a killed run's rebuilt summary)
// reads the struct, not keys; JSON exists only in the codec. The keys and `schema_version` are
// documented in docs/runtime.md ("summary.json").
#pragma once

#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "arena/frame_scratch.h"
#include "common/status.h"
#include "runtime/tick_loop.h"

namespace zm {

// summary.json's `schema_version`. Raise it when a key changes meaning or goes away (adding a key
// does not); RunSummaryFromJson refuses a newer version than this build knows and reads the older
// ones. 2: `loop_closures` became `closures_accepted` beside `frames_localized` (a version-1 file's
// loop_closures is read as both: it counted the frames whose closure was accepted, one at most
// each); `stages`, `images_refused`, `first_image_error`, `frame_scratch` and the budget's
// `vocabulary_bytes`, `index_bytes`, `frame_scratch_bytes` were added.
inline constexpr int kSummarySchemaVersion = 2;

// Steady-state tick times (the first, start-up tick is reported apart in `startup`).
struct TickMsSummary {
  double mean = 0.0;
  double p50 = 0.0;
  double p99 = 0.0;
  double max = 0.0;
  std::uint64_t count = 0;
};

// One stage's time per steady-state tick (LoopStage: features, quantize, likelihood, verify,
// memory; telemetry.h), from the same ticks as tick_ms.
struct StageSummary {
  double p50_ms = 0.0;
  double p99_ms = 0.0;
  double mean_ms = 0.0;
};

// A StreamingStats of tick or stage times as summary.json states it: the one derivation for a
// loop's totals (LoopSummary) and for a run rebuilt from its ticks.jsonl (harness/device_run.cc).
[[nodiscard]] TickMsSummary TickMsSummaryOf(const StreamingStats& ms);
[[nodiscard]] StageSummary StageSummaryOf(const StreamingStats& ms);

// The paper's TimeTotal (RTAB-Map's per-frame processing time) four ways, summary.json's
// "time_total_ms" (issue 27 §4), from what a run counted:
//   steady             mean tick_ms over the ticks after the start-up tick (= tick_ms.mean: the
//                      tick's steps plus any wait on the idle part before it, late_ms)
//   with_startup       the same mean with the start-up tick (the start-up load) counted in
//   without_idle_loads steady less the waits on idle-time loads (late_ms): the steps alone
//   with_idle_loads    the steps plus all the idle-time loads' wall time (idle_load_ms) spread
//                      over the steady ticks: what the map spent per frame had every load run
//                      inside a tick, as RTAB-Map's do
// The one derivation: LoopSummary and the summary of a killed run (harness/device_run.cc) both
// call TimeTotalOf.
struct TimeTotalInputs {
  double steady_mean_ms = 0.0;
  std::uint64_t steady_ticks = 0;
  bool has_startup = false;
  double startup_tick_ms = 0.0;
  double late_ms = 0.0;       // summed over the steady ticks
  double idle_load_ms = 0.0;  // summed over the run's idle parts that had loads queued
};
struct TimeTotal {
  double steady = 0.0;
  double with_startup = 0.0;
  double without_idle_loads = 0.0;
  double with_idle_loads = 0.0;
};
[[nodiscard]] TimeTotal TimeTotalOf(const TimeTotalInputs& in);

// The first tick's start-up load (tick_loop.h's StartupTotals).
struct StartupSummary {
  double tick_ms = 0.0;
  double load_ms = 0.0;
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t bytes_read = 0;
  std::uint64_t db_transactions = 0;
  std::uint64_t db_queries = 0;
  std::uint64_t db_blob_reads = 0;
};

// Database work after the start-up load (SteadyDbWork).
struct SteadyStateSummary {
  std::uint64_t db_queries = 0;
  std::uint64_t db_transactions = 0;
  std::uint64_t db_blob_reads = 0;
  std::uint64_t db_bytes_read = 0;
};

// Time-sliced loads: the options in force and what the idle parts did.
struct LoadsSummary {
  bool sliced = true;
  double tick_ms = 0.0;
  std::uint64_t tick_bytes = 0;
  double idle_ms = 0.0;
  std::uint64_t idle_bytes = 0;
  double margin_ms = 0.0;
  double idle_load_ms_total = 0.0;
  std::uint64_t idle_keyframes_loaded = 0;
  std::uint64_t keyframes_cancelled = 0;
  std::uint64_t loads_preempted = 0;
  std::uint64_t max_pending_keyframes = 0;
  std::uint64_t late_ticks = 0;
  double max_late_ms = 0.0;
  double late_ms_total = 0.0;
};

// Trajectory metrics of the estimate against the scenario's ground truth (docs/evaluation.md):
// unaligned (the estimate lives in the map frame) and SE(3)-aligned. Null when not measured.
struct TrajectorySummary {
  std::optional<double> ate_rmse_m;
  std::optional<double> ate_se3_rmse_m;
  std::optional<double> rpe_trans_rmse_m;
  std::optional<double> rpe_rot_rmse_deg;
  std::optional<std::uint64_t> associated_poses;  // omitted when not measured
};

// What a replay of a recorded scenario adds (harness/run.h): where it came from, the frames'
// clock and the trajectory metrics.
struct ReplaySummary {
  std::string profile;
  std::string scenario;
  double time_compression = 0.0;
  bool realtime_frames = false;
  std::uint64_t frames_arrived = 0;
  std::uint64_t frames_dropped = 0;
  std::uint64_t frames_not_taken = 0;
  std::uint64_t frames_refused = 0;  // by the input gate (runtime/input_gate.h)
  double wall_s = 0.0;
  double wall_origin_mono_s = 0.0;
  // Real-time frames: the loop's own model of the rate (update_rate_hz is then what the robot
  // got: frames processed per second of the frames' clock). Omitted otherwise.
  std::optional<double> update_rate_model_hz;
  TrajectorySummary trajectory;
};

struct RunSummary {
  int schema_version = kSummarySchemaVersion;
  std::string policy;
  std::uint64_t k_max = 0;
  std::uint64_t slot_bytes = 0;
  std::uint64_t arena_slots = 0;
  std::uint64_t arena_bytes_reserved = 0;
  bool arena_locked = false;
  std::uint64_t map_share_bytes = 0;
  // Localization's memory the budget counted beside the slots (Budget; 0 where none).
  std::uint64_t vocabulary_bytes = 0;
  std::uint64_t index_bytes = 0;
  std::uint64_t frame_scratch_bytes = 0;
  std::uint64_t ticks = 0;
  bool interrupted = false;
  std::optional<double> update_rate_hz;  // null: not measured (a killed unpaced run)
  double frame_rate_hz = 0.0;
  TickMsSummary tick_ms;
  TimeTotal time_total_ms;
  StartupSummary startup;
  SteadyStateSummary steady_state;
  // Per stage, by LoopStage (summary.json `stages`, keyed by LoopStageName).
  std::array<StageSummary, kLoopStageCount> stages{};
  // Loop closures accepted and frames localized (LoopTotals: the same count today), closures
  // rejected; camera frames whose image the front-end refused (the tick ran on odometry).
  std::uint64_t closures_accepted = 0;
  std::uint64_t frames_localized = 0;
  std::uint64_t closures_rejected = 0;
  std::uint64_t images_refused = 0;
  std::optional<std::string> first_image_error;  // omitted when none was refused
  // The front-end's frame scratch at the end of the run (FrameScratchStats: how much of the
  // region a frame used, requests the heap served, blocks that kept it from resetting); omitted
  // without a front-end.
  std::optional<FrameScratchStats> frame_scratch;
  std::uint64_t peak_resident_keyframes = 0;
  std::uint64_t peak_resident_bytes = 0;
  std::uint64_t over_budget_ticks = 0;
  std::uint64_t max_over_budget_keyframes = 0;
  std::uint64_t longest_over_budget_run_ticks = 0;
  std::uint64_t alloc_failures = 0;
  std::uint64_t stalled_ticks = 0;
  std::uint64_t step_errors = 0;
  std::optional<std::string> first_error;  // omitted when no step failed
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t keyframes_unloaded = 0;
  std::uint64_t zone_loads = 0;
  std::uint64_t db_transactions = 0;
  std::uint64_t db_queries = 0;
  std::uint64_t db_blob_reads = 0;
  std::uint64_t search_queries = 0;
  std::uint64_t search_transactions = 0;
  std::uint64_t db_bytes_read = 0;
  double load_ms_total = 0.0;
  double unload_ms_total = 0.0;
  LoadsSummary loads;
  std::uint64_t malformed_lines = 0;
  // A replay's part (harness/run.h); absent for zonemapd's live sessions.
  std::optional<ReplaySummary> replay;
  // The evaluation's map process: its refused ledger grants (device ledger only), and whether
  // the metrics were rebuilt from the ticks of a process that did not finish. Omitted otherwise.
  std::optional<std::uint64_t> ledger_refusals;
  bool partial = false;
};

// The typed totals of a loop (everything but a replay's part). Allocates (the policy name); call
// it once at the end of a run (or once when the loop is built), never per tick.
[[nodiscard]] RunSummary LoopSummary(const TickLoop& loop, bool interrupted);

// The codec. ToJson writes every key (null where an optional member is empty and the key is
// always present: update_rate_hz and the trajectory metrics; omitted for the others).
// RunSummaryFromJson reads what ToJson writes; a key missing in an older file keeps its default;
// a wrong type or a newer schema_version is an error naming the key.
[[nodiscard]] nlohmann::json ToJson(const RunSummary& summary);
[[nodiscard]] Result<RunSummary> RunSummaryFromJson(const nlohmann::json& json);

}  // namespace zm
