// zonemap public API, way 2: the complete path.
//
// zonemap's own map database (SQLite, written by `zonemap sim`, `zonemap import-rtabmap` and
// `zonemap zones annotate`), its fixed keyframe arena sized from the profile's budget, the
// memory policy and the localizer, in the tick loop zonemapd runs: the host hands in odometry
// and image features, zonemap answers with the corrected pose in the map frame.
//
//   zonemap::MapLoopOptions opt;
//   opt.db_path = "map.db";
//   opt.profile = "orin-nano-8gb";
//   auto loop = zonemap::MapLoop::Open(opt);             // everything allocated here
//   for (;;) {
//     auto out = (*loop)->Process({.stamp_s = t, .odom = odom, .features = feats});
//     if (out.ok()) publish(out->pose);                  // map frame, TUM order
//   }
//
// Invariants kept (docs/design.md): resident keyframes <= K_max at every instant for the
// bounded policies (the arena has exactly K_max slots: a load past it is refused, never grown);
// unload before load, one SQLite transaction per zone load; the localizer only sees resident
// keyframes; no heap allocation in a warm tick (every policy); a bad frame is refused, never
// processed. Loads happen inside Process, on the caller's thread.
//
// Threading: not thread-safe; one thread calls Process/Step. Unlike zonemapd, MapLoop does not
// cap its process's memory (map.process_cap_bytes) or install signal handlers: the host owns
// its process.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "zonemap/status.h"
#include "zonemap/types.h"

namespace zonemap {

struct MapLoopOptions {
  std::string db_path;           // the map database (read-only)
  // The device profile: a name (searched like zonemapd's) or a path to a .toml file. Empty (the
  // default, the same as ManagerOptions::profile) = no profile: every module's defaults and no
  // device memory, so K_max is memory_thr's count, else the whole map. Why not "host", the
  // programs' default: a library must open the same wherever it is installed, and a profile
  // name is searched beside the build's source tree or in $ZM_PROFILES_DIR, which an installed
  // library's user does not have (docs/api.md); a device's byte budget is asked for by naming
  // the device.
  std::string profile;
  std::string policy;                 // override of the profile's policy; empty = keep
  std::string memory_thr;             // override of MemoryThr: "N", "BYTES" ("2GiB") or "N,BYTES"
  std::uint32_t max_features = 2048;  // the largest frame Process accepts
  // Replay instead of live input: a frames file recorded by `zonemap sim` (frames.bin); then
  // call Step(), not Process().
  std::string frames_path;
};

// One image feature: keypoint in pixels (same camera as the map) and its 256-bit binary
// descriptor (ORB).
struct Feature {
  float u = 0.0f, v = 0.0f;
  std::array<std::uint8_t, 32> descriptor{};
};

struct FrameInput {
  double stamp_s = 0.0;               // must increase from frame to frame
  Pose odom;                          // odometry pose (drifting odom frame)
  std::span<const Feature> features;  // at most MapLoopOptions::max_features
};

// What one tick produced (zonemapd's `pose` line and telemetry, typed).
struct TickOutput {
  std::uint64_t tick = 0;
  double stamp_s = 0.0;
  Pose pose;                        // corrected body pose in the map frame
  Pose correction;                  // map <- odom correction applied to this frame's odometry
  ZoneId zone = kNoZone;
  bool startup = false;             // this tick carried the policy's start-up load
  bool loop_closure = false;        // a closure was accepted (it corrects from the next tick)
  KeyframeId matched;               // the keyframe it matched; 0 = none
  std::uint32_t inliers = 0;
  std::uint32_t resident_keyframes = 0;
  std::uint32_t keyframes_loaded = 0;
  std::uint32_t keyframes_unloaded = 0;
  bool over_budget = false;         // resident exceeded K_max at some instant (basic only)
  bool stalled = false;             // a step failed (counted in stats(); the loop goes on)
  double tick_ms = 0.0;
};

struct LoopStats {
  std::uint64_t ticks = 0;
  std::uint64_t loop_closures = 0;  // accepted (summary.json closures_accepted)
  std::uint64_t keyframes_loaded = 0;
  std::uint64_t keyframes_unloaded = 0;
  std::uint64_t zone_loads = 0;
  std::uint64_t db_transactions = 0;
  std::uint64_t db_bytes_read = 0;
  std::uint32_t peak_resident_keyframes = 0;
  std::uint64_t over_budget_ticks = 0;
  std::uint64_t stalled_ticks = 0;
  std::uint64_t rejected_frames = 0;  // Process() calls refused as bad input
  double tick_ms_mean = 0.0;          // steady state: every tick after the first
  double tick_ms_p50 = 0.0;
  double tick_ms_p99 = 0.0;
  double tick_ms_max = 0.0;
};

class MapLoop {
 public:
  // Loads the profile, opens the database (schema checked, statements prepared), reads the
  // map's metadata (no payload), derives K_max, reserves the arena (the budget's bytes, up
  // front) and builds the indexes, the policy and the localizer. Cost: start-up only, O(map
  // metadata); the arena reservation is K_max slots of the largest keyframe. Errors name the
  // file, key or limit (a profile key, a database without zones, a budget holding no slot, ...).
  [[nodiscard]] static Result<std::unique_ptr<MapLoop>> Open(const MapLoopOptions& options);
  ~MapLoop();
  MapLoop(const MapLoop&) = delete;
  MapLoop& operator=(const MapLoop&) = delete;

  // One tick on a live frame: pose update, zone, the policy's unload-then-load (zone batches
  // from SQLite straight into arena slots), localization on the resident keyframes, basic's
  // retrieval/transfer. Cost: one tick of zonemapd (3-11 ms on the simulated hospital on the
  // build VM, README; dominated by loads when a zone is entered, docs/mapdb.md). Allocates
  // nothing once warm. A bad frame is kInvalidArgument, counted in stats().rejected_frames and
  // not processed: too many features, a non-finite keypoint or pose value, then zonemapd's input
  // gate (a stamp not finite, beyond 2^32 s or not greater than the last accepted one; | |q| - 1 |
  // above the profile's [input] quaternion_tolerance; a position beyond the map's extent +
  // [input] max_distance_from_map_m; docs/api.md). kFailedPrecondition in replay mode.
  [[nodiscard]] Result<TickOutput> Process(const FrameInput& frame);

  // Replay mode (MapLoopOptions::frames_path): the next recorded frame's tick; nullopt at the
  // end of the file. kFailedPrecondition without a frames file; I/O and corrupt-file errors
  // from the frames file. A recorded frame the input gate refuses is skipped and counted in
  // stats().rejected_frames.
  [[nodiscard]] Result<std::optional<TickOutput>> Step();

  // Queries: O(1), no allocation unless stated.
  [[nodiscard]] std::string_view policy() const;
  [[nodiscard]] std::uint32_t k_max() const;
  [[nodiscard]] bool bounded() const;
  [[nodiscard]] std::uint64_t slot_bytes() const;
  [[nodiscard]] std::uint32_t resident_count() const;
  [[nodiscard]] std::string_view zone_name(ZoneId zone) const;  // empty for an unknown id
  [[nodiscard]] std::string_view profile_path() const;  // the profile file read; "(no profile)"
  [[nodiscard]] LoopStats stats() const;                        // O(quantile buckets)

 private:
  struct Impl;
  explicit MapLoop(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace zonemap
