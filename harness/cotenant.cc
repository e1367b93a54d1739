// Co-tenant stand-in: the model table and its KV geometry, configuration and sizes, the outcome
// decision and the report built from event lines. The run loop is cotenant_run.cc, the child
// process cotenant_process.cc. Every output says "stand-in".
#include "harness/cotenant.h"

#include <time.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "harness/device_scale.h"
#include "harness/experiment_profile.h"
#include "harness/weights_file.h"

namespace zm {
namespace {

// Weights: the paper's sizes (decimal GB). KV cache at f16 (2 bytes), K and V, per layer:
// 2 * kv_heads * head_dim * 2 bytes per token. Geometry from each model's config.json
// (docs/harness.md, "The paper's models"):
//   qwen3-vl-2b   28 layers, 8 KV heads x 128            -> 28 * 4096 = 114688 B/token
//   qwen3-vl-4b   36 layers, 8 KV heads x 128            -> 36 * 4096 = 147456 B/token
//   qwen3.5-*     24 layers, every 4th full attention (6), 2 KV heads x 256 -> 6 * 2048 =
//                 12288 B/token; the 18 Gated DeltaNet layers keep a fixed f32 state of
//                 16 heads x 128 x 128 plus a 3-column conv state of 6144 channels =
//                 1122304 B each -> 20201472 B per sequence
//   gemma3-4b     34 layers, 4 KV heads x 256 = 4096 B/token/layer; every 6th layer global
//                 (5) -> 20480 B/token; the 29 sliding-window layers -> 118784 B/token for at
//                 most 1024 tokens
constexpr std::array<CotenantModel, 5> kModels = {{
    {"qwen3-vl-2b", "qwen3-vl 2B", 1'900'000'000ULL, 114'688, 0, 0, 0},
    {"qwen3-vl-4b", "qwen3-vl 4B", 3'300'000'000ULL, 147'456, 0, 0, 0},
    {"qwen3.5-0.8b", "qwen3.5 0.8B", 1'000'000'000ULL, 12'288, 0, 0, 20'201'472},
    {"qwen3.5-2b", "qwen3.5 2B", 2'700'000'000ULL, 12'288, 0, 0, 20'201'472},
    {"gemma3-4b", "gemma3 4B", 3'300'000'000ULL, 20'480, 118'784, 1024, 0},
}};

std::uint64_t RoundUpPages(std::uint64_t bytes) {
  return (bytes + kWeightsPageBytes - 1) / kWeightsPageBytes * kWeightsPageBytes;
}

std::string Plural(std::uint64_t n, const char* what) {
  return std::to_string(n) + " " + what + (n == 1 ? "" : "s");
}

double Num(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : 0.0;
}
std::uint64_t U64(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<std::uint64_t>() : 0;
}
bool Bool(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_boolean() && it->get<bool>();
}
std::string Str(const nlohmann::json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}

}  // namespace

std::span<const CotenantModel> CotenantModels() { return kModels; }

Result<CotenantModel> FindCotenantModel(std::string_view name) {
  for (const CotenantModel& m : kModels) {
    if (m.name == name) return m;
  }
  return NotFound("unknown co-tenant model '" + std::string(name) +
                  "' (known: " + CotenantModelNames() + ")");
}

std::string CotenantModelNames() {
  std::string s;
  for (const CotenantModel& m : kModels) s += (s.empty() ? "" : ", ") + std::string(m.name);
  return s;
}

std::uint64_t KvCacheBytes(const CotenantModel& m, std::uint64_t context_tokens) {
  return m.state_bytes + context_tokens * m.kv_bytes_per_token +
         std::min<std::uint64_t>(context_tokens, m.window_tokens) * m.window_bytes_per_token;
}

std::string_view KvAllocationName(KvAllocation a) {
  return a == KvAllocation::kAtLoad ? "at_load" : "per_request";
}

std::string_view CotenantWeightsName(CotenantWeights w) {
  switch (w) {
    case CotenantWeights::kPinned:
      return "pinned";
    case CotenantWeights::kMmap:
      return "mmap";
    case CotenantWeights::kRead:
      return "read";
  }
  return "pinned";
}

bool ParseCotenantWeights(std::string_view text, CotenantWeights* out) {
  for (CotenantWeights w :
       {CotenantWeights::kPinned, CotenantWeights::kMmap, CotenantWeights::kRead}) {
    if (text == CotenantWeightsName(w)) {
      *out = w;
      return true;
    }
  }
  return false;
}

std::string_view WeightsLoadName(WeightsLoad w) {
  return w == WeightsLoad::kRead ? "read" : "mmap";
}

std::string_view CotenantOutcomeName(CotenantOutcome o) {
  switch (o) {
    case CotenantOutcome::kCompleted:
      return "completed";
    case CotenantOutcome::kStalled:
      return "stalled";
    case CotenantOutcome::kFailedToStart:
      return "failed_to_start";
    case CotenantOutcome::kKilled:
      return "killed";
  }
  return "unknown";
}

std::string_view CotenantOutcomeSymbol(CotenantOutcome o) {
  switch (o) {
    case CotenantOutcome::kCompleted:
      return "\u25cb";  // ○
    case CotenantOutcome::kStalled:
      return "\u25b3";  // △
    case CotenantOutcome::kFailedToStart:
      return "\u00d7";  // ×
    case CotenantOutcome::kKilled:
      return "\u2020";  // †
  }
  return "?";
}

CotenantConfig CotenantConfigFromProfile(const ExperimentProfile& profile) {
  CotenantConfig c;
  c.model = profile.core.model.name;
  c.weights_bytes = profile.core.model.weights_bytes;
  c.options = profile.cotenant;
  return c;
}

Result<CotenantSizes> ResolveCotenantSizes(const CotenantConfig& c) {
  const CotenantOptions& o = c.options;
  ZM_RETURN_IF_ERROR(ValidateDeviceScale(c.device_scale).Annotate("co-tenant"));
  if (o.answer_tokens == 0 || o.prompt_batch_tokens == 0) {
    return InvalidArgument("co-tenant answer_tokens and prompt_batch_tokens must be positive");
  }
  if (static_cast<std::uint64_t>(o.prompt_tokens) + o.answer_tokens > o.context_tokens) {
    return InvalidArgument("co-tenant prompt_tokens + answer_tokens (" +
                           std::to_string(o.prompt_tokens + std::uint64_t{o.answer_tokens}) +
                           ") exceed context_tokens (" + std::to_string(o.context_tokens) + ")");
  }
  CotenantSizes s;
  if (Result<CotenantModel> m = FindCotenantModel(c.model); m.ok()) {
    s.model = *m;
  } else if (o.kv_bytes_per_token != 0 && c.weights_bytes != 0) {
    s.model.name = c.model;
  } else {
    return NotFound(m.status().message() +
                    "; for another model set weights_bytes and [cotenant] kv_bytes_per_token");
  }
  if (o.kv_bytes_per_token != 0) {
    s.model.kv_bytes_per_token = o.kv_bytes_per_token;
    s.model.window_bytes_per_token = 0;
    s.model.window_tokens = 0;
    s.model.state_bytes = 0;
  }
  s.model_weights_bytes = c.weights_bytes != 0 ? c.weights_bytes : s.model.weights_bytes;
  s.weights_bytes = std::max<std::uint64_t>(
      ScaleBytes(s.model_weights_bytes, c.device_scale) / kWeightsPageBytes * kWeightsPageBytes,
      kWeightsPageBytes);
  s.kv_reserved_bytes = RoundUpPages(ScaledKvBytes(s, c.device_scale, o.context_tokens));
  s.request_kv_bytes =
      ScaledKvBytes(s, c.device_scale, std::uint64_t{o.prompt_tokens} + o.answer_tokens);
  s.watchdog_s = o.watchdog_s * c.device_scale;
  return s;
}

std::uint64_t ScaledKvBytes(const CotenantSizes& s, double device_scale,
                            std::uint64_t context_tokens) {
  return ScaleBytes(KvCacheBytes(s.model, context_tokens), device_scale);
}

Result<std::uint64_t> CotenantKvReserveBytes(const CotenantConfig& config) {
  CotenantConfig unscaled = config;
  unscaled.device_scale = 1.0;
  ZM_ASSIGN_OR_RETURN(const CotenantSizes s, ResolveCotenantSizes(unscaled));
  return s.kv_reserved_bytes;
}

OutcomeDecision DecideCotenantOutcome(const CotenantResult& r) {
  const std::uint32_t submitted = r.requests + r.requests_failed + r.requests_unfinished;
  std::string restarts;
  if (r.restarts > 0) restarts += "; restarted " + Plural(r.restarts, "time");
  if (r.failed_starts > 0) restarts += "; " + Plural(r.failed_starts, "start") + " failed";
  if (r.starts == 0) {
    std::string why = r.start_failure;
    if (r.kills + r.crashes > 0) {
      why += std::string(why.empty() ? "" : "; ") + "killed " +
             Plural(r.kills + r.crashes, "time") + " while loading" +
             (r.kills > 0 ? " (SIGKILL: an OOM kill)" : "");
    }
    return {CotenantOutcome::kFailedToStart, why.empty() ? "it never started" : why};
  }
  if (r.kills + r.crashes > 0) {
    std::string why;
    if (r.kills > 0)
      why = "killed by SIGKILL " + Plural(r.kills, "time") + " (an OOM kill, or the operator)";
    if (r.crashes > 0)
      why += std::string(why.empty() ? "" : ", ") + "crashed " + Plural(r.crashes, "time");
    return {CotenantOutcome::kKilled, why + restarts};
  }
  if (r.stalls > 0) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", r.watchdog_s);
    return {CotenantOutcome::kStalled, "the watchdog saw no token for " + std::string(buf) + " s " +
                                           Plural(r.stalls, "time") + restarts};
  }
  if (submitted > 0 && r.requests == 0) {
    return {CotenantOutcome::kStalled,
            "none of the " + Plural(submitted, "submitted request") + " completed" + restarts};
  }
  return {CotenantOutcome::kCompleted,
          r.requests_failed > 0 ? Plural(r.requests_failed, "request") + " failed" + restarts
          : restarts.empty()    ? ""
                                : restarts.substr(2)};
}

// ---- CotenantReportBuilder ----

CotenantReportBuilder::CotenantReportBuilder(double origin_mono_s) {
  r_.origin_mono_s = origin_mono_s;
}

Status CotenantReportBuilder::Add(const nlohmann::json& e) {
  // A field of the wrong type would throw from nlohmann's accessors: turned into a value here,
  // since this runs on the supervisor's thread.
  try {
    return AddEvent(e);
  } catch (const nlohmann::json::exception& ex) {
    return InvalidArgument(std::string("co-tenant event ") + e.dump() + ": " + ex.what());
  }
}

Status CotenantReportBuilder::AddEvent(const nlohmann::json& e) {
  if (!e.is_object() || !e.contains("event") || !e["event"].is_string()) {
    return InvalidArgument("co-tenant event without an \"event\" name: " + e.dump());
  }
  const std::string ev = e["event"].get<std::string>();
  const double origin = r_.origin_mono_s;
  auto rel = [&](const char* key) { return Num(e, key) - origin; };
  auto sizes = [&]() {
    if (e.contains("model")) r_.model = Str(e, "model");
    if (e.contains("device_scale")) r_.device_scale = Num(e, "device_scale");
    if (e.contains("model_weights_bytes")) r_.model_weights_bytes = U64(e, "model_weights_bytes");
    if (e.contains("weights_bytes")) r_.weights_bytes = U64(e, "weights_bytes");
    if (e.contains("kv_reserved_bytes")) r_.kv_reserved_bytes = U64(e, "kv_reserved_bytes");
    if (e.contains("request_kv_bytes")) r_.request_kv_bytes = U64(e, "request_kv_bytes");
    if (e.contains("context_tokens"))
      r_.context_tokens = static_cast<std::uint32_t>(U64(e, "context_tokens"));
    if (e.contains("watchdog_s")) r_.watchdog_s = Num(e, "watchdog_s");
  };
  auto record = [&](bool ok) {
    CotenantRequestRecord q;
    q.id = U64(e, "id");
    q.instance = instance_;
    q.pid = static_cast<std::int64_t>(Num(e, "pid"));
    q.ok = ok;
    q.reason = Str(e, "reason");
    q.submitted_s = e.contains("submitted_s") ? rel("submitted_s") : 0.0;
    q.started_s = e.contains("started_s") ? rel("started_s") : 0.0;
    q.ended_s = e.contains("ended_s") ? rel("ended_s") : rel("mono_s");
    q.tokens_per_s = Num(e, "tokens_per_s");
    q.prefill_tokens_per_s = Num(e, "prefill_tokens_per_s");
    q.latency_ms = Num(e, "latency_ms");
    q.queue_ms = Num(e, "queue_ms");
    q.kv_bytes = U64(e, "kv_bytes");
    q.kv_resident_bytes = U64(e, "kv_resident_bytes");
    q.major_faults = U64(e, "major_faults");
    q.minor_faults = U64(e, "minor_faults");
    q.max_token_gap_ms = Num(e, "max_token_gap_ms");
    q.stalls = static_cast<std::uint32_t>(U64(e, "stalls"));
    if (r_.per_request.size() < kMaxRecords) r_.per_request.push_back(std::move(q));
  };
  if (ev == "spawn") {
    instance_ = static_cast<std::uint32_t>(U64(e, "instance"));
    if (instance_ > 0) ++r_.restarts;
  } else if (ev == "start") {
    ++r_.starts;
    sizes();
    r_.weights_path = Str(e, "weights_path");
    r_.weights_load = Str(e, "weights_load");
    r_.weights = e.contains("weights") ? Str(e, "weights") : r_.weights_load;
    r_.lock_error = e.contains("mlock_error") ? Str(e, "mlock_error") : std::string();
    r_.kv_allocation = Str(e, "kv_allocation");
    r_.file_backed = Bool(e, "file_backed");
    r_.evictable = Bool(e, "evictable");
    r_.load_ms = Num(e, "load_ms");
    if (Bool(e, "weights_file_created")) r_.weights_create_ms = Num(e, "weights_create_ms");
  } else if (ev == "weights_file") {
    r_.weights_path = Str(e, "weights_path");
    if (Bool(e, "weights_file_created")) r_.weights_create_ms = Num(e, "weights_create_ms");
  } else if (ev == "failed_to_start") {
    ++r_.failed_starts;
    sizes();
    r_.start_failure = Str(e, "reason");
  } else if (ev == "request") {
    ++r_.requests;
    r_.tokens_generated += U64(e, "answer_tokens");
    r_.major_faults += U64(e, "major_faults");
    r_.decode_ms_total += Num(e, "decode_ms");
    tps_.Add(Num(e, "tokens_per_s"));
    prefill_tps_.Add(Num(e, "prefill_tokens_per_s"));
    latency_.Add(Num(e, "latency_ms"));
    record(true);
  } else if (ev == "request_failed") {
    if (Bool(e, "unfinished")) {
      ++r_.requests_unfinished;
    } else {
      ++r_.requests_failed;
    }
    record(false);
  } else if (ev == "stall") {
    ++r_.stalls;
  } else if (ev == "exit") {
    const std::string kind = Str(e, "kind");
    if (kind == "killed") ++r_.kills;
    if (kind == "crashed") ++r_.crashes;
  } else if (ev == "end") {
    r_.checksum ^= U64(e, "checksum");
  }
  return Status::Ok();
}

Status CotenantReportBuilder::AddLine(std::string_view line) {
  const nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    return InvalidArgument("co-tenant event line is not JSON: " + std::string(line.substr(0, 200)));
  }
  return Add(j);
}

