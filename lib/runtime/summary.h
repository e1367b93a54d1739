// summary.json: the run's totals as JSON, written by zonemapd at exit and extended by the
// evaluation (trajectory metrics, the device, the co-tenant). JSON lives only here, at the edge:
// the loop itself keeps typed totals (tick_loop.h's LoopTotals).
#pragma once

#include <nlohmann/json.hpp>

#include "runtime/tick_loop.h"

namespace zm {

// The summary.json keys a loop can fill by itself (everything but trajectory metrics). Allocates;
// call it once at the end of a run, never per tick.
[[nodiscard]] nlohmann::json LoopSummary(const TickLoop& loop, bool interrupted);

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
// call it.
struct TimeTotalInputs {
  double steady_mean_ms = 0.0;
  std::uint64_t steady_ticks = 0;
  bool has_startup = false;
  double startup_tick_ms = 0.0;
  double late_ms = 0.0;       // summed over the steady ticks
  double idle_load_ms = 0.0;  // summed over the run's idle parts that had loads queued
};
[[nodiscard]] nlohmann::json TimeTotalJson(const TimeTotalInputs& in);

}  // namespace zm
