// RunSummary: the typed totals of a run and their one JSON codec (summary.h; the keys in
// docs/runtime.md, "summary.json").
#include "runtime/summary.h"

#include <string_view>
#include <type_traits>

namespace zm {
namespace {

using Json = nlohmann::json;

// Reads members of one JSON object into typed fields: a missing key keeps the field's value (an
// older file), null empties an optional, any other type mismatch is the first error, named by
// its path ("summary.json: tick_ms.p99 is a string, expected a number").
class ObjectReader {
 public:
  ObjectReader(const Json& j, std::string path, Status* error)
      : j_(j), path_(std::move(path)), error_(error) {
    if (!j_.is_object() && error_->ok()) *error_ = Fail(path_.empty() ? "(top)" : path_, "an object");
  }

  template <typename T>
  void Get(std::string_view key, T& out) {
    if (!j_.is_object()) return;
    const auto it = j_.find(key);
    if (it == j_.end()) return;
    Read(*it, Path(key), out);
  }

  // A nested object: `read` fills `out` from an ObjectReader over it.
  template <typename T, typename F>
  void Object(std::string_view key, T& out, F read) {
    if (!j_.is_object()) return;
    const auto it = j_.find(key);
    if (it == j_.end()) return;
    ObjectReader sub(*it, Path(key), error_);
    read(sub, out);
  }

 private:
  std::string Path(std::string_view key) const {
    return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
  }
  static Status Fail(const std::string& path, const char* expected) {
    return InvalidArgument("summary.json: " + path + " is not " + expected);
  }
  void Mismatch(const std::string& path, const char* expected) {
    if (error_->ok()) *error_ = Fail(path, expected);
  }

  void Read(const Json& v, const std::string& path, bool& out) {
    if (v.is_boolean()) {
      out = v.get<bool>();
    } else {
      Mismatch(path, "a boolean");
    }
  }
  void Read(const Json& v, const std::string& path, int& out) {
    if (v.is_number_integer()) {
      out = v.get<int>();
    } else {
      Mismatch(path, "an integer");
    }
  }
  void Read(const Json& v, const std::string& path, std::uint64_t& out) {
    if (v.is_number_unsigned()) {
      out = v.get<std::uint64_t>();
    } else if (v.is_number_integer() && v.get<std::int64_t>() >= 0) {
      out = static_cast<std::uint64_t>(v.get<std::int64_t>());
    } else {
      Mismatch(path, "a count (an integer >= 0)");
    }
  }
  void Read(const Json& v, const std::string& path, double& out) {
    if (v.is_number()) {
      out = v.get<double>();
    } else {
      Mismatch(path, "a number");
    }
  }
  void Read(const Json& v, const std::string& path, std::string& out) {
    if (v.is_string()) {
      out = v.get<std::string>();
    } else {
      Mismatch(path, "a string");
    }
  }
  template <typename T>
  void Read(const Json& v, const std::string& path, std::optional<T>& out) {
    if (v.is_null()) {
      out.reset();
      return;
    }
    T value{};
    Read(v, path, value);
    out = value;
  }

