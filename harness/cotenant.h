// Co-tenant STAND-IN: a stand-in for a VLM served by llama.cpp / Ollama beside the map, not a
// model. It behaves like one where memory is concerned:
//   - weights in a file (weights_file.h), mapped read-only and shared, so they are page cache the
//     kernel may evict under pressure and refault later, costing tokens/s (or read into process
//     memory, as Ollama's own engine does);
//   - a KV cache in anonymous memory sized from the model's architecture (bytes per token of
//     context, CotenantModel), reserved for n_ctx tokens at start-up and touched as each
//     request's context grows;
//   - a request = prompt processing (one pass over all the weights per prompt_batch_tokens
//     tokens) then decode, one pass over ALL the weights (and the KV cache so far) per generated
//     token: memory-bandwidth bound like real decode.
//
// Outcomes are measured, never ruled (the paper's Table II symbols, plus killed):
//   × failed to start: the weights could not be mapped or the KV cache not allocated (or the
//     device ledger refused the weights);
//   † killed: the process died by a signal it did not ask for (SIGKILL: an OOM kill);
//   △ stalled: the watchdog saw no token for [cotenant] watchdog_s inside a request (or
//     requests were submitted and none completed);
//   ○ completed: otherwise.
// DecideCotenantOutcome() is the one place that turns the counts into an outcome.
//
// The program (app/zonemap_cotenant.cc) streams one JSON line per event as it happens ("start",
// "failed_to_start", "request", "request_failed", "stall", "end"), so a supervisor
// (cotenant_supervisor.h) has every completed request up to a kill. CotenantReportBuilder folds
// those lines into a CotenantResult, the same way in-process and across restarts.
//
// Invariants: every output (event lines, ToJson, the program's text) says "stand-in"; the
// device scale is in every line and report; RunCotenant releases the weights, the KV cache and
// any ledger grant before it returns.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "harness/cotenant_options.h"
#include "runtime/streaming_stats.h"

