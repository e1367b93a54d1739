// The tick loop: the single-threaded heart of zonemapd (and of every replay the evaluation runs).
//
// One tick, fixed order, a timer around each step (PX4's work-item shape):
//   1. read a frame                       FrameSource::Next
//   2. update the pose                    T_map_odom (correction) * odometry
//   3. look up the zone                   ZoneIndex::GetZone with hysteresis
//   4. the policy plans                   MemoryPolicy::PlanBeforeLocalize (unload, then load);
//                                         on the first frame MemoryPolicy::Start (start-up load)
//                                         (2-4's decisions: DecideStep::Before, decide_step.h,
//                                         the one decide step the public API drives too)
//   5. apply the plan                     WorkingSet::Apply: releases at once, loads queued;
//                                         then the in-tick slice (LoadSliceOptions::tick_ms,
//                                         tick_bytes) of the robot's own zone, nearest batch
//                                         first, so the zone just entered starts loading at once
//   6. localize on the resident set       Localizer::Localize over views of resident slots only
//                                         (complete keyframes; a zone still loading is used
//                                         keyframe by keyframe); then DecideStep::After + Apply
//                                         (basic's retrieval and transfer, as in RTAB-Map)
//   7. record                             fill the TickRecord and the totals
// and, between ticks, the idle part (Idle(), called by the driver after it has written the
// tick's outputs and before it waits for the next frame): the queued loads advance one keyframe
// at a time until the next frame is due (less a margin and the slowest recent keyframe's time),
// the per-tick idle budget (idle_ms, idle_bytes) is spent, or a frame is already waiting. One
// thread throughout: a load never runs beside a tick, it runs where the loop would sleep.
//
// The loop does no output of its own: the caller reads last_record() after each Tick() and
// writes whatever it writes (telemetry JSONL, the pose line to the robot, a trajectory file).
// Totals are typed (LoopTotals); JSON exists only at the edges.
//
// Start-up: the first frame's tick carries the policy's start-up load (semantic: the first zone;
// basic: its whole initial working memory), loaded to the end in that tick (a predictive
// prefetch is left to the idle part). It is reported apart (LoopTotals::startup) and kept out of
// the tick-time statistics, which describe the steady state.
//
// Tick time (TickRecord::tick_ms, LoopTotals::tick_ms): steps 1-7 of the tick, plus the time the
// idle part before it ran past this frame's due time (late_ms: the wait that frame would have
// had on a robot; 0 while the idle part keeps its deadline). The idle part itself is reported
// apart (idle_load_ms).
//
// Everything is built in Create(); a warm tick allocates nothing (tested, for every policy).
// Errors never unwind through the loop: each step returns a value, and a failed step marks the
// tick stalled and is counted. An accepted loop closure changes the pose correction from the
// NEXT tick. Statistics are fixed-size (StreamingStats): memory after a month equals memory
// after a minute.
//
// Time: the loop runs on the frames' own clock (stamps), so a replay is deterministic and
// basic's whole-second ages mean what they mean on a robot running at the frame rate. The idle
// part's deadline is the frame period at LoopOptions::rate_hz after this tick started (a replay
// gets the idle time a robot would have, however fast it replays), or the caller's own due time
// (a paced replay, a robot whose frames come on a known schedule). A replay stays deterministic
// as long as the idle part finishes its loads before the deadline, which it does with the
// shipped budgets on the maps measured (docs/memory.md); a tighter budget makes residency depend
// on the machine's speed, as it would on a robot.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "arena/arena.h"
#include "common/status.h"
#include "geometry/pose.h"
#include "localization/frame.h"
#include "localization/front_end.h"
#include "localization/localizer.h"
#include "mapdb/map_db.h"
#include "memory/ltm_graph.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/policy.h"
#include "memory/working_set.h"
#include "runtime/budget.h"
#include "runtime/decide_step.h"
#include "runtime/frame_source.h"
#include "runtime/streaming_stats.h"
#include "runtime/telemetry.h"
#include "zones/zone_index.h"
#include "zones/zone_set.h"

