// One replay of a scenario through the tick loop: what `zonemap run` and the evaluation matrix
// call. Opens the scenario's database and frames, runs every tick, writes RUNDIR/ticks.jsonl,
// RUNDIR/estimate.tum and RUNDIR/summary.json (the keys of docs/design.md), and returns the
// summary. Deterministic: the same inputs give the same decisions and the same summary, timings
// aside.
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "common/status.h"
#include "runtime/telemetry.h"
#include "runtime/tick_loop.h"

namespace zm {

struct RunRequest {
  std::string scenario_dir;
  std::string out_dir;
  LoopConfig loop;
  TelemetryOptions telemetry;
  std::string profile_name;  // for the summary only
  bool verify_checksums = false;  // CRC-check payloads as they land (MapDbOptions)
  // > 0: pace ticks on the wall clock at this multiple of the frames' own clock (1 = real
  // time), as frames arrive on a robot; 0: replay as fast as the loop goes.
  double pace_speedup = 0.0;
  // Called after every tick with the loop (device bookkeeping); may be empty. Whatever it
  // returns (a `"key":value,...` fragment, or empty) is appended to that tick's telemetry line.
  std::function<std::string_view(const TickLoop&)> on_tick;
};

// Runs the replay. `stop` (may be null) ends it early at a tick boundary (SIGINT/SIGTERM); the
// telemetry is flushed and the summary written for the ticks done.
[[nodiscard]] Result<nlohmann::json> RunScenario(const RunRequest& request,
                                                 const std::atomic<bool>* stop = nullptr);

}  // namespace zm
