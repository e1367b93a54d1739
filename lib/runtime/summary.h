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

}  // namespace zm