CotenantResult CotenantReportBuilder::Report() const {
  CotenantResult r = r_;
  r.tokens_per_s = tps_.Quantile(0.5);
  r.prefill_tokens_per_s = prefill_tps_.Quantile(0.5);
  r.latency_ms_p50 = latency_.Quantile(0.5);
  r.latency_ms_p95 = latency_.Quantile(0.95);
  r.latency_ms_mean = latency_.mean();
  r.tokens_per_s_aggregate =
      r.decode_ms_total > 0.0 ? static_cast<double>(r.tokens_generated) * 1000.0 / r.decode_ms_total
                              : 0.0;
  OutcomeDecision d = DecideCotenantOutcome(r);
  r.outcome = d.outcome;
  r.reason = std::move(d.reason);
  return r;
}

// ---- JSON ----

nlohmann::json ToJson(const CotenantRequestRecord& q) {
  return {{"id", q.id},
          {"instance", q.instance},
          {"pid", q.pid},
          {"ok", q.ok},
          {"reason", q.reason},
          {"submitted_s", q.submitted_s},
          {"started_s", q.started_s},
          {"ended_s", q.ended_s},
          {"tokens_per_s", q.tokens_per_s},
          {"prefill_tokens_per_s", q.prefill_tokens_per_s},
          {"latency_ms", q.latency_ms},
          {"queue_ms", q.queue_ms},
          {"kv_bytes", q.kv_bytes},
          {"kv_resident_bytes", q.kv_resident_bytes},
          {"major_faults", q.major_faults},
          {"minor_faults", q.minor_faults},
          {"max_token_gap_ms", q.max_token_gap_ms},
          {"stalls", q.stalls}};
}

