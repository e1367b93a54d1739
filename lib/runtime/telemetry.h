// Per-tick telemetry: one fixed-size record per tick (what TickLoop fills, once: the pose line,
// ticks.jsonl, estimate.tum and the statistics all read this one record, tick_publisher.h),
// written as one JSON line to RUNDIR/ticks.jsonl. Formatting goes through std::to_chars
// (text_line.h) into a member buffer and a BufferedFile (buffer set once at open), so writing a
// tick never allocates (not even inside glibc's printf, which mallocs for formats of many
// conversions). SIGINT/SIGTERM handling only
// sets a flag; the loop then flushes and closes the file normally.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "common/ids.h"
#include "common/status.h"
#include "geometry/pose.h"
#include "runtime/buffered_file.h"

namespace zm {

// The loop's fixed steps (PX4 work-item shape), each timed.
enum class TickStep : int {
  kReadFrame = 0,
  kPoseUpdate,
  kZoneLookup,
  kPlan,
  kApply,
  kLocalize,
  kRecord,
  kCount
};
inline constexpr int kTickStepCount = static_cast<int>(TickStep::kCount);
[[nodiscard]] const char* TickStepName(TickStep step);

// Telemetry's options ([loop] telemetry_flush_ticks in a profile).
struct TelemetryOptions {
  std::uint32_t flush_ticks = 10;  // flush ticks.jsonl every N ticks (and at exit)
};

// Where a tick's time goes, as RTAB-Map reports it (issue 26): the front-end (decoding the
// frame's image and extracting ORB), the frame's bag of words, the likelihood over the resident
// keyframes, the candidates' matching and PnP, and memory management (the policy's plans,
// unloads, loads and the inverted index kept equal to the resident set). They sum to the tick's
// time less reading the frame and recording.
enum class LoopStage : int { kFeatures, kQuantize, kLikelihood, kVerify, kMemory };
inline constexpr int kLoopStageCount = 5;
[[nodiscard]] const char* LoopStageName(LoopStage stage);

struct TickRecord {
  std::uint64_t tick = 0;
  double stamp_s = 0.0;
  Pose3 pose = Pose3::Identity();        // corrected body pose in the map frame (the estimate)
  Pose3 correction = Pose3::Identity();  // T_map_odom applied to this frame's odometry
  // T_map_odom in force after this tick (a closure accepted on it changes it): pose = this *
  // odometry. The pose line's map->odom transform.
  Pose3 map_from_odom = Pose3::Identity();
  std::uint32_t k_max = 0;               // the budget in force (MemoryThr, keyframes)
  std::uint64_t malformed_lines = 0;     // input refused before this tick, so far (the source's)
  double x_m = 0.0, y_m = 0.0, yaw_rad = 0.0;  // the same pose, for plots
  bool startup = false;                  // this tick carried the start-up load
  ZoneId zone = kNoZone;
  std::uint32_t resident_keyframes = 0;
  std::uint64_t resident_bytes = 0;
  std::uint32_t keyframes_loaded = 0;
  std::uint32_t keyframes_unloaded = 0;
  std::uint32_t db_transactions = 0;
  std::uint32_t db_queries = 0;
  std::uint64_t db_bytes_read = 0;
  // Database work in one unit (LoadStats): db_queries are SQL statements executed, loads and
  // basic's graph searches alike; search_* is the searching part; startup_db_* the part of the
  // first tick that was the start-up load (0 on every other tick).
  std::uint32_t db_blob_reads = 0;
  std::uint32_t search_queries = 0;
  std::uint32_t search_transactions = 0;
  std::uint32_t startup_db_queries = 0;
  std::uint32_t startup_db_transactions = 0;
  std::uint32_t startup_db_blob_reads = 0;
  double load_ms = 0.0;
  double unload_ms = 0.0;
  std::uint32_t pending_keyframes = 0;      // queued to load after this tick (time-sliced loads)
  double idle_load_ms = 0.0;                // idle part(s) between the last tick and this one
  std::uint32_t idle_keyframes_loaded = 0;  // loaded there (not in keyframes_loaded)
  double late_ms = 0.0;                     // this frame's wait on that idle part (in tick_ms)
  bool over_budget = false;
  std::uint64_t refused_acquisitions = 0;  // cumulative arena refusals
  bool loop_closure = false;               // a closure was accepted this tick
  std::int64_t matched_keyframe = 0;       // 0 = none
  std::uint32_t inliers = 0;
  // The accepted closure's pose covariance (LocalizeResult::body_covariance: position in the map
  // frame, then rotation about the map's axes, ROS order) and its RMS reprojection error; zero
  // when no closure was accepted. pose_output.h turns it into the covariance the robot gets.
  Eigen::Matrix<double, 6, 6> closure_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  double reprojection_rms_px = 0.0;
  std::int64_t highest_hypothesis = 0;
  std::uint32_t candidates = 0;
  bool stalled = false;                    // a step failed this tick (counted in the totals)
  double step_ms[kTickStepCount] = {};
  double stage_ms[kLoopStageCount] = {};
  std::uint32_t features = 0;           // the frame's features (extracted or carried)
  bool has_image = false;               // a camera frame: the front-end extracted its features
  bool image_refused = false;           // its image could not be used: the tick ran on odometry
  bool vocabulary = false;              // scored with the map's vocabulary (the next two hold)
  float likelihood = 0.0f;              // the highest hypothesis' likelihood
  std::uint64_t postings_walked = 0;    // the likelihood's work
  double tick_ms = 0.0;
};

class TelemetryWriter {
 public:
  TelemetryWriter() = default;
  TelemetryWriter(const TelemetryWriter&) = delete;
  TelemetryWriter& operator=(const TelemetryWriter&) = delete;

  // Opens (truncates) `path` (the one BufferedFile: its buffer is allocated here, once).
  [[nodiscard]] Status Open(const std::string& path);
  // Appends one JSON line. `extra` (may be empty) is a pre-formatted fragment of further members,
  // `"key":value,"key2":value2`, appended inside the object: how the evaluation adds its device
  // samples without the core knowing them. Never allocates; returns false if the write failed or
  // the line would not fit the fixed buffer.
  bool Write(const TickRecord& r, std::string_view extra = {});
  void Flush();
  void Close();
  [[nodiscard]] std::uint64_t lines() const { return lines_; }

 private:
  BufferedFile file_;
  // The record's members (at most ~1.3 kB with every number at its widest) plus an `extra` as
  // long as TickPublisher's 1.5 kB buffer.
  char line_[4096] = {};
  std::uint64_t lines_ = 0;
};

}  // namespace zm
