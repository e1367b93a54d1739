// RunSummary: the typed totals of a run and their one JSON codec (summary.h; the keys in
// docs/runtime.md, "summary.json").
#include "runtime/summary.h"

#include <optional>
#include <string>
#include <string_view>

namespace zm {
namespace {

using Json = nlohmann::json;

// How an empty optional member is written: null (the key is always there: update_rate_hz and the
// trajectory metrics) or left out (the others).
enum class IfEmpty { kNull, kOmit };

// Writes members into one JSON object. The same calls as ObjectReader's, so one field list per
// struct (below) serves both directions.
class ObjectWriter {
 public:
  explicit ObjectWriter(Json& j) : j_(j) {
    if (!j_.is_object()) j_ = Json::object();
  }

  template <typename T>
  void Field(std::string_view key, const T& value) {
    j_[std::string(key)] = value;
  }
  template <typename T>
  void Field(std::string_view key, const std::optional<T>& value, IfEmpty empty) {
    if (value) {
      j_[std::string(key)] = *value;
    } else if (empty == IfEmpty::kNull) {
      j_[std::string(key)] = nullptr;
    }
  }
  // A flag written only when set.
  void Flag(std::string_view key, bool value) {
    if (value) j_[std::string(key)] = true;
  }
  // A nested object: `fields` writes `value`'s members into it.
  template <typename T, typename F>
  void Object(std::string_view key, const T& value, F fields) {
    ObjectWriter sub(j_[std::string(key)]);
    fields(sub, value);
  }
  // A nested object present only when `value` holds one.
  template <typename T, typename F>
  void Object(std::string_view key, const std::optional<T>& value, F fields) {
    if (value) Object(key, *value, fields);
  }
  // Members of a part kept at this level (a replay's), written when the part is there; the
  // reader knows the part by `marker`, one of its keys.
  template <typename T, typename F>
  void Part(std::string_view /*marker*/, const std::optional<T>& part, F fields) {
    if (part) fields(*this, *part);
  }

 private:
  Json& j_;
};

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
  void Field(std::string_view key, T& out) {
    if (const Json* v = Find(key)) Read(*v, Path(key), out);
  }
  template <typename T>
  void Field(std::string_view key, std::optional<T>& out, IfEmpty /*how it was written*/) {
    Field(key, out);
  }
  void Flag(std::string_view key, bool& out) { Field(key, out); }
  template <typename T, typename F>
  void Object(std::string_view key, T& out, F fields) {
    if (const Json* v = Find(key)) {
      ObjectReader sub(*v, Path(key), error_);
      fields(sub, out);
    }
  }
  template <typename T, typename F>
  void Object(std::string_view key, std::optional<T>& out, F fields) {
    if (Find(key) != nullptr) Object(key, out.emplace(), fields);
  }
  template <typename T, typename F>
  void Part(std::string_view marker, std::optional<T>& part, F fields) {
    if (Find(marker) != nullptr) fields(*this, part.emplace());
  }