nlohmann::json ToJson(const CotenantResult& r) {
  using nlohmann::json;
  const bool have_rates = r.requests > 0;
  json j = {
      {"stand_in", true},
      {"note", r.note},
      {"model", r.model},
      {"device_scale", r.device_scale},
      {"model_weights_bytes", r.model_weights_bytes},
      {"weights_bytes", r.weights_bytes},
      {"kv_reserved_bytes", r.kv_reserved_bytes},
      {"request_kv_bytes", r.request_kv_bytes},
      {"context_tokens", r.context_tokens},
      {"weights_path", r.weights_path},
      {"weights", r.weights},
      {"weights_lock_error", r.lock_error},
      {"weights_load", r.weights_load},
      {"kv_allocation", r.kv_allocation},
      {"file_backed", r.file_backed},
      {"evictable", r.evictable},
      {"load_ms", r.load_ms},
      {"weights_create_ms", r.weights_create_ms},
      {"origin_mono_s", r.origin_mono_s},
      {"watchdog_s", r.watchdog_s},
      {"outcome", std::string(CotenantOutcomeName(r.outcome))},
      {"outcome_symbol", std::string(CotenantOutcomeSymbol(r.outcome))},
      {"reason", r.reason},
      {"starts", r.starts},
      {"failed_starts", r.failed_starts},
      {"kills", r.kills},
      {"crashes", r.crashes},
      {"restarts", r.restarts},
      {"stalls", r.stalls},
      {"requests", r.requests},
      {"requests_completed", r.requests},
      {"requests_failed", r.requests_failed},
      {"requests_unfinished", r.requests_unfinished},
      {"tokens_generated", r.tokens_generated},
      {"major_faults", r.major_faults},
      {"tokens_per_s", have_rates ? json(r.tokens_per_s) : json(nullptr)},
      {"tokens_per_s_aggregate", have_rates ? json(r.tokens_per_s_aggregate) : json(nullptr)},
      {"decode_ms_total", r.decode_ms_total},
      {"prefill_tokens_per_s", have_rates ? json(r.prefill_tokens_per_s) : json(nullptr)},
      {"latency_ms",
       have_rates
           ? json{{"p50", r.latency_ms_p50}, {"p95", r.latency_ms_p95}, {"mean", r.latency_ms_mean}}
           : json(nullptr)},
      {"checksum", r.checksum},
  };
  // Built element by element: converting a vector of arrays in one go trips GCC 12's -O3
  // -Wnull-dereference false positive inside nlohmann's to_json (aarch64).
  json per = json::array();
  json detail = json::array();
  for (const CotenantRequestRecord& q : r.per_request) {
    if (q.ok) per.push_back(json::array({q.ended_s, q.tokens_per_s, q.latency_ms}));
    detail.push_back(ToJson(q));
  }
  j["per_request"] = std::move(per);
  j["requests_detail"] = std::move(detail);
  return j;
}

double MonotonicSeconds() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

}  // namespace zm
