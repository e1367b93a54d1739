// LoopSummary: the typed totals of a loop as summary.json's keys (docs/design.md).
#include "runtime/summary.h"

namespace zm {

nlohmann::json LoopSummary(const TickLoop& loop, bool interrupted) {
  const LoopTotals& t = loop.totals();
  nlohmann::json s;
  s["policy"] = std::string(PolicyName(loop.config().policy.kind));
  s["k_max"] = loop.k_max();
  s["slot_bytes"] = loop.slot_bytes();
  s["arena_slots"] = loop.arena().capacity();
  s["arena_bytes_reserved"] = loop.arena().stats().bytes_reserved;
  s["arena_locked"] = loop.arena().locked();
  s["map_share_bytes"] = loop.budget().map_share_bytes;
  s["ticks"] = t.ticks;
  s["interrupted"] = interrupted;
  s["update_rate_hz"] = t.simulated_s > 0 ? static_cast<double>(t.ticks) / t.simulated_s : 0.0;
  s["frame_rate_hz"] = loop.config().loop.rate_hz;
  // Steady-state ticks (the first, start-up tick is reported apart in "startup").
  s["tick_ms"] = {{"mean", t.tick_ms.mean()},
                  {"p50", t.tick_ms.Quantile(0.50)},
                  {"p99", t.tick_ms.Quantile(0.99)},
                  {"max", t.tick_ms.max()},
                  {"count", t.tick_ms.count()}};
  s["time_total_ms"] = TimeTotalJson({.steady_mean_ms = t.tick_ms.mean(),
                                      .steady_ticks = t.tick_ms.count(),
                                      .has_startup = t.ticks > 0,
                                      .startup_tick_ms = t.startup.tick_ms,
                                      .late_ms = t.late_ms,
                                      .idle_load_ms = t.idle_load_ms});
  s["startup"] = {{"tick_ms", t.startup.tick_ms},
                  {"load_ms", t.startup.load_ms},
                  {"keyframes_loaded", t.startup.keyframes_loaded},
                  {"bytes_read", t.startup.bytes_read},
                  {"db_transactions", t.startup.db_transactions},
                  {"db_queries", t.startup.db_queries},
                  {"db_blob_reads", t.startup.db_blob_reads}};
  // Everything after the start-up load, in the same unit (db_* below are the whole run's).
  const DbWork steady = SteadyDbWork(t);
  s["steady_state"] = {{"db_queries", steady.queries},
                       {"db_transactions", steady.transactions},
                       {"db_blob_reads", steady.blob_reads},
                       {"db_bytes_read", steady.bytes_read}};
  s["loop_closures"] = t.loop_closures;
  s["closures_rejected"] = t.closures_rejected;
  s["peak_resident_keyframes"] = t.peak_resident_keyframes;
  s["peak_resident_bytes"] = t.peak_resident_bytes;
  s["over_budget_ticks"] = t.over_budget_ticks;
  s["max_over_budget_keyframes"] = t.max_over_budget_keyframes;
  s["longest_over_budget_run_ticks"] = t.longest_over_budget_run;
  s["alloc_failures"] = loop.arena().stats().refused;
  s["stalled_ticks"] = t.stalled_ticks;
  s["step_errors"] = t.step_errors;
  if (!t.first_error.ok()) s["first_error"] = t.first_error.ToString();
  s["keyframes_loaded"] = t.keyframes_loaded;
  s["keyframes_unloaded"] = t.keyframes_unloaded;
  s["zone_loads"] = t.zone_loads;
  s["db_transactions"] = t.db_transactions;
  s["db_queries"] = t.db_queries;
  s["db_blob_reads"] = t.db_blob_reads;
  s["search_queries"] = t.search_queries;
  s["search_transactions"] = t.search_transactions;
  s["db_bytes_read"] = t.db_bytes_read;
  s["load_ms_total"] = t.load_ms;
  s["unload_ms_total"] = t.unload_ms;
  const LoadSliceOptions& lo = loop.config().loads;
  s["loads"] = {{"sliced", lo.sliced},
                {"tick_ms", lo.tick_ms},
                {"tick_bytes", lo.tick_bytes},
                {"idle_ms", lo.idle_ms},
                {"idle_bytes", lo.idle_bytes},
                {"margin_ms", lo.margin_ms},
                {"idle_load_ms_total", t.idle_load_ms},
                {"idle_keyframes_loaded", t.idle_keyframes_loaded},
                {"keyframes_cancelled", t.keyframes_cancelled},
                {"loads_preempted", t.loads_preempted},
                {"max_pending_keyframes", t.max_pending_keyframes},
                {"late_ticks", t.late_ticks},
                {"max_late_ms", t.max_late_ms},
                {"late_ms_total", t.late_ms}};
  s["malformed_lines"] = loop.malformed_lines();
  return s;
}

nlohmann::json TimeTotalJson(const TimeTotalInputs& in) {
  const double n = static_cast<double>(in.steady_ticks);
  const double steady = in.steady_ticks > 0 ? in.steady_mean_ms : 0.0;
  const double with_startup =
      in.has_startup ? (steady * n + in.startup_tick_ms) / (n + 1.0) : steady;
  const double late = in.steady_ticks > 0 ? in.late_ms / n : 0.0;
  const double idle = in.steady_ticks > 0 ? in.idle_load_ms / n : 0.0;
  return {{"steady", steady},
          {"with_startup", with_startup},
          {"without_idle_loads", steady - late},
          {"with_idle_loads", steady - late + idle}};
}

}  // namespace zm