 private:
  const Json* Find(std::string_view key) const {
    if (!j_.is_object()) return nullptr;
    const auto it = j_.find(key);
    return it == j_.end() ? nullptr : &*it;
  }
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

// Each struct's keys, once: ToJson walks them with an ObjectWriter, RunSummaryFromJson with an
// ObjectReader (`v` is either; `s` the struct, const when writing).
constexpr auto kTickMsFields = [](auto& v, auto& t) {
  v.Field("mean", t.mean);
  v.Field("p50", t.p50);
  v.Field("p99", t.p99);
  v.Field("max", t.max);
  v.Field("count", t.count);
};
constexpr auto kTimeTotalFields = [](auto& v, auto& t) {
  v.Field("steady", t.steady);
  v.Field("with_startup", t.with_startup);
  v.Field("without_idle_loads", t.without_idle_loads);
  v.Field("with_idle_loads", t.with_idle_loads);
};
constexpr auto kStartupFields = [](auto& v, auto& s) {
  v.Field("tick_ms", s.tick_ms);
  v.Field("load_ms", s.load_ms);
  v.Field("keyframes_loaded", s.keyframes_loaded);
  v.Field("bytes_read", s.bytes_read);
  v.Field("db_transactions", s.db_transactions);
  v.Field("db_queries", s.db_queries);
  v.Field("db_blob_reads", s.db_blob_reads);
};
constexpr auto kSteadyFields = [](auto& v, auto& s) {
  v.Field("db_queries", s.db_queries);
  v.Field("db_transactions", s.db_transactions);
  v.Field("db_blob_reads", s.db_blob_reads);
  v.Field("db_bytes_read", s.db_bytes_read);
};
constexpr auto kLoadsFields = [](auto& v, auto& l) {
  v.Field("sliced", l.sliced);
  v.Field("tick_ms", l.tick_ms);
  v.Field("tick_bytes", l.tick_bytes);
  v.Field("idle_ms", l.idle_ms);
  v.Field("idle_bytes", l.idle_bytes);
  v.Field("margin_ms", l.margin_ms);
  v.Field("idle_load_ms_total", l.idle_load_ms_total);
  v.Field("idle_keyframes_loaded", l.idle_keyframes_loaded);
  v.Field("keyframes_cancelled", l.keyframes_cancelled);
  v.Field("loads_preempted", l.loads_preempted);
  v.Field("max_pending_keyframes", l.max_pending_keyframes);
  v.Field("late_ticks", l.late_ticks);
  v.Field("max_late_ms", l.max_late_ms);
  v.Field("late_ms_total", l.late_ms_total);
};
constexpr auto kStageFields = [](auto& v, auto& s) {
  v.Field("p50_ms", s.p50_ms);
  v.Field("p99_ms", s.p99_ms);
  v.Field("mean_ms", s.mean_ms);
};
constexpr auto kStagesFields = [](auto& v, auto& stages) {
  for (int i = 0; i < kLoopStageCount; ++i) {
    v.Object(LoopStageName(static_cast<LoopStage>(i)), stages[static_cast<std::size_t>(i)],
             kStageFields);
  }
};
constexpr auto kFrameScratchFields = [](auto& v, auto& f) {
  v.Field("capacity_bytes", f.capacity_bytes);
  v.Field("high_water_bytes", f.high_water_bytes);
  v.Field("allocations", f.allocations);
  v.Field("overflows", f.overflows);
  v.Field("scopes", f.scopes);
  v.Field("blocks_outliving_scope", f.blocks_outliving_scope);
};
// A replay's part, at the top level (marked by wall_s).
constexpr auto kReplayFields = [](auto& v, auto& r) {
  v.Field("profile", r.profile);
  v.Field("scenario", r.scenario);
  v.Field("time_compression", r.time_compression);
  v.Field("realtime_frames", r.realtime_frames);
  v.Field("frames_arrived", r.frames_arrived);
  v.Field("frames_dropped", r.frames_dropped);
  v.Field("frames_not_taken", r.frames_not_taken);
  v.Field("frames_refused", r.frames_refused);
  v.Field("wall_s", r.wall_s);
  v.Field("wall_origin_mono_s", r.wall_origin_mono_s);
  v.Field("update_rate_model_hz", r.update_rate_model_hz, IfEmpty::kOmit);
  auto& t = r.trajectory;
  v.Field("ate_rmse_m", t.ate_rmse_m, IfEmpty::kNull);
  v.Field("ate_se3_rmse_m", t.ate_se3_rmse_m, IfEmpty::kNull);
  v.Field("rpe_trans_rmse_m", t.rpe_trans_rmse_m, IfEmpty::kNull);
  v.Field("rpe_rot_rmse_deg", t.rpe_rot_rmse_deg, IfEmpty::kNull);
  v.Field("associated_poses", t.associated_poses, IfEmpty::kOmit);
};
constexpr auto kSummaryFields = [](auto& v, auto& s) {
  v.Field("schema_version", s.schema_version);
  v.Field("policy", s.policy);
  v.Field("k_max", s.k_max);
  v.Field("slot_bytes", s.slot_bytes);
  v.Field("arena_slots", s.arena_slots);
  v.Field("arena_bytes_reserved", s.arena_bytes_reserved);
  v.Field("arena_locked", s.arena_locked);
  v.Field("map_share_bytes", s.map_share_bytes);
  v.Field("vocabulary_bytes", s.vocabulary_bytes);
  v.Field("index_bytes", s.index_bytes);
  v.Field("frame_scratch_bytes", s.frame_scratch_bytes);
  v.Field("ticks", s.ticks);
  v.Field("interrupted", s.interrupted);
  v.Field("update_rate_hz", s.update_rate_hz, IfEmpty::kNull);
  v.Field("frame_rate_hz", s.frame_rate_hz);
  v.Object("tick_ms", s.tick_ms, kTickMsFields);
  v.Object("time_total_ms", s.time_total_ms, kTimeTotalFields);
  v.Object("startup", s.startup, kStartupFields);
  v.Object("steady_state", s.steady_state, kSteadyFields);
  v.Object("stages", s.stages, kStagesFields);
  v.Field("closures_accepted", s.closures_accepted);
  v.Field("frames_localized", s.frames_localized);
  v.Field("closures_rejected", s.closures_rejected);
  v.Field("images_refused", s.images_refused);
  v.Field("first_image_error", s.first_image_error, IfEmpty::kOmit);
  v.Object("frame_scratch", s.frame_scratch, kFrameScratchFields);
  v.Field("peak_resident_keyframes", s.peak_resident_keyframes);
  v.Field("peak_resident_bytes", s.peak_resident_bytes);
  v.Field("over_budget_ticks", s.over_budget_ticks);
  v.Field("max_over_budget_keyframes", s.max_over_budget_keyframes);
  v.Field("longest_over_budget_run_ticks", s.longest_over_budget_run_ticks);
  v.Field("alloc_failures", s.alloc_failures);
  v.Field("stalled_ticks", s.stalled_ticks);
  v.Field("step_errors", s.step_errors);
  v.Field("first_error", s.first_error, IfEmpty::kOmit);
  v.Field("keyframes_loaded", s.keyframes_loaded);
  v.Field("keyframes_unloaded", s.keyframes_unloaded);
  v.Field("zone_loads", s.zone_loads);
  v.Field("db_transactions", s.db_transactions);
  v.Field("db_queries", s.db_queries);
  v.Field("db_blob_reads", s.db_blob_reads);
  v.Field("search_queries", s.search_queries);
  v.Field("search_transactions", s.search_transactions);
  v.Field("db_bytes_read", s.db_bytes_read);
  v.Field("load_ms_total", s.load_ms_total);
  v.Field("unload_ms_total", s.unload_ms_total);
  v.Object("loads", s.loads, kLoadsFields);
  v.Field("malformed_lines", s.malformed_lines);
  v.Part("wall_s", s.replay, kReplayFields);
  v.Field("ledger_refusals", s.ledger_refusals, IfEmpty::kOmit);
  v.Flag("partial", s.partial);
};

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

TickMsSummary TickMsSummaryOf(const StreamingStats& ms) {
  return {.mean = ms.mean(),
          .p50 = ms.Quantile(0.50),
          .p99 = ms.Quantile(0.99),
          .max = ms.max(),
          .count = ms.count()};
}

StageSummary StageSummaryOf(const StreamingStats& ms) {
  return {.p50_ms = ms.Quantile(0.50), .p99_ms = ms.Quantile(0.99), .mean_ms = ms.mean()};
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
  s.vocabulary_bytes = loop.budget().vocabulary_bytes;
  s.index_bytes = loop.budget().index_bytes;
  s.frame_scratch_bytes = loop.budget().frame_scratch_bytes;
  s.ticks = t.ticks;
  s.interrupted = interrupted;
  s.update_rate_hz = t.simulated_s > 0 ? static_cast<double>(t.ticks) / t.simulated_s : 0.0;
  s.frame_rate_hz = loop.config().loop.rate_hz;
  s.tick_ms = TickMsSummaryOf(t.tick_ms);
  for (std::size_t i = 0; i < s.stages.size(); ++i) s.stages[i] = StageSummaryOf(t.stage_ms[i]);
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
  s.closures_accepted = t.closures_accepted;
  s.frames_localized = t.frames_localized;
  s.closures_rejected = t.closures_rejected;
  s.images_refused = t.images_refused;
  if (!t.first_image_error.ok()) s.first_image_error = t.first_image_error.ToString();
  if (const FrontEnd* fe = loop.front_end(); fe != nullptr) {
    s.frame_scratch = fe->extractor().scratch_stats();
  }
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
  Json j = Json::object();
  ObjectWriter w(j);
  kSummaryFields(w, s);
  return j;
}

Result<RunSummary> RunSummaryFromJson(const Json& j) {
  Status error;
  RunSummary s;
  ObjectReader r(j, "", &error);
  s.schema_version = 0;  // a file from before the version existed
  r.Field("schema_version", s.schema_version);
  if (error.ok() && s.schema_version > kSummarySchemaVersion) {
    return InvalidArgument("summary.json: schema_version " + std::to_string(s.schema_version) +
                           " is newer than this build reads (" +
                           std::to_string(kSummarySchemaVersion) + ")");
  }
  kSummaryFields(r, s);
  if (s.schema_version < 2) {  // version 1's one count: the frames whose closure was accepted
    r.Field("loop_closures", s.closures_accepted);
    s.frames_localized = s.closures_accepted;
  }
  if (!error.ok()) return error;
  return s;
}

}  // namespace zm