namespace zm {

// The loop's own options ([loop] in a profile).
struct LoopOptions {
  double rate_hz = 1.0;                 // frame rate the robot runs at (Rtabmap/DetectionRate)
  double small_displacement_m = 0.1;    // RGBD/LinearUpdate
  double small_displacement_rad = 0.1;  // RGBD/AngularUpdate
  std::uint64_t max_ticks = 0;          // 0 = until the source ends
};

// Everything the loop is built from: the modules' own options, filled once (profile.h).
struct LoopConfig {
  DeviceOptions device;
  ModelOptions model;
  MapOptions map;
  PolicyOptions policy;
  LoadSliceOptions loads;
  ZoneIndexOptions zones;
  LocalizerConfig localizer;
  // The front-end's extractor for camera frames: must be the options the map's keyframes were
  // extracted with (the simulator and the importers use these defaults).
  OrbOptions orb;
  LoopOptions loop;
};

// What only a replay knows in advance (the evaluation's planned route and oracle future).
struct LoopPlanInputs {
  std::vector<ZoneId> route;          // planned zone sequence (predictive); may be empty
  std::vector<ZoneId> oracle_future;  // the zone of every tick, from tick 0 (oracle only)
};

// Start-up, reported apart from the steady state: the policy's start-up load (basic: its whole
// initial working memory), which the first tick carries before it localizes. Database work in
// the one unit of LoadStats (statements, transactions, blob reads).
struct StartupTotals {
  double tick_ms = 0.0;               // the whole first tick
  double load_ms = 0.0;               // of which loading
  std::uint32_t keyframes_loaded = 0;
  std::uint64_t bytes_read = 0;
  std::uint32_t db_transactions = 0;
  std::uint32_t db_queries = 0;       // SQL statements executed
  std::uint32_t db_blob_reads = 0;
};

// Totals over a run, typed (summary writers turn them into JSON).
struct LoopTotals {
  std::uint64_t ticks = 0;
  // Localization as RTAB-Map reports it: loop closures accepted (the localizer's
  // LocalizeResult::closures_accepted, summed), beside the frames localized (ticks whose pose is
  // an accepted closure's fix). The same count today: the localizer stops at the first accepted
  // candidate, so a frame has at most one. closures_rejected: candidates examined, not accepted.
  std::uint64_t closures_accepted = 0;
  std::uint64_t frames_localized = 0;
  std::uint64_t closures_rejected = 0;
  // Camera frames whose image the front-end could not use (the tick ran on odometry), and the
  // first one's reason. Not the input gate's refusals (summary.json frames_refused): those
  // frames never reach the loop.
  std::uint64_t images_refused = 0;
  Status first_image_error;
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t keyframes_unloaded = 0;
  std::uint64_t zone_loads = 0;
  // Database work of the whole run, start-up included, one unit for every policy (LoadStats'
  // definitions: statements executed, transactions with an autocommit statement counted as
  // one, incremental blob reads), loads and basic's graph searches alike; search_* is the part
  // that was searching. The steady state is these minus `startup` (SteadyDbWork).
  std::uint64_t db_transactions = 0;
  std::uint64_t db_queries = 0;        // SQL statements executed
  std::uint64_t db_blob_reads = 0;
  std::uint64_t search_queries = 0;    // of db_queries
  std::uint64_t search_transactions = 0;  // of db_transactions
  std::uint64_t db_bytes_read = 0;
  std::uint32_t peak_resident_keyframes = 0;
  std::uint64_t peak_resident_bytes = 0;
  std::uint64_t over_budget_ticks = 0;
  std::uint32_t max_over_budget_keyframes = 0;   // worst excess over K_max at any instant
  std::uint64_t longest_over_budget_run = 0;      // consecutive ticks over budget
  std::uint64_t stalled_ticks = 0;
  std::uint64_t step_errors = 0;
  Status first_error;                             // the first step error (Ok when none)
  double load_ms = 0.0;               // in ticks and in the idle parts
  double unload_ms = 0.0;
  // Time-sliced loads (LoadSliceOptions): what the idle parts between ticks did, and what the
  // loads cost the ticks.
  double idle_load_ms = 0.0;                 // wall time of the idle parts that had loads queued
  std::uint64_t idle_keyframes_loaded = 0;   // of keyframes_loaded
  std::uint64_t keyframes_cancelled = 0;     // queued keyframes released before they loaded
  std::uint64_t loads_preempted = 0;         // zone loads overtaken by a newer zone's
  std::uint32_t max_pending_keyframes = 0;   // longest load queue after a tick
  std::uint64_t late_ticks = 0;              // ticks whose frame waited on an idle part
  double max_late_ms = 0.0;
  double late_ms = 0.0;  // summed over the steady ticks (each one's tick_ms includes its own)
  double simulated_s = 0.0;  // sum over ticks of max(frame period, tick time)
  StartupTotals startup;
  StreamingStats tick_ms;    // every tick after the first (the steady state)
  // The same ticks' stage times (TickRecord::stage_ms), by LoopStage.
  std::array<StreamingStats, kLoopStageCount> stage_ms;
};

// Database work after start-up: the run's totals minus the start-up load (the one derivation;
// summary.json's "steady_state").
struct DbWork {
  std::uint64_t queries = 0;       // SQL statements executed
  std::uint64_t transactions = 0;
  std::uint64_t blob_reads = 0;
  std::uint64_t bytes_read = 0;
};
[[nodiscard]] DbWork SteadyDbWork(const LoopTotals& totals);

// The budget's inputs for a loop over a map and frames (DeriveBudget, budget.h): the options,
// the map's facts, its vocabulary (null when it has none) and the frames' images (camera frames:
// the front-end's scratch). The one place for the loop and `zonemap budget --map`.
[[nodiscard]] BudgetInputs LoopBudgetInputs(const LoopConfig& config, const MapMetadata& map,
                                            const Vocabulary* vocabulary,
                                            const FrameSource::Images& images);

// What TickLoop::SetBudget did (acknowledged to the robot as `ack budget ...`).
struct BudgetChange {
  enum class Outcome : std::uint8_t {
    kApplied,  // the requested K_max is in force
    kClamped,  // more than the arena holds was asked: K_max = the arena's capacity
    kIgnored,  // the unbounded policy has no budget
    kRefused,  // 0 keyframes: K_max stays
  };
  Outcome outcome = Outcome::kApplied;
  std::uint64_t requested = 0;
  std::uint32_t k_max = 0;     // the budget in force afterwards
  std::uint32_t resident = 0;  // resident keyframes afterwards
  std::uint32_t unloaded = 0;  // keyframes unloaded by the change (at once)
};
[[nodiscard]] const char* BudgetOutcomeName(BudgetChange::Outcome outcome);

class TickLoop {
 public:
  // Opens nothing itself: the map and the frames are handed in (they outlive the loop). Reads
  // the map's metadata only (no payload), derives the budget (DeriveBudget), and builds the
  // arena, the indexes, the policy, the working set and the localizer.
  [[nodiscard]] static Result<std::unique_ptr<TickLoop>> Create(const LoopConfig& config,
                                                                MapReader& map,
                                                                FrameSource& frames,
                                                                LoopPlanInputs plan_inputs = {});
  ~TickLoop();
  TickLoop(const TickLoop&) = delete;
  TickLoop& operator=(const TickLoop&) = delete;

