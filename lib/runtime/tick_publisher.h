// One tick, published: the loop fills its TickRecord once (TickLoop::last_record()), and this
// hands that one record to each consumer in turn, the same way for zonemapd (daemon.h) and
// `zonemap run` (harness/run.cc):
//
//   pose tracker   status and covariance (pose_output.h), when the run tracks them (zonemapd);
//   pose line      PoseLineOf(record, tracker), formatted into a reserved buffer and returned for
//                  the caller to send (zonemapd: stdout or the UDP peer);
//   estimate.tum   one TUM line (EstimateWriter), when a path is given;
//   ticks.jsonl    one JSON line (TelemetryWriter): the record, then the tracker's members
//                  (status, frames_since_fix, sigma_xy_m, k_max, malformed) when tracking, then
//                  the caller's `extra` (the evaluation's device samples);
//   flush          both files every flush_ticks ticks, the estimate first: a tick on disk always
//                  has its pose on disk.
// The statistics (LoopTotals) are the loop's own, accounted from the same record inside Tick().
//
// Everything is allocated in Open(); Publish() never allocates.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "common/status.h"
#include "runtime/estimate_writer.h"
#include "runtime/pose_output.h"
#include "runtime/telemetry.h"

namespace zm {

struct PublishOptions {
  std::string telemetry_path;    // ticks.jsonl ("" = none)
  std::string estimate_path;     // estimate.tum ("" = none)
  std::uint32_t flush_ticks = 10;  // flush both every N ticks (0 = only at Flush()/Close())
  // Track the localization status and covariance, write pose lines and the tracker's telemetry
  // members (zonemapd); off: neither (a replay's ticks.jsonl carries the record alone).
  bool track_status = false;
  PoseOutputOptions output{};    // the tracker's uncertainty model ([output])
};

class TickPublisher {
 public:
  TickPublisher() = default;
  TickPublisher(const TickPublisher&) = delete;
  TickPublisher& operator=(const TickPublisher&) = delete;

  // Opens the files (truncating them) and sets up the tracker. Errors name the file.
  [[nodiscard]] Status Open(const PublishOptions& options);
  // Publishes one processed tick (in order). Returns the pose line ('\n' included) when tracking,
  // else empty; valid until the next call. `extra`: further telemetry members, `"k":v,...`.
  std::string_view Publish(const TickRecord& record, std::string_view extra = {});
  void Flush();
  void Close();

  [[nodiscard]] const PoseTracker& tracker() const { return tracker_; }
  [[nodiscard]] std::uint64_t telemetry_lines() const { return telemetry_.lines(); }

 private:
  PublishOptions options_;
  PoseTracker tracker_{PoseOutputOptions{}};
  TelemetryWriter telemetry_;
  EstimateWriter estimate_;
  bool has_telemetry_ = false;
  bool has_estimate_ = false;
  char pose_line_[kPoseLineMaxBytes] = {};
  char extra_[1536] = {};  // the tracker's members and the caller's extra
};

}  // namespace zm
