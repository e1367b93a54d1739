// One replay of a scenario through the tick loop: what `zonemap run` and the evaluation matrix
// call. Opens the scenario's database and frames, runs every tick, writes RUNDIR/ticks.jsonl,
// RUNDIR/estimate.tum and RUNDIR/summary.json (the keys of docs/design.md), and returns the
// summary. Deterministic: the same inputs give the same decisions and the same summary, timings
// aside.
#pragma once

#include <atomic>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "common/status.h"
#include "runtime/input_gate.h"
#include "runtime/telemetry.h"
#include "runtime/tick_loop.h"

namespace zm {

// The run's clock at a tick, for on_tick.
struct TickClock {
  double wall_s = 0.0;  // seconds since the run's origin (CLOCK_MONOTONIC), at the tick's end
  std::uint64_t frames_arrived = 0;  // so far (real-time frames; else frames processed)
  std::uint64_t frames_dropped = 0;  // so far
};

struct RunRequest {
  std::string scenario_dir;
  std::string out_dir;
  LoopConfig loop;
  TelemetryOptions telemetry;
  InputOptions input;             // the input gate's rules ([input]; input_gate.h)
  std::string profile_name;       // for the summary only
  bool verify_checksums = false;  // CRC-check payloads as they land (MapDbOptions)
  // Real-time frames (harness/realtime_frames.h): > 0 = frames arrive on the clock at the
  // profile's rate ([loop] rate_hz), this many frames-clock seconds per wall second (1 = real
  // time), and an overrunning tick drops the frames that arrived meanwhile; 0 = every recorded
  // frame, as fast as the loop goes (no drops; the old replay).
  double time_compression = 0.0;
  // Called once the loop is built (arena reserved and pre-faulted) and before the first frame:
  // returns the clock origin (CLOCK_MONOTONIC s) at which the first frame arrives, e.g. after a
  // handshake with the process running the experiment. Empty: now.
  std::function<Result<double>(const TickLoop&)> on_ready;
  // Called after every tick (device bookkeeping; it may steer the loop between ticks, e.g.
  // TickLoop::WithholdSlots); may be empty. Whatever it returns (a `"key":value,...` fragment,
  // or empty) is appended to that tick's telemetry line. Must not allocate (a warm tick
  // allocates nothing).
  std::function<std::string_view(TickLoop&, const TickClock&)> on_tick;
};

// Runs the replay. estimate.tum is streamed (flushed with the telemetry), so a process killed
// mid-run leaves the poses it produced. summary.json gains `time_compression`,
// `frames_arrived`, `frames_dropped`, `frames_not_taken`, `wall_s`, `wall_origin_mono_s`; with
// real-time frames `update_rate_hz` is frames processed per second of the frames' clock. `stop`
// (may be null) ends it early at a tick boundary (SIGINT/SIGTERM); the telemetry is flushed and the
// summary written for the ticks done.
[[nodiscard]] Result<nlohmann::json> RunScenario(const RunRequest& request,
                                                 const std::atomic<bool>* stop = nullptr);

}  // namespace zm