  // One tick. true: a frame was processed (read last_record()); false: the source ended (or
  // max_ticks was reached). Step failures are counted in totals(), not returned; an error
  // returned here is fatal (the frame source failed).
  [[nodiscard]] Result<bool> Tick();

  // What one idle part did.
  struct IdleReport {
    double ms = 0.0;                  // wall time spent (0 when nothing was queued)
    std::uint32_t keyframes_loaded = 0;
    std::uint64_t bytes_read = 0;
    std::uint32_t pending_keyframes = 0;  // still queued afterwards
    double late_ms = 0.0;             // how far it ran past the next frame's due time
  };
  // The idle part after a Tick() (see the header): advances the queued loads until `frame_due`
  // less LoadSliceOptions::margin_ms (and the slowest recent keyframe), the idle budget, or a
  // frame waiting at the source. frame_due = {} means this tick's start plus the frame period.
  // Errors are counted in totals() (and mark the next tick stalled), like a step's. Never
  // blocks, allocates nothing; a no-op when nothing is queued or loads are not sliced.
  IdleReport Idle(std::chrono::steady_clock::time_point frame_due = {});

  [[nodiscard]] const LoopTotals& totals() const { return totals_; }
  [[nodiscard]] const LoopConfig& config() const { return config_; }
  [[nodiscard]] const Budget& budget() const { return budget_; }
  [[nodiscard]] std::uint32_t k_max() const { return budget_.k_max; }
  [[nodiscard]] bool bounded() const { return budget_.bounded; }
  [[nodiscard]] std::uint64_t slot_bytes() const { return arena_.slot_bytes(); }
  [[nodiscard]] const Arena& arena() const { return arena_; }
  [[nodiscard]] const WorkingSet& working_set() const { return *working_set_; }
  [[nodiscard]] const MemoryPolicy& policy() const { return decide_->policy(); }
  [[nodiscard]] const Localizer& localizer() const { return *localizer_; }
  // The camera frames' front-end; null when the source's frames carry features, not images.
  [[nodiscard]] const FrontEnd* front_end() const { return front_end_.get(); }
  [[nodiscard]] const MapIndex& map_index() const { return map_index_; }
  [[nodiscard]] const ZoneSet& zone_set() const { return zone_set_; }
  // The record of the last processed frame (valid after Tick() returned true).
  [[nodiscard]] const TickRecord& last_record() const { return record_; }
  // Why the last refused camera frame's image could not be used (last_record().image_refused):
  // the front-end's words, naming the frame and the limit (zonemapd's diagnostic).
  [[nodiscard]] const Status& last_frame_error() const { return frame_error_; }
  [[nodiscard]] std::uint64_t malformed_lines() const { return frames_.malformed_lines(); }
  [[nodiscard]] double frame_period_s() const { return frame_period_s_; }
  // The current map<-odom correction T_map_odom: the last processed frame's pose is
  // map_from_odom() * its odometry, and so is the next frame's prediction.
  [[nodiscard]] const Pose3& map_from_odom() const { return t_map_odom_; }

