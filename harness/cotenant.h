// Co-tenant STAND-IN: a stand-in for a VLM/LLM decoding beside the map, not a model. It
// allocates model-sized weights, faults them in, then serves requests of a fixed prompt and
// answer length. Each generated token streams ALL the weights once (a dependent reduction over
// every 64-bit word), so, like real LLM decode, it is memory-bandwidth bound; the prompt is
// processed in batches, one pass over the weights per prompt_batch_tokens tokens (batched
// prefill reuses each weight for many tokens). It reports decode tokens/s and request latency.
//
// Outcomes (the paper's Table II symbols), decided in this order:
//   × failed to start: the device ledger refused to register weights + overhead, or the
//     weights could not be mapped (process cap, out of memory).
//   △ stalled: it started but could not make steady progress: the ledger counted an
//     out-of-memory event while it ran, or a request missed request_deadline_s, or it was
//     stopped before completing any request. While the ledger says the device is
//     over-committed (some tenant's refused demand would exceed the device), the stand-in waits
//     (on a real device it would be paging or reclaimed) and the wait counts as stall time.
//   ○ completed: otherwise.
//
// Invariants: every output (ToJson, the program's text) says "stand-in"; weights are released
// and the ledger grant returned before RunCotenant() returns.
#pragma once

#include <sys/types.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "common/status.h"

namespace zm {

struct ExperimentProfile;

inline constexpr std::string_view kCotenantNote =
    "stand-in for VLM decoding: streams model-sized weights once per generated token "
    "(memory-bandwidth bound); not a real model";

// The paper's models and their weight sizes (decimal GB, as the paper gives them).
struct CotenantModel {
  std::string_view name;     // "qwen3-vl-2b"
  std::string_view display;  // "qwen3-vl 2B"
  std::uint64_t weights_bytes = 0;
};
[[nodiscard]] std::span<const CotenantModel> CotenantModels();
[[nodiscard]] Result<CotenantModel> FindCotenantModel(std::string_view name);
[[nodiscard]] std::string CotenantModelNames();  // "qwen3-vl-2b, qwen3-vl-4b, ..."

enum class CotenantOutcome { kCompleted, kStalled, kFailedToStart };
[[nodiscard]] std::string_view CotenantOutcomeName(CotenantOutcome o);    // "completed", ...
[[nodiscard]] std::string_view CotenantOutcomeSymbol(CotenantOutcome o);  // "○", "△", "×"

struct CotenantConfig {
  std::string model = "qwen3-vl-2b";
  std::uint64_t weights_bytes = 0;   // 0 = the model table's size
  std::uint64_t overhead_bytes = 0;  // KV cache / activations, allocated and touched too
  double scale = 1.0;                // multiplies weights and overhead (tests, CI)
  std::uint32_t prompt_tokens = 256;
  std::uint32_t answer_tokens = 64;
  std::uint32_t prompt_batch_tokens = 64;
  std::uint32_t requests = 5;        // 0 = serve until stopped
  double request_period_s = 0.0;     // start a request every period; 0 = back to back
  double request_deadline_s = 0.0;   // 0 = no deadline
  std::string ledger_path;           // empty = no device ledger
  std::uint64_t ledger_device_bytes = 0;  // creates the ledger if absent; 0 = attach only
  std::string ledger_name;           // tenant name; empty = "cotenant:<model>"
};

// The [cotenant] section of a profile (ledger and request count left at their defaults).
[[nodiscard]] CotenantConfig CotenantConfigFromProfile(const ExperimentProfile& profile);

struct CotenantResult {
  std::string model;
  std::uint64_t model_weights_bytes = 0;  // the table's (or given) size before scaling
  double scale = 1.0;
  std::uint64_t weights_bytes = 0;        // actually allocated
  std::uint64_t overhead_bytes = 0;
  CotenantOutcome outcome = CotenantOutcome::kFailedToStart;
  std::string reason;                     // why it failed or stalled; empty when completed
  std::uint32_t requests = 0;             // completed requests
  std::uint32_t requests_late = 0;        // missed the deadline (or abandoned waiting)
  std::uint64_t tokens_generated = 0;
  double tokens_per_s = 0.0;              // median decode rate over completed requests
  double prefill_tokens_per_s = 0.0;      // median
  double latency_ms_p50 = 0.0;            // request latency
  double latency_ms_p95 = 0.0;
  double stream_gbps = 0.0;               // median bytes streamed per second while decoding
  double touch_ms = 0.0;                  // faulting the weights in
  double stall_ms = 0.0;                  // waited while the device was over-committed
  std::uint64_t oom_events_seen = 0;      // ledger OOM events (any tenant) while running
  std::uint64_t checksum = 0;             // the reduction's result (keeps it from being elided)
  // Every completed request: {seconds since the first request started, decode tokens/s,
  // latency ms}; for distributions and for values along the robot's path.
  std::vector<std::array<double, 3>> per_request;
  std::string note{kCotenantNote};
};

// Runs the stand-in in the calling thread until `requests` are served or *stop is set
// (checked between tokens). Never throws; a start-up failure is the kFailedToStart outcome.
[[nodiscard]] CotenantResult RunCotenant(const CotenantConfig& config,
                                         const std::atomic<bool>* stop = nullptr);

// {"stand_in": true, "note", "model", "weights_bytes", "tokens_per_s", "latency_ms": {"p50",
// "p95"}, "requests", "outcome", "outcome_symbol", ...}; rates and latencies are null when the
// stand-in failed to start or completed nothing.
[[nodiscard]] nlohmann::json ToJson(const CotenantResult& result);
[[nodiscard]] Result<CotenantResult> CotenantResultFromJson(const nlohmann::json& json);

// The stand-in on its own thread of this process. Its weights count against this process's
// memory (and any RLIMIT_AS/RLIMIT_DATA cap): beside a capped map process use CotenantProcess.
class CotenantThread {
 public:
  CotenantThread() = default;
  CotenantThread(CotenantThread&&) = delete;
  CotenantThread& operator=(CotenantThread&&) = delete;
  ~CotenantThread();  // requests a stop and joins

