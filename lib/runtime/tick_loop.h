// The tick loop: the single-threaded heart of zonemapd and of `zonemap run`.
//
// One tick, fixed order, a timer around each step (PX4's work-item shape):
//   1. read a frame                       FrameSource::Next
//   2. update the pose                    T_map_odom (correction) * odometry
//   3. look up the zone                   ZoneIndex::GetZone with hysteresis
//   4. the policy plans                   MemoryPolicy::PlanBeforeLocalize (unload, then load)
//   5. apply the plan                     WorkingSet::Apply -> MapDb::LoadZone into arena slots
//   6. localize on the resident set       Localizer::Localize over views of resident slots only;
//                                         then PlanAfterLocalize + Apply (basic's retrieval and
//                                         transfer happen here, as in RTAB-Map)
//   7. write telemetry                    TelemetryWriter (one JSON line)
//
// Everything is built in Create(); a warm tick allocates nothing in zonemap code (tested with
// the semantic policy). Errors never unwind through the loop: each step returns a value, and a
// failed step marks the tick stalled and is counted. An accepted loop closure changes the pose
// correction from the NEXT tick.
//
// Time: the loop runs on the frames' own clock (stamps), so a replay is deterministic and
// basic's whole-second ages mean what they mean on a robot running at the frame rate.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "arena/arena.h"
#include "common/status.h"
#include "geometry/pose.h"
#include "geometry/trajectory.h"
#include "localization/frame.h"
#include "localization/localizer.h"
#include "mapdb/map_db.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/policy.h"
#include "memory/working_set.h"
#include "runtime/frame_source.h"
#include "runtime/telemetry.h"
#include "zones/zone_index.h"
#include "zones/zone_set.h"

namespace zm {

struct LoopConfig {
  PolicyOptions policy;                 // memory policy and its budget (k_max filled by Create)
  LocalizerConfig localizer;
  ZoneIndexOptions zones;
  std::uint64_t memory_thr_keyframes = 0;  // MemoryThr as a count (0 = none)
  std::uint64_t memory_thr_bytes = 0;      // MemoryThr as bytes (0 = none)
  std::uint64_t slot_bytes = 0;            // 0 = the database's largest payload
  bool lock_arena = false;
  bool prefault_arena = false;
  bool verify_checksums = false;           // CRC-check payloads as they land (costs ~load time)
  std::uint32_t telemetry_flush_ticks = 10;
  std::uint64_t max_ticks = 0;             // 0 = until the source ends
  std::uint64_t expected_ticks = 0;        // per-tick series are reserved for this many ticks
  double small_displacement_m = 0.1;       // RGBD/LinearUpdate
  double small_displacement_rad = 0.1;     // RGBD/AngularUpdate
};

// Totals over a run, for summary.json.
struct LoopTotals {
  std::uint64_t ticks = 0;
  std::uint64_t loop_closures = 0;
  std::uint64_t closures_rejected = 0;
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t keyframes_unloaded = 0;
  std::uint64_t zone_loads = 0;
  std::uint64_t db_transactions = 0;
  std::uint64_t db_queries = 0;
  std::uint64_t search_queries = 0;
  std::uint64_t db_bytes_read = 0;
  std::uint32_t peak_resident_keyframes = 0;
  std::uint64_t peak_resident_bytes = 0;
  std::uint64_t over_budget_ticks = 0;
  std::uint32_t max_over_budget_keyframes = 0;   // worst excess over K_max at any instant
  std::uint64_t longest_over_budget_run = 0;      // consecutive ticks over budget
  std::uint64_t stalled_ticks = 0;
  std::uint64_t step_errors = 0;
  std::string first_error;
  double load_ms = 0.0;
  double unload_ms = 0.0;
  double simulated_s = 0.0;  // sum over ticks of max(frame period, tick time)
};

class TickLoop {
 public:
  // Opens nothing itself: the database, frames and telemetry are handed in (they outlive the
  // loop). `zones` may be empty when the database holds them. Builds the arena, the indexes,
  // the policy, the working set and the localizer.
  [[nodiscard]] static Result<std::unique_ptr<TickLoop>> Create(const LoopConfig& config, MapDb& db,
                                                                FrameSource& frames,
                                                                TelemetryWriter* telemetry,
                                                                std::vector<ZoneId> route,
                                                                std::vector<ZoneId> oracle_future,
                                                                double frame_rate_hz);
  ~TickLoop();

  // Start-up load (the policy's Start). Call once before Tick().
  Status Start();
  // One tick. true: a frame was processed; false: the source ended (or max_ticks reached).
  // Step failures are counted in totals(), not returned; an error here is fatal (I/O).
  [[nodiscard]] Result<bool> Tick();

  [[nodiscard]] const LoopTotals& totals() const { return totals_; }
  [[nodiscard]] const LoopConfig& config() const { return config_; }
  [[nodiscard]] const std::vector<double>& tick_ms() const { return tick_ms_; }
  // Estimated body trajectory (map frame), one pose per tick, stamped with the frame stamps.
  [[nodiscard]] const Trajectory& estimate() const { return estimate_; }
  [[nodiscard]] std::uint32_t k_max() const { return k_max_; }
  [[nodiscard]] std::uint64_t slot_bytes() const { return arena_.slot_bytes(); }
  [[nodiscard]] const Arena& arena() const { return arena_; }
  [[nodiscard]] const WorkingSet& working_set() const { return *working_set_; }
  [[nodiscard]] const MemoryPolicy& policy() const { return *policy_; }
  [[nodiscard]] const Localizer& localizer() const { return *localizer_; }
  [[nodiscard]] const MapIndex& map_index() const { return map_index_; }
  [[nodiscard]] const ZoneSet& zone_set() const { return zone_set_; }
  [[nodiscard]] const TickRecord& last_record() const { return record_; }
  [[nodiscard]] std::uint64_t malformed_lines() const { return frames_.malformed_lines(); }
  [[nodiscard]] bool bounded() const { return bounded_; }

 private:
  TickLoop(const LoopConfig& config, MapDb& db, FrameSource& frames, TelemetryWriter* telemetry,
           Arena arena, MapIndex index);
  void Account(const TickTelemetry& t);
  void NoteError(const Status& s);

  LoopConfig config_;
  MapDb& db_;
  FrameSource& frames_;
  TelemetryWriter* telemetry_;
  Arena arena_;
  MapIndex map_index_;
  ZoneSet zone_set_;
  ZoneIndex zone_index_;
  std::unique_ptr<MemoryPolicy> policy_;
  std::unique_ptr<WorkingSet> working_set_;
  std::unique_ptr<Localizer> localizer_;
  std::vector<ZoneId> route_;
  std::uint32_t k_max_ = 0;
  bool bounded_ = true;
  double frame_period_s_ = 1.0;

  // Per-tick state, reserved in Create.
  Frame frame_;
  Plan plan_;
  TickTelemetry tel_;
  TickContext ctx_;
  TickRecord record_;
  std::vector<ResidentKeyframe> resident_views_;
  std::vector<Pose3> keyframe_poses_;  // by KfIndex
  std::vector<double> tick_ms_;
  Trajectory estimate_;
  Pose3 t_map_odom_ = Pose3::Identity();
  Pose3 last_kept_pose_ = Pose3::Identity();
  bool have_kept_pose_ = false;
  ZoneId zone_ = kNoZone;
  std::uint64_t over_budget_run_ = 0;
  LoopTotals totals_;
};

}  // namespace zm