  // The robot steers the memory manager (issue 18 §2). Both are called between ticks.
  //
  // Reserves room for a live route of up to `zones` zones (start-up only: allocates).
  void ReserveRoute(std::size_t zones);
  // Replaces the planned route (predictive follows it) with the zones the path through
  // `waypoints` (map frame) crosses, in order: the segments between waypoints are sampled every
  // kRouteSampleStepM, each sample looked up with ZoneIndex::Lookup, samples outside every zone
  // and repeats dropped. false (the previous route kept) when the sequence would exceed the
  // reserve. An empty list clears the route. No allocation.
  [[nodiscard]] bool SetRoute(std::span<const Eigen::Vector3d> waypoints);
  [[nodiscard]] std::span<const ZoneId> route() const { return route_; }
  // The decide step's context of the last tick (zone, pose, small displacement, ...).
  [[nodiscard]] const TickContext& context() const { return decide_->context(); }
  static constexpr double kRouteSampleStepM = 0.25;
  // Changes MemoryThr from now on. Down: the policy unloads at once until the working set fits
  // (MemoryPolicy::ChangeBudget; releases only, so residency never exceeds the new budget at any
  // instant; basic instead lowers its MemoryThr and transfers over the next ticks, as RTAB-Map
  // does). Up: at most the arena's capacity (fixed at start, the profile's budget for the
  // bounded policies): more is clamped to it, never grown. 0 is refused; unbounded ignores it.
  // Keyframes unloaded count in totals(). No allocation.
  [[nodiscard]] BudgetChange SetBudget(std::uint64_t k_max);
  // Holds back up to `slots` of the arena's free slots from loads (Arena::Withhold: set, not
  // added; 0 gives them back), between ticks: the harness's device ledger does so while it
  // refuses the map process's grant, so nothing more loads until a grant succeeds. Residency is
  // untouched (nothing is unloaded). Returns how many are held. No allocation.
  std::uint32_t WithholdSlots(std::uint32_t slots) noexcept { return arena_.Withhold(slots); }

 private:
  TickLoop(const LoopConfig& config, FrameSource& frames, Arena arena, MapIndex index);
  // Adds what the working set did (a tick's or an idle part's telemetry) to the totals.
  void Account(const TickTelemetry& t);
  void NoteError(const Status& s);
  // Polls the frame source between two keyframes of the idle part.
  class FrameWaiting final : public SliceInterrupt {
   public:
    explicit FrameWaiting(FrameSource& frames) : frames_(frames) {}
    bool ShouldStop() override { return frames_.FrameWaiting(); }

   private:
    FrameSource& frames_;
  };

  LoopConfig config_;
  FrameSource& frames_;
  Arena arena_;
  MapIndex map_index_;
  Budget budget_;
  ZoneSet zone_set_;
  ZoneIndex zone_index_;
  std::unique_ptr<LtmGraph> ltm_graph_;  // before decide_: its policy reads through it
  std::unique_ptr<DecideStep> decide_;   // the policy, its plan and the tick's context
  std::unique_ptr<WorkingSet> working_set_;
  std::unique_ptr<Localizer> localizer_;
  // Camera frames (issue 26): the front-end that extracts the frame's features inside the tick,
  // and the map's vocabulary the localizer scores with (either may be absent).
  std::unique_ptr<FrontEnd> front_end_;
  std::optional<Vocabulary> vocabulary_;
  std::vector<ZoneId> route_;
  std::vector<ZoneId> route_scratch_;  // SetRoute builds here, then swaps (same capacity)
  double frame_period_s_ = 1.0;

  // Per-tick state, reserved in Create.
  Frame frame_;
  TickTelemetry tel_;
  TickRecord record_;
  Status frame_error_;  // the last refused frame's reason
  std::vector<ResidentKeyframe> resident_views_;
  std::vector<Pose3> keyframe_poses_;  // by KfIndex
  Pose3 t_map_odom_ = Pose3::Identity();
  std::uint64_t over_budget_run_ = 0;
  FrameWaiting frame_waiting_{frames_};
  std::chrono::steady_clock::time_point tick_start_{};
  // The idle parts since the last tick, reported in the next tick's record.
  double idle_ms_ = 0.0;
  std::uint32_t idle_keyframes_ = 0;
  double late_ms_ = 0.0;
  bool idle_error_ = false;
  bool idle_over_budget_ = false;
  LoopTotals totals_;
};

}  // namespace zm