namespace zm {

struct ExperimentProfile;
class DeviceModel;  // harness/device_model.h

inline constexpr std::string_view kCotenantNote =
    "stand-in for VLM decoding: weights read from a file (pinned in memory, or mmap'ed) and "
    "streamed once per generated token (memory-bandwidth bound), a KV cache read with the "
    "context; not a real model";

// The paper's models: weight sizes as the paper gives them (decimal GB) and the KV cache's
// geometry at f16 (llama.cpp's and Ollama's default cache type), from each model's config.json
// (docs/harness.md lists the numbers and their sources). KV bytes at context c:
//   state_bytes + c * kv_bytes_per_token + min(c, window_tokens) * window_bytes_per_token.
struct CotenantModel {
  std::string_view name;     // "qwen3-vl-2b"
  std::string_view display;  // "qwen3-vl 2B"
  std::uint64_t weights_bytes = 0;
  std::uint64_t kv_bytes_per_token = 0;      // layers attending over the whole context
  std::uint64_t window_bytes_per_token = 0;  // sliding-window layers (gemma3: 5 of 6)
  std::uint32_t window_tokens = 0;
  std::uint64_t state_bytes = 0;  // fixed per sequence (linear-attention state)
};
[[nodiscard]] std::span<const CotenantModel> CotenantModels();
[[nodiscard]] Result<CotenantModel> FindCotenantModel(std::string_view name);
[[nodiscard]] std::string CotenantModelNames();  // "qwen3-vl-2b, qwen3-vl-4b, ..."

// KV cache bytes of `model` holding `context_tokens` tokens, unscaled.
[[nodiscard]] std::uint64_t KvCacheBytes(const CotenantModel& model, std::uint64_t context_tokens);

enum class CotenantOutcome { kCompleted, kStalled, kFailedToStart, kKilled };
// "completed", "stalled", "failed_to_start", "killed" (summary.json's cotenant.outcome).
[[nodiscard]] std::string_view CotenantOutcomeName(CotenantOutcome o);
// "○", "△", "×", "†" (killed).
[[nodiscard]] std::string_view CotenantOutcomeSymbol(CotenantOutcome o);

struct CotenantConfig {
  std::string model = "qwen3-vl-2b";  // the model table's name (for the KV geometry)
  std::uint64_t weights_bytes = 0;    // 0 = the model table's size
  double device_scale = 1.0;          // 0 < S <= 1: multiplies weights and KV cache together
  CotenantOptions options;            // [cotenant]
  // Self-paced requests (the program without --serve): this many (0 = until stopped), one every
  // options.request_period_s.
  std::uint32_t requests = 5;
  std::string ledger_path;                // empty = no device ledger (the portable fallback's)
  std::uint64_t ledger_device_bytes = 0;  // creates the ledger if absent; 0 = attach only
  std::string ledger_name;                // tenant name; empty = "cotenant:<model>"
};

// [model] (name, weights) + [cotenant] of a profile; requests and ledger left at their defaults.
[[nodiscard]] CotenantConfig CotenantConfigFromProfile(const ExperimentProfile& profile);
// KV cache bytes the co-tenant reserves at start-up for options.context_tokens, at device scale 1
// (the number the map's memory split would plan for). Errors as ResolveCotenantSizes.
[[nodiscard]] Result<std::uint64_t> CotenantKvReserveBytes(const CotenantConfig& config);

// The sizes a configuration resolves to, device scale applied.
struct CotenantSizes {
  CotenantModel model;                    // table entry (or one built from the overrides)
  std::uint64_t model_weights_bytes = 0;  // before scaling
  std::uint64_t weights_bytes = 0;        // scaled, whole pages
  std::uint64_t kv_reserved_bytes = 0;    // scaled KV cache for context_tokens
  std::uint64_t request_kv_bytes = 0;     // scaled KV cache for prompt + answer
  // The watchdog at this scale: options.watchdog_s x device_scale. A pass streams the weights,
  // which scale with S, so a token takes S times as long as at full size and a gap of W seconds
  // at full size is a gap of W x S seconds here: the same number of token times (docs/harness.md).
  double watchdog_s = 0.0;
};
// Errors: unknown model without a kv_bytes_per_token override, device scale outside (0, 1],
// zero answer or batch tokens, prompt + answer above context_tokens.
[[nodiscard]] Result<CotenantSizes> ResolveCotenantSizes(const CotenantConfig& config);
// Scaled KV bytes at `context_tokens` (the one formula RunCotenant and the reports use).
[[nodiscard]] std::uint64_t ScaledKvBytes(const CotenantSizes& sizes, double device_scale,
                                          std::uint64_t context_tokens);

// One request, as the report keeps it. Times are seconds since the report's origin (the
// supervisor's start, or RunCotenant's).
struct CotenantRequestRecord {
  std::uint64_t id = 0;
  std::uint32_t instance = 0;  // which start of the process served it (0 = first)
  std::int64_t pid = 0;
  bool ok = false;  // completed; false = failed (reason says why)
  std::string reason;
  double submitted_s = 0.0;
  double started_s = 0.0;
  double ended_s = 0.0;
  double tokens_per_s = 0.0;  // decode
  double prefill_tokens_per_s = 0.0;
  double latency_ms = 0.0;              // started -> ended
  double queue_ms = 0.0;                // submitted -> started
  std::uint64_t kv_bytes = 0;           // KV cache at the end of the request (scaled)
  std::uint64_t kv_resident_bytes = 0;  // of it, resident (mincore) at the end of the request
  std::uint64_t major_faults = 0;       // during the request (refaulted weights show here)
  std::uint64_t minor_faults = 0;
  double max_token_gap_ms = 0.0;
  std::uint32_t stalls = 0;  // watchdog events inside this request
};

// What a co-tenant run measured (one process, or every instance a supervisor started).
struct CotenantResult {
  std::string note{kCotenantNote};
  std::string model;
  double device_scale = 1.0;
  std::uint64_t model_weights_bytes = 0;
  std::uint64_t weights_bytes = 0;      // scaled, as mapped
  std::uint64_t kv_reserved_bytes = 0;  // scaled KV cache for context_tokens
  std::uint64_t request_kv_bytes = 0;   // scaled KV cache of one request
  std::uint32_t context_tokens = 0;
  std::string weights_path;
  // pinned | pinned_refused (the lock was refused: the memory is ordinary anonymous memory) |
  // mmap | read: where the last start's weights and KV cache lived.
  std::string weights;
  std::string lock_error;     // why a pinned start's mlock was refused (empty otherwise)
  std::string weights_load;   // the mechanism: "mmap" | "read"
  std::string kv_allocation;  // "per_request" | "at_load"
  bool file_backed = false;
  bool evictable = false;
  double load_ms = 0.0;            // last start's weights load
  double weights_create_ms = 0.0;  // > 0 when a start created the weights file
  double origin_mono_s = 0.0;      // CLOCK_MONOTONIC of t = 0 in the records
  double watchdog_s = 0.0;
  std::string start_failure;  // why the last failed start failed