  // Starts it. kFailedPrecondition if already running.
  [[nodiscard]] Status Start(CotenantConfig config);
  void RequestStop() noexcept { stop_.store(true); }
  [[nodiscard]] bool done() const noexcept { return done_.load(); }
  // Waits for it to finish (call RequestStop() first to end an open-ended run).
  [[nodiscard]] Result<CotenantResult> Join();

 private:
  std::atomic<bool> stop_{false};
  std::atomic<bool> done_{false};
  CotenantResult result_;
  std::thread thread_;
};

// The stand-in as a child process (the `zonemap-cotenant` program with --json), so it has its
// own memory and the map process can be capped alone.
class CotenantProcess {
 public:
  CotenantProcess() = default;
  CotenantProcess(CotenantProcess&& other) noexcept;
  CotenantProcess& operator=(CotenantProcess&& other) noexcept;
  CotenantProcess(const CotenantProcess&) = delete;
  CotenantProcess& operator=(const CotenantProcess&) = delete;
  ~CotenantProcess();  // SIGTERM and reap if still running

  // Starts `executable` (empty = FindCotenantExecutable()) with CotenantCommandLine(config).
  [[nodiscard]] static Result<CotenantProcess> Spawn(const CotenantConfig& config,
                                                     std::string executable = {});
  // Asks the child to finish (SIGTERM: it stops between tokens and prints its results).
  void RequestStop() noexcept;
  // Reads the child's JSON result and reaps it.
  [[nodiscard]] Result<CotenantResult> Wait();
  [[nodiscard]] pid_t pid() const noexcept { return pid_; }

 private:
  pid_t pid_ = -1;
  int stdout_fd_ = -1;
};

// Arguments (without argv[0]) that make `zonemap-cotenant` run `config` and print JSON.
[[nodiscard]] std::vector<std::string> CotenantCommandLine(const CotenantConfig& config);
// $ZM_COTENANT_EXE, else zonemap-cotenant next to this executable or in ../app/, else the bare
// name (looked up in PATH).
[[nodiscard]] std::string FindCotenantExecutable();

}  // namespace zm