  const Json& j_;
  std::string path_;
  Status* error_;
};

// null for an empty optional.
template <typename T>
Json OrNull(const std::optional<T>& v) {
  return v ? Json(*v) : Json(nullptr);
}

void ReadTickMs(ObjectReader& r, TickMsSummary& t) {
  r.Get("mean", t.mean);
  r.Get("p50", t.p50);
  r.Get("p99", t.p99);
  r.Get("max", t.max);
  r.Get("count", t.count);
}
void ReadTimeTotal(ObjectReader& r, TimeTotal& t) {
  r.Get("steady", t.steady);
  r.Get("with_startup", t.with_startup);
  r.Get("without_idle_loads", t.without_idle_loads);
  r.Get("with_idle_loads", t.with_idle_loads);
}
void ReadStartup(ObjectReader& r, StartupSummary& s) {
  r.Get("tick_ms", s.tick_ms);
  r.Get("load_ms", s.load_ms);
  r.Get("keyframes_loaded", s.keyframes_loaded);
  r.Get("bytes_read", s.bytes_read);
  r.Get("db_transactions", s.db_transactions);
  r.Get("db_queries", s.db_queries);
  r.Get("db_blob_reads", s.db_blob_reads);
}
void ReadSteady(ObjectReader& r, SteadyStateSummary& s) {
  r.Get("db_queries", s.db_queries);
  r.Get("db_transactions", s.db_transactions);
  r.Get("db_blob_reads", s.db_blob_reads);
  r.Get("db_bytes_read", s.db_bytes_read);
}
void ReadLoads(ObjectReader& r, LoadsSummary& l) {
  r.Get("sliced", l.sliced);
  r.Get("tick_ms", l.tick_ms);
  r.Get("tick_bytes", l.tick_bytes);
  r.Get("idle_ms", l.idle_ms);
  r.Get("idle_bytes", l.idle_bytes);
  r.Get("margin_ms", l.margin_ms);
  r.Get("idle_load_ms_total", l.idle_load_ms_total);
  r.Get("idle_keyframes_loaded", l.idle_keyframes_loaded);
  r.Get("keyframes_cancelled", l.keyframes_cancelled);
  r.Get("loads_preempted", l.loads_preempted);
  r.Get("max_pending_keyframes", l.max_pending_keyframes);
  r.Get("late_ticks", l.late_ticks);
  r.Get("max_late_ms", l.max_late_ms);
  r.Get("late_ms_total", l.late_ms_total);
}

}  // namespace

TimeTotal TimeTotalOf(const TimeTotalInputs& in) {
  const double n = static_cast<double>(in.steady_ticks);
  const double steady = in.steady_ticks > 0 ? in.steady_mean_ms : 0.0;
  const double with_startup =
      in.has_startup ? (steady * n + in.startup_tick_ms) / (n + 1.0) : steady;
  const double late = in.steady_ticks > 0 ? in.late_ms / n : 0.0;
  const double idle = in.steady_ticks > 0 ? in.idle_load_ms / n : 0.0;
  return {.steady = steady,
          .with_startup = with_startup,
          .without_idle_loads = steady - late,
          .with_idle_loads = steady - late + idle};
}

RunSummary LoopSummary(const TickLoop& loop, bool interrupted) {
  const LoopTotals& t = loop.totals();
  RunSummary s;
  s.policy = std::string(PolicyName(loop.config().policy.kind));
  s.k_max = loop.k_max();
  s.slot_bytes = loop.slot_bytes();
  s.arena_slots = loop.arena().capacity();
  s.arena_bytes_reserved = loop.arena().stats().bytes_reserved;
  s.arena_locked = loop.arena().locked();
  s.map_share_bytes = loop.budget().map_share_bytes;
  s.ticks = t.ticks;
  s.interrupted = interrupted;
  s.update_rate_hz = t.simulated_s > 0 ? static_cast<double>(t.ticks) / t.simulated_s : 0.0;
  s.frame_rate_hz = loop.config().loop.rate_hz;
  s.tick_ms = {.mean = t.tick_ms.mean(),
               .p50 = t.tick_ms.Quantile(0.50),
               .p99 = t.tick_ms.Quantile(0.99),
               .max = t.tick_ms.max(),
               .count = t.tick_ms.count()};
  s.time_total_ms = TimeTotalOf({.steady_mean_ms = t.tick_ms.mean(),
                                 .steady_ticks = t.tick_ms.count(),
                                 .has_startup = t.ticks > 0,
                                 .startup_tick_ms = t.startup.tick_ms,
                                 .late_ms = t.late_ms,
                                 .idle_load_ms = t.idle_load_ms});
  s.startup = {.tick_ms = t.startup.tick_ms,
               .load_ms = t.startup.load_ms,
               .keyframes_loaded = t.startup.keyframes_loaded,
               .bytes_read = t.startup.bytes_read,
               .db_transactions = t.startup.db_transactions,
               .db_queries = t.startup.db_queries,
               .db_blob_reads = t.startup.db_blob_reads};
  // Everything after the start-up load, in the same unit (db_* below are the whole run's).
  const DbWork steady = SteadyDbWork(t);
  s.steady_state = {.db_queries = steady.queries,
                    .db_transactions = steady.transactions,
                    .db_blob_reads = steady.blob_reads,
                    .db_bytes_read = steady.bytes_read};
  s.loop_closures = t.loop_closures;
  s.closures_rejected = t.closures_rejected;
  s.peak_resident_keyframes = t.peak_resident_keyframes;
  s.peak_resident_bytes = t.peak_resident_bytes;
  s.over_budget_ticks = t.over_budget_ticks;
  s.max_over_budget_keyframes = t.max_over_budget_keyframes;
  s.longest_over_budget_run_ticks = t.longest_over_budget_run;
  s.alloc_failures = loop.arena().stats().refused;
  s.stalled_ticks = t.stalled_ticks;
  s.step_errors = t.step_errors;
  if (!t.first_error.ok()) s.first_error = t.first_error.ToString();
  s.keyframes_loaded = t.keyframes_loaded;
  s.keyframes_unloaded = t.keyframes_unloaded;
  s.zone_loads = t.zone_loads;
  s.db_transactions = t.db_transactions;
  s.db_queries = t.db_queries;
  s.db_blob_reads = t.db_blob_reads;
  s.search_queries = t.search_queries;
  s.search_transactions = t.search_transactions;
  s.db_bytes_read = t.db_bytes_read;
  s.load_ms_total = t.load_ms;
  s.unload_ms_total = t.unload_ms;
  const LoadSliceOptions& lo = loop.config().loads;
  s.loads = {.sliced = lo.sliced,
             .tick_ms = lo.tick_ms,
             .tick_bytes = lo.tick_bytes,
             .idle_ms = lo.idle_ms,
             .idle_bytes = lo.idle_bytes,
             .margin_ms = lo.margin_ms,
             .idle_load_ms_total = t.idle_load_ms,
             .idle_keyframes_loaded = t.idle_keyframes_loaded,
             .keyframes_cancelled = t.keyframes_cancelled,
             .loads_preempted = t.loads_preempted,
             .max_pending_keyframes = t.max_pending_keyframes,
             .late_ticks = t.late_ticks,
             .max_late_ms = t.max_late_ms,
             .late_ms_total = t.late_ms};
  s.malformed_lines = loop.malformed_lines();
  return s;
}

Json ToJson(const RunSummary& s) {
  Json j;
  j["schema_version"] = s.schema_version;
  j["policy"] = s.policy;
  j["k_max"] = s.k_max;
  j["slot_bytes"] = s.slot_bytes;
  j["arena_slots"] = s.arena_slots;
  j["arena_bytes_reserved"] = s.arena_bytes_reserved;
  j["arena_locked"] = s.arena_locked;
  j["map_share_bytes"] = s.map_share_bytes;
  j["ticks"] = s.ticks;
  j["interrupted"] = s.interrupted;
  j["update_rate_hz"] = OrNull(s.update_rate_hz);
  j["frame_rate_hz"] = s.frame_rate_hz;
  j["tick_ms"] = {{"mean", s.tick_ms.mean},
                  {"p50", s.tick_ms.p50},
                  {"p99", s.tick_ms.p99},
                  {"max", s.tick_ms.max},
                  {"count", s.tick_ms.count}};
  j["time_total_ms"] = {{"steady", s.time_total_ms.steady},
                        {"with_startup", s.time_total_ms.with_startup},
                        {"without_idle_loads", s.time_total_ms.without_idle_loads},
                        {"with_idle_loads", s.time_total_ms.with_idle_loads}};
  j["startup"] = {{"tick_ms", s.startup.tick_ms},
                  {"load_ms", s.startup.load_ms},
                  {"keyframes_loaded", s.startup.keyframes_loaded},
                  {"bytes_read", s.startup.bytes_read},
                  {"db_transactions", s.startup.db_transactions},
                  {"db_queries", s.startup.db_queries},
                  {"db_blob_reads", s.startup.db_blob_reads}};
  j["steady_state"] = {{"db_queries", s.steady_state.db_queries},
                       {"db_transactions", s.steady_state.db_transactions},
                       {"db_blob_reads", s.steady_state.db_blob_reads},
                       {"db_bytes_read", s.steady_state.db_bytes_read}};
  j["loop_closures"] = s.loop_closures;
  j["closures_rejected"] = s.closures_rejected;
  j["peak_resident_keyframes"] = s.peak_resident_keyframes;
  j["peak_resident_bytes"] = s.peak_resident_bytes;
  j["over_budget_ticks"] = s.over_budget_ticks;
  j["max_over_budget_keyframes"] = s.max_over_budget_keyframes;
  j["longest_over_budget_run_ticks"] = s.longest_over_budget_run_ticks;
  j["alloc_failures"] = s.alloc_failures;
  j["stalled_ticks"] = s.stalled_ticks;
  j["step_errors"] = s.step_errors;
  if (s.first_error) j["first_error"] = *s.first_error;
  j["keyframes_loaded"] = s.keyframes_loaded;
  j["keyframes_unloaded"] = s.keyframes_unloaded;
  j["zone_loads"] = s.zone_loads;
  j["db_transactions"] = s.db_transactions;
  j["db_queries"] = s.db_queries;
  j["db_blob_reads"] = s.db_blob_reads;
  j["search_queries"] = s.search_queries;
  j["search_transactions"] = s.search_transactions;
  j["db_bytes_read"] = s.db_bytes_read;
  j["load_ms_total"] = s.load_ms_total;
  j["unload_ms_total"] = s.unload_ms_total;
  const LoadsSummary& l = s.loads;
  j["loads"] = {{"sliced", l.sliced},
                {"tick_ms", l.tick_ms},
                {"tick_bytes", l.tick_bytes},
                {"idle_ms", l.idle_ms},
                {"idle_bytes", l.idle_bytes},
                {"margin_ms", l.margin_ms},
                {"idle_load_ms_total", l.idle_load_ms_total},
                {"idle_keyframes_loaded", l.idle_keyframes_loaded},
                {"keyframes_cancelled", l.keyframes_cancelled},
                {"loads_preempted", l.loads_preempted},
                {"max_pending_keyframes", l.max_pending_keyframes},
                {"late_ticks", l.late_ticks},
                {"max_late_ms", l.max_late_ms},
                {"late_ms_total", l.late_ms_total}};
  j["malformed_lines"] = s.malformed_lines;
  if (s.replay) {
    const ReplaySummary& r = *s.replay;
    j["profile"] = r.profile;
    j["scenario"] = r.scenario;
    j["time_compression"] = r.time_compression;
    j["realtime_frames"] = r.realtime_frames;
    j["frames_arrived"] = r.frames_arrived;
    j["frames_dropped"] = r.frames_dropped;
    j["frames_not_taken"] = r.frames_not_taken;
    j["frames_refused"] = r.frames_refused;
    j["wall_s"] = r.wall_s;
    j["wall_origin_mono_s"] = r.wall_origin_mono_s;
    if (r.update_rate_model_hz) j["update_rate_model_hz"] = *r.update_rate_model_hz;
    const TrajectorySummary& t = r.trajectory;
    j["ate_rmse_m"] = OrNull(t.ate_rmse_m);
    j["ate_se3_rmse_m"] = OrNull(t.ate_se3_rmse_m);
    j["rpe_trans_rmse_m"] = OrNull(t.rpe_trans_rmse_m);
    j["rpe_rot_rmse_deg"] = OrNull(t.rpe_rot_rmse_deg);
    if (t.associated_poses) j["associated_poses"] = *t.associated_poses;
  }
  if (s.ledger_refusals) j["ledger_refusals"] = *s.ledger_refusals;
  if (s.partial) j["partial"] = true;
  return j;
}

Result<RunSummary> RunSummaryFromJson(const Json& j) {
  Status error;
  RunSummary s;
  ObjectReader r(j, "", &error);
  s.schema_version = 0;  // a file from before the version existed
  r.Get("schema_version", s.schema_version);
  if (error.ok() && s.schema_version > kSummarySchemaVersion) {
    return InvalidArgument("summary.json: schema_version " + std::to_string(s.schema_version) +
                           " is newer than this build reads (" +
                           std::to_string(kSummarySchemaVersion) + ")");
  }
  r.Get("policy", s.policy);
  r.Get("k_max", s.k_max);
  r.Get("slot_bytes", s.slot_bytes);
  r.Get("arena_slots", s.arena_slots);
  r.Get("arena_bytes_reserved", s.arena_bytes_reserved);
  r.Get("arena_locked", s.arena_locked);
  r.Get("map_share_bytes", s.map_share_bytes);
  r.Get("ticks", s.ticks);
  r.Get("interrupted", s.interrupted);
  r.Get("update_rate_hz", s.update_rate_hz);
  r.Get("frame_rate_hz", s.frame_rate_hz);
  r.Object("tick_ms", s.tick_ms, ReadTickMs);
  r.Object("time_total_ms", s.time_total_ms, ReadTimeTotal);
  r.Object("startup", s.startup, ReadStartup);
  r.Object("steady_state", s.steady_state, ReadSteady);
  r.Get("loop_closures", s.loop_closures);
  r.Get("closures_rejected", s.closures_rejected);
  r.Get("peak_resident_keyframes", s.peak_resident_keyframes);
  r.Get("peak_resident_bytes", s.peak_resident_bytes);
  r.Get("over_budget_ticks", s.over_budget_ticks);
  r.Get("max_over_budget_keyframes", s.max_over_budget_keyframes);
  r.Get("longest_over_budget_run_ticks", s.longest_over_budget_run_ticks);
  r.Get("alloc_failures", s.alloc_failures);
  r.Get("stalled_ticks", s.stalled_ticks);
  r.Get("step_errors", s.step_errors);
  r.Get("first_error", s.first_error);
  r.Get("keyframes_loaded", s.keyframes_loaded);
  r.Get("keyframes_unloaded", s.keyframes_unloaded);
  r.Get("zone_loads", s.zone_loads);
  r.Get("db_transactions", s.db_transactions);
  r.Get("db_queries", s.db_queries);
  r.Get("db_blob_reads", s.db_blob_reads);
  r.Get("search_queries", s.search_queries);
  r.Get("search_transactions", s.search_transactions);
  r.Get("db_bytes_read", s.db_bytes_read);
  r.Get("load_ms_total", s.load_ms_total);
  r.Get("unload_ms_total", s.unload_ms_total);
  r.Object("loads", s.loads, ReadLoads);
  r.Get("malformed_lines", s.malformed_lines);
  // The replay's part is there when its keys are (a file of zonemapd's has none).
  if (j.is_object() && j.contains("wall_s")) {
    ReplaySummary rp;
    r.Get("profile", rp.profile);
    r.Get("scenario", rp.scenario);
    r.Get("time_compression", rp.time_compression);
    r.Get("realtime_frames", rp.realtime_frames);
    r.Get("frames_arrived", rp.frames_arrived);
    r.Get("frames_dropped", rp.frames_dropped);
    r.Get("frames_not_taken", rp.frames_not_taken);
    r.Get("frames_refused", rp.frames_refused);
    r.Get("wall_s", rp.wall_s);
    r.Get("wall_origin_mono_s", rp.wall_origin_mono_s);
    r.Get("update_rate_model_hz", rp.update_rate_model_hz);
    r.Get("ate_rmse_m", rp.trajectory.ate_rmse_m);
    r.Get("ate_se3_rmse_m", rp.trajectory.ate_se3_rmse_m);
    r.Get("rpe_trans_rmse_m", rp.trajectory.rpe_trans_rmse_m);
    r.Get("rpe_rot_rmse_deg", rp.trajectory.rpe_rot_rmse_deg);
    r.Get("associated_poses", rp.trajectory.associated_poses);
    s.replay = std::move(rp);
  }
  r.Get("ledger_refusals", s.ledger_refusals);
  r.Get("partial", s.partial);
  if (!error.ok()) return error;
  return s;
}

}  // namespace zm