  CotenantOutcome outcome = CotenantOutcome::kFailedToStart;
  std::string reason;        // why it is not ○; empty when completed
  std::uint32_t starts = 0;  // instances that started (weights + KV in memory)
  std::uint32_t failed_starts = 0;
  std::uint32_t kills = 0;     // deaths by SIGKILL
  std::uint32_t crashes = 0;   // other unexpected deaths
  std::uint32_t restarts = 0;  // spawns after the first
  std::uint32_t stalls = 0;    // watchdog events
  std::uint32_t requests_submitted = 0;
  std::uint32_t requests = 0;             // completed
  std::uint32_t requests_failed = 0;      // refused, lost to a death, or the service was down
  std::uint32_t requests_unfinished = 0;  // in flight when the run was stopped
  std::uint64_t tokens_generated = 0;
  std::uint64_t major_faults = 0;  // over completed requests
  double decode_ms_total = 0.0;    // decode wall time summed over completed requests
  double tokens_per_s = 0.0;       // median decode rate over completed requests
  // Every completed request's answer tokens over their decode time together (tokens_generated /
  // decode_ms_total): slow requests weigh by how long they took, as a user waiting sees them.
  double tokens_per_s_aggregate = 0.0;
  double latency_ms_mean = 0.0;
  double prefill_tokens_per_s = 0.0;  // median
  double latency_ms_p50 = 0.0;
  double latency_ms_p95 = 0.0;
  std::uint64_t checksum = 0;  // the passes' reduction (keeps them from being elided)
  std::vector<CotenantRequestRecord> per_request;  // every request, completed or failed
};

// The outcome of the counts in `r` (r.outcome and r.reason are ignored and not changed).
struct OutcomeDecision {
  CotenantOutcome outcome;
  std::string reason;
};
[[nodiscard]] OutcomeDecision DecideCotenantOutcome(const CotenantResult& r);

// Folds event lines (the program's, and the supervisor's own) into a CotenantResult.
class CotenantReportBuilder {
 public:
  static constexpr std::size_t kMaxRecords = 100'000;  // bounded however long it runs

  explicit CotenantReportBuilder(double origin_mono_s = 0.0);
  // One event object (a parsed line). Unknown events are ignored; malformed ones are an error.
  Status Add(const nlohmann::json& event);
  // Parses and adds one line.
  Status AddLine(std::string_view line);
  // The result so far, with quantiles and the outcome decided.
  [[nodiscard]] CotenantResult Report() const;
  [[nodiscard]] const CotenantResult& partial() const noexcept { return r_; }

 private:
  Status AddEvent(const nlohmann::json& event);

  CotenantResult r_;
  StreamingStats tps_, prefill_tps_, latency_;
  std::uint32_t instance_ = 0;  // the latest "spawn" event's
};

// Feeds requests to RunCotenant. Blocks until the next request; false = no more requests.
struct CotenantTicket {
  std::uint64_t id = 0;
  double submitted_mono_s = 0.0;
};
struct CotenantHooks {
  // Every event line, in order (calls are serialized). Default: none.
  std::function<void(std::string_view line)> emit;
  // Before anything is mapped: false = do not start (stopped). Default: start at once.
  std::function<bool()> await_start;
  // Default: config.requests requests, one every options.request_period_s.
  std::function<bool(CotenantTicket&)> next_request;
};

// Runs the stand-in in the calling thread until the requests run out or *stop is set (checked
// between passes). Never throws; a start-up failure is the kFailedToStart outcome.
[[nodiscard]] CotenantResult RunCotenant(const CotenantConfig& config,
                                         const std::atomic<bool>* stop = nullptr,
                                         CotenantHooks hooks = {});

// {"stand_in": true, "note", "model", "device_scale", "weights_bytes", "tokens_per_s",
// "tokens_per_s_aggregate", "decode_ms_total", "latency_ms": {"p50", "p95", "mean"}, "requests",
// "outcome", "outcome_symbol", "per_request": [[end s, tokens/s, latency ms]...],
// "requests_detail": [...], ...}; rates are null without a completed request.
[[nodiscard]] nlohmann::json ToJson(const CotenantResult& result);
[[nodiscard]] nlohmann::json ToJson(const CotenantRequestRecord& record);

// One co-tenant child process (the zonemap-cotenant program streaming JSON lines on stdout).
// Move-only; the destructor stops (SIGTERM) and reaps a child still running.
class CotenantProcess {
 public:
  CotenantProcess() = default;
  CotenantProcess(CotenantProcess&& other) noexcept;
  CotenantProcess& operator=(CotenantProcess&& other) noexcept;
  CotenantProcess(const CotenantProcess&) = delete;
  CotenantProcess& operator=(const CotenantProcess&) = delete;
  ~CotenantProcess();

  // Starts `executable` (empty = FindCotenantExecutable()) with CotenantCommandLine(config,
  // serve). serve = requests come as command lines on its stdin ("start", "request ID T", "stop");
  // otherwise it paces itself (config.requests, options.request_period_s) and starts at once.
  // device, when given, is entered by the child between fork and exec (SpawnInDevice): when it
  // cannot enter, the program never runs and the error (a failed start) says why.
  [[nodiscard]] static Result<CotenantProcess> Spawn(const CotenantConfig& config,
                                                     std::string executable = {},
                                                     bool serve = false,
                                                     const DeviceModel* device = nullptr);
  // SIGTERM: it stops between passes, writes its "end" line and exits 0.
  void RequestStop() noexcept;
  // Sends one command line (serve mode). False when the child no longer reads (it died).
  [[nodiscard]] bool SendLine(std::string_view line) noexcept;
  // Reads what the child wrote within timeout_ms; appends complete lines. False at end of file
  // (the child closed stdout: it is exiting).
  [[nodiscard]] bool ReadLines(std::vector<std::string>& lines, int timeout_ms);
  // Waits for the child to exit (SIGKILL after timeout_s) and returns its wait status.
  [[nodiscard]] int Reap(double timeout_s);
  // Reads every line to the end, reaps, and folds them: the result of a self-paced child. A
  // death by a signal is recorded (kills/crashes) like the supervisor does.
  [[nodiscard]] Result<CotenantResult> Wait();
  [[nodiscard]] pid_t pid() const noexcept { return pid_; }
  [[nodiscard]] int stdout_fd() const noexcept { return out_fd_; }

 private:
  void Reset() noexcept;  // stop, reap, close: the state of a default-constructed object

  pid_t pid_ = -1;
  int out_fd_ = -1;      // the child's stdout (read end of a pipe)
  int in_fd_ = -1;       // the child's stdin (a socket, so a dead reader is EPIPE, not SIGPIPE)
  std::string partial_;  // a line not yet complete
  double spawned_mono_s_ = 0.0;
};

// How a reaped child ended, as the reports count it.
struct CotenantExit {
  std::string_view kind;  // "exited", "killed" (SIGKILL), "crashed" (another signal)
  int code = 0;           // exit code, or the signal number
};
[[nodiscard]] CotenantExit ClassifyCotenantExit(int wait_status);

// Arguments (without argv[0]) that make `zonemap-cotenant` run `config` and stream JSON lines.
[[nodiscard]] std::vector<std::string> CotenantCommandLine(const CotenantConfig& config,
                                                           bool serve = false);
// $ZM_COTENANT_EXE, else zonemap-cotenant next to this executable or in ../app/, else the bare
// name (looked up in PATH).
[[nodiscard]] std::string FindCotenantExecutable();

// CLOCK_MONOTONIC in seconds: the clock every event line carries (same for every process).
[[nodiscard]] double MonotonicSeconds() noexcept;

}  // namespace zm
