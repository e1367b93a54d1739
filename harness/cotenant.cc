// Co-tenant stand-in: model table, the weight-streaming decode loop, outcome rules, and the two
// ways to run it beside the tick loop (thread, child process). Every output says "stand-in".
#include "harness/cotenant.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>

#include "harness/device_ledger.h"
#include "runtime/memory_cap.h"
#include "harness/experiment_profile.h"
#include "runtime/streaming_stats.h"

extern char** environ;

namespace zm {
namespace {

// Sizes as the paper gives them (decimal gigabytes).
constexpr std::array<CotenantModel, 5> kModels = {{
    {"qwen3-vl-2b", "qwen3-vl 2B", 1'900'000'000ULL},
    {"qwen3-vl-4b", "qwen3-vl 4B", 3'300'000'000ULL},
    {"qwen3.5-0.8b", "qwen3.5 0.8B", 1'000'000'000ULL},
    {"qwen3.5-2b", "qwen3.5 2B", 2'700'000'000ULL},
    {"gemma3-4b", "gemma3 4B", 3'300'000'000ULL},
}};

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

bool Stopped(const std::atomic<bool>* stop) {
  return stop != nullptr && stop->load(std::memory_order_relaxed);
}

// Sleeps up to `ms`, waking early when *stop is set.
void SleepFor(double ms, const std::atomic<bool>* stop) {
  if (!(ms > 0.0)) return;
  const auto until =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double, std::milli>(ms));
  while (!Stopped(stop) && Clock::now() < until) {
    const Clock::duration left = until - Clock::now();
    const Clock::duration step = std::chrono::milliseconds(5);
    std::this_thread::sleep_for(std::min(left, step));
  }
}

// Fills the weights with a cheap pseudo-random sequence (every page written: resident, not the
// shared zero page).
void TouchWeights(std::uint64_t* w, std::size_t words) {
  std::uint64_t x = 0x9E3779B97F4A7C15ULL;
  for (std::size_t i = 0; i < words; ++i) {
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    w[i] = x;
  }
}

// One pass over all the weights: the stand-in for one forward pass. Eight independent lanes so
// the loop is limited by memory bandwidth, not by an add chain; the result seeds the next pass
// and ends in the reported checksum, and the barrier stops the compiler from merging passes.
[[gnu::noinline]] std::uint64_t StreamPass(const std::uint64_t* w, std::size_t words,
                                           std::uint64_t seed) {
  std::uint64_t a[8] = {seed, 1, 2, 3, 4, 5, 6, 7};
  std::size_t i = 0;
  for (; i + 8 <= words; i += 8) {
    for (std::size_t k = 0; k < 8; ++k) a[k] += w[i + k];
  }
  for (; i < words; ++i) a[0] += w[i];
  std::uint64_t h = 0;
  for (std::uint64_t v : a) h = (h ^ v) * 0x100000001B3ULL;
  asm volatile("" : : "r"(h) : "memory");
  return h;
}

// What the run holds; released on every path out of RunCotenant.
struct Holdings {
  std::optional<DeviceLedger> ledger;
  LedgerTenant tenant;
  void* weights = nullptr;
  std::size_t weights_bytes = 0;
  void* overhead = nullptr;
  std::size_t overhead_bytes = 0;
  ~Holdings() {
    UnmapBytes(weights, weights_bytes);
    UnmapBytes(overhead, overhead_bytes);
    tenant.Release();
  }
};

std::uint64_t Scaled(std::uint64_t bytes, double scale) {
  const double v = std::round(static_cast<double>(bytes) * scale);
  return v <= 0.0 ? 0 : static_cast<std::uint64_t>(v);
}

}  // namespace

std::span<const CotenantModel> CotenantModels() { return kModels; }

Result<CotenantModel> FindCotenantModel(std::string_view name) {
  for (const CotenantModel& m : kModels) {
    if (m.name == name) return m;
  }
  return NotFound("unknown co-tenant model '" + std::string(name) + "' (known: " +
                  CotenantModelNames() + ")");
}

std::string CotenantModelNames() {
  std::string s;
  for (const CotenantModel& m : kModels) s += (s.empty() ? "" : ", ") + std::string(m.name);
  return s;
}

std::string_view CotenantOutcomeName(CotenantOutcome o) {
  switch (o) {
    case CotenantOutcome::kCompleted: return "completed";
    case CotenantOutcome::kStalled: return "stalled";
    case CotenantOutcome::kFailedToStart: return "failed to start";
  }
  return "unknown";
}

std::string_view CotenantOutcomeSymbol(CotenantOutcome o) {
  switch (o) {
    case CotenantOutcome::kCompleted: return "\u25cb";      // ○
    case CotenantOutcome::kStalled: return "\u25b3";        // △
    case CotenantOutcome::kFailedToStart: return "\u00d7";  // ×
  }
  return "?";
}

CotenantConfig CotenantConfigFromProfile(const ExperimentProfile& profile) {
  CotenantConfig c;
  c.model = profile.core.model.name;
  c.weights_bytes = profile.core.model.weights_bytes;
  c.overhead_bytes = profile.core.model.kv_cache_bytes;
  c.prompt_tokens = profile.cotenant.prompt_tokens;
  c.answer_tokens = profile.cotenant.answer_tokens;
  c.prompt_batch_tokens = profile.cotenant.prompt_batch_tokens;
  c.request_period_s = profile.cotenant.request_period_s;
  c.request_deadline_s = profile.cotenant.request_deadline_s;
  return c;
}

CotenantResult RunCotenant(const CotenantConfig& config, const std::atomic<bool>* stop) {
  CotenantResult r;
  r.model = config.model;
  r.scale = config.scale;
  r.outcome = CotenantOutcome::kFailedToStart;
  if (config.weights_bytes != 0) {
    r.model_weights_bytes = config.weights_bytes;
  } else if (Result<CotenantModel> m = FindCotenantModel(config.model); m.ok()) {
    r.model_weights_bytes = m->weights_bytes;
  } else {
    r.reason = m.status().message();
    return r;
  }
  if (!(config.scale > 0.0) || config.answer_tokens == 0 || config.prompt_batch_tokens == 0) {
    r.reason = "bad configuration: scale, answer_tokens and prompt_batch_tokens must be positive";
    return r;
  }
  r.weights_bytes = std::max<std::uint64_t>(Scaled(r.model_weights_bytes, config.scale) / 8 * 8, 8);
  r.overhead_bytes = Scaled(config.overhead_bytes, config.scale);

  Holdings hold;
  std::uint64_t oom0 = 0;  // ledger OOM events before this tenant existed
  if (!config.ledger_path.empty()) {
    Result<DeviceLedger> ledger = DeviceLedger::Open(config.ledger_path, config.ledger_device_bytes);
    if (!ledger.ok()) {
      r.reason = ledger.status().message();
      return r;
    }
    hold.ledger.emplace(std::move(ledger).value());
    // Sampled before registering: another tenant may be refused the moment our grant is
    // visible, before this thread runs again (seen under qemu), and that event is ours to see.
    oom0 = hold.ledger->oom_events();
    std::string name = config.ledger_name.empty() ? "cotenant:" + config.model : config.ledger_name;
    if (name.size() >= kLedgerNameBytes) name.resize(kLedgerNameBytes - 1);
    Result<LedgerTenant> tenant = hold.ledger->Register(name, r.weights_bytes + r.overhead_bytes);
    if (!tenant.ok()) {
      r.reason = "weights do not fit: " + tenant.status().message();
      return r;
    }
    hold.tenant = std::move(tenant).value();
  }
  const auto touch0 = Clock::now();
  hold.weights = TryMapBytes(r.weights_bytes);
  if (hold.weights == nullptr) {
    r.reason = "allocating " + FormatBytes(r.weights_bytes) +
               " of weights failed (process cap or out of memory)";
    return r;
  }
  hold.weights_bytes = r.weights_bytes;
  if (r.overhead_bytes != 0) {
    hold.overhead = TryMapBytes(r.overhead_bytes);
    if (hold.overhead == nullptr) {
      r.reason = "allocating " + FormatBytes(r.overhead_bytes) +
                 " of KV cache/activations failed (process cap or out of memory)";
      return r;
    }
    hold.overhead_bytes = r.overhead_bytes;
    std::memset(hold.overhead, 0x5A, r.overhead_bytes);
  }
  auto* w = static_cast<std::uint64_t*>(hold.weights);
  const std::size_t words = r.weights_bytes / 8;
  TouchWeights(w, words);
  r.touch_ms = MsSince(touch0);

  const std::uint32_t prefill_passes =
      (config.prompt_tokens + config.prompt_batch_tokens - 1) / config.prompt_batch_tokens;
  const double deadline_ms = config.request_deadline_s * 1000.0;
  // Per-request samples kept for the distributions (the summaries come from StreamingStats).
  const std::size_t keep = config.requests == 0 ? 1024 : config.requests;
  StreamingStats tps, prefill_tps, latency, gbps;
  std::uint64_t h = 0;
  bool abandoned = false;
  const auto run0 = Clock::now();
  for (std::uint32_t req = 0; config.requests == 0 || req < config.requests; ++req) {
    if (config.request_period_s > 0.0) {
      SleepFor(static_cast<double>(req) * config.request_period_s * 1000.0 - MsSince(run0), stop);
    }
    if (Stopped(stop)) break;
    const auto t0 = Clock::now();
    bool late = false;
    // Waits while the device is over-committed. False if the request must be abandoned.
    auto wait_for_memory = [&]() {
      if (!hold.ledger || !hold.ledger->OverCommitted()) return true;
      const auto w0 = Clock::now();
      while (hold.ledger->OverCommitted() && !Stopped(stop)) {
        if (deadline_ms > 0.0 && MsSince(t0) > deadline_ms) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      r.stall_ms += MsSince(w0);
      return !hold.ledger->OverCommitted();
    };
    bool ok = true;
    for (std::uint32_t p = 0; p < prefill_passes && ok; ++p) {
      ok = wait_for_memory() && !Stopped(stop);
      if (ok) h = StreamPass(w, words, h);
    }
    const double prefill_ms = MsSince(t0);
    const auto d0 = Clock::now();
    std::uint32_t generated = 0;
    for (; generated < config.answer_tokens && ok; ++generated) {
      ok = wait_for_memory() && !Stopped(stop);
      if (ok) h = StreamPass(w, words, h + generated);
    }
    if (!ok) {
      if (Stopped(stop)) break;  // stopped mid-request: not a request at all
      ++r.requests_late;       // gave up waiting for memory past the deadline
      abandoned = true;
      break;
    }
    const double decode_ms = MsSince(d0);
    const double total_ms = MsSince(t0);
    r.tokens_generated += generated;
    ++r.requests;
    if (deadline_ms > 0.0 && total_ms > deadline_ms) late = true;
    if (late) ++r.requests_late;
    latency.Add(total_ms);
    tps.Add(decode_ms > 0.0 ? generated * 1000.0 / decode_ms : 0.0);
    if (r.per_request.size() < keep) {
      r.per_request.push_back({MsSince(run0) / 1000.0,
                               decode_ms > 0.0 ? generated * 1000.0 / decode_ms : 0.0, total_ms});
    }
    prefill_tps.Add(prefill_ms > 0.0 ? config.prompt_tokens * 1000.0 / prefill_ms : 0.0);
    gbps.Add(decode_ms > 0.0
                 ? static_cast<double>(r.weights_bytes) * generated / (decode_ms * 1e6)
                 : 0.0);
  }
  r.checksum = h;
  r.oom_events_seen = hold.ledger ? hold.ledger->oom_events() - oom0 : 0;
  r.latency_ms_p50 = latency.Quantile(0.5);
  r.latency_ms_p95 = latency.Quantile(0.95);
  r.tokens_per_s = tps.Quantile(0.5);
  r.prefill_tokens_per_s = prefill_tps.Quantile(0.5);
  r.stream_gbps = gbps.Quantile(0.5);

  if (r.oom_events_seen > 0) {
    r.outcome = CotenantOutcome::kStalled;
    r.reason = std::to_string(r.oom_events_seen) +
               " out-of-memory event(s) on the device ledger while it ran";
  } else if (abandoned) {
    r.outcome = CotenantOutcome::kStalled;
    r.reason = "a request waited past its deadline for an over-committed device";
  } else if (r.requests_late > 0) {
    r.outcome = CotenantOutcome::kStalled;
    r.reason = std::to_string(r.requests_late) + " request(s) missed the " +
               std::to_string(config.request_deadline_s) + " s deadline";
  } else if (r.requests == 0) {
    r.outcome = CotenantOutcome::kStalled;
    r.reason = "stopped before completing any request";
  } else {
    r.outcome = CotenantOutcome::kCompleted;
  }
  return r;
}

nlohmann::json ToJson(const CotenantResult& r) {
  using nlohmann::json;
  const bool have_rates = r.requests > 0;
  json j = {
      {"stand_in", true},
      {"note", r.note},
      {"model", r.model},
      {"model_weights_bytes", r.model_weights_bytes},
      {"scale", r.scale},
      {"weights_bytes", r.weights_bytes},
      {"overhead_bytes", r.overhead_bytes},
      {"outcome", std::string(CotenantOutcomeName(r.outcome))},
      {"outcome_symbol", std::string(CotenantOutcomeSymbol(r.outcome))},
      {"reason", r.reason},
      {"requests", r.requests},
      {"requests_late", r.requests_late},
      {"tokens_generated", r.tokens_generated},
      {"tokens_per_s", have_rates ? json(r.tokens_per_s) : json(nullptr)},
      {"prefill_tokens_per_s", have_rates ? json(r.prefill_tokens_per_s) : json(nullptr)},
      {"latency_ms",
       have_rates ? json{{"p50", r.latency_ms_p50}, {"p95", r.latency_ms_p95}} : json(nullptr)},
      {"stream_gbps", have_rates ? json(r.stream_gbps) : json(nullptr)},
      {"touch_ms", r.touch_ms},
      {"stall_ms", r.stall_ms},
      {"oom_events_seen", r.oom_events_seen},
      {"checksum", r.checksum},
  };
  // Built element by element: converting the vector of arrays in one go trips GCC 12's -O3
  // -Wnull-dereference false positive inside nlohmann's to_json.
  json per = json::array();
  for (const auto& q : r.per_request) per.push_back(json::array({q[0], q[1], q[2]}));
  j["per_request"] = std::move(per);
  return j;
}

Result<CotenantResult> CotenantResultFromJson(const nlohmann::json& j) {
  try {
    if (!j.value("stand_in", false)) {
      return InvalidArgument("co-tenant result JSON does not say it is a stand-in");
    }
    CotenantResult r;
    r.note = j.at("note").get<std::string>();
    r.model = j.at("model").get<std::string>();
    r.model_weights_bytes = j.at("model_weights_bytes").get<std::uint64_t>();
    r.scale = j.at("scale").get<double>();
    r.weights_bytes = j.at("weights_bytes").get<std::uint64_t>();
    r.overhead_bytes = j.at("overhead_bytes").get<std::uint64_t>();
    const std::string outcome = j.at("outcome").get<std::string>();
    bool known = false;
    for (CotenantOutcome o : {CotenantOutcome::kCompleted, CotenantOutcome::kStalled,
                              CotenantOutcome::kFailedToStart}) {
      if (CotenantOutcomeName(o) == outcome) {
        r.outcome = o;
        known = true;
      }
    }
    if (!known) return InvalidArgument("co-tenant result: unknown outcome '" + outcome + "'");
    r.reason = j.at("reason").get<std::string>();
    r.requests = j.at("requests").get<std::uint32_t>();
    r.requests_late = j.at("requests_late").get<std::uint32_t>();
    r.tokens_generated = j.at("tokens_generated").get<std::uint64_t>();
    if (!j.at("tokens_per_s").is_null()) {
      r.tokens_per_s = j.at("tokens_per_s").get<double>();
      r.prefill_tokens_per_s = j.at("prefill_tokens_per_s").get<double>();
      r.latency_ms_p50 = j.at("latency_ms").at("p50").get<double>();
      r.latency_ms_p95 = j.at("latency_ms").at("p95").get<double>();
      r.stream_gbps = j.at("stream_gbps").get<double>();
    }
    r.touch_ms = j.at("touch_ms").get<double>();
    r.stall_ms = j.at("stall_ms").get<double>();
    r.oom_events_seen = j.at("oom_events_seen").get<std::uint64_t>();
    r.checksum = j.at("checksum").get<std::uint64_t>();
    if (j.contains("per_request")) {
      for (const auto& q : j.at("per_request")) {
        r.per_request.push_back({q.at(0).get<double>(), q.at(1).get<double>(), q.at(2).get<double>()});
      }
    }
    return r;
  } catch (const nlohmann::json::exception& e) {
    return InvalidArgument(std::string("co-tenant result JSON: ") + e.what());
  }
}

// ---- CotenantThread ----

CotenantThread::~CotenantThread() {
  RequestStop();
  if (thread_.joinable()) thread_.join();
}

Status CotenantThread::Start(CotenantConfig config) {
  if (thread_.joinable()) return FailedPrecondition("co-tenant stand-in thread already started");
  stop_.store(false);
  done_.store(false);
  try {
    thread_ = std::thread([this, c = std::move(config)] {
      result_ = RunCotenant(c, &stop_);
      done_.store(true);
    });
  } catch (const std::system_error& e) {
    return ResourceExhausted(std::string("co-tenant stand-in thread: ") + e.what());
  }
  return Status::Ok();
}

Result<CotenantResult> CotenantThread::Join() {
  if (!thread_.joinable()) return FailedPrecondition("co-tenant stand-in thread not started");
  thread_.join();
  return result_;
}

// ---- CotenantProcess ----

std::vector<std::string> CotenantCommandLine(const CotenantConfig& c) {
  auto num = [](double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return std::string(buf);
  };
  std::vector<std::string> a = {
      "--model",          c.model,
      "--scale",          num(c.scale),
      "--prompt-tokens",  std::to_string(c.prompt_tokens),
      "--answer-tokens",  std::to_string(c.answer_tokens),
      "--prompt-batch",   std::to_string(c.prompt_batch_tokens),
      "--requests",       std::to_string(c.requests),
      "--period-s",       num(c.request_period_s),
      "--deadline-s",     num(c.request_deadline_s),
      "--json",
  };
  if (c.weights_bytes != 0) a.insert(a.end(), {"--weights-bytes", std::to_string(c.weights_bytes)});
  if (c.overhead_bytes != 0) {
    a.insert(a.end(), {"--overhead-bytes", std::to_string(c.overhead_bytes)});
  }
  if (!c.ledger_path.empty()) {
    a.insert(a.end(), {"--ledger", c.ledger_path});
    if (c.ledger_device_bytes != 0) {
      a.insert(a.end(), {"--ledger-device-bytes", std::to_string(c.ledger_device_bytes)});
    }
  }
  if (!c.ledger_name.empty()) a.insert(a.end(), {"--ledger-name", c.ledger_name});
  return a;
}

std::string FindCotenantExecutable() {
  if (const char* env = std::getenv("ZM_COTENANT_EXE"); env != nullptr && *env != '\0') return env;
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const auto dir = exe.parent_path();
    for (const auto& candidate : {dir / "zonemap-cotenant", dir / ".." / "app" / "zonemap-cotenant",
                                  dir / ".." / ".." / "app" / "zonemap-cotenant"}) {
      if (std::filesystem::is_regular_file(candidate, ec)) return candidate.lexically_normal();
    }
  }
  return "zonemap-cotenant";
}

CotenantProcess::CotenantProcess(CotenantProcess&& o) noexcept
    : pid_(o.pid_), stdout_fd_(o.stdout_fd_) {
  o.pid_ = -1;
  o.stdout_fd_ = -1;
}

CotenantProcess& CotenantProcess::operator=(CotenantProcess&& o) noexcept {
  if (this != &o) {
    this->~CotenantProcess();
    pid_ = o.pid_;
    stdout_fd_ = o.stdout_fd_;
    o.pid_ = -1;
    o.stdout_fd_ = -1;
  }
  return *this;
}

CotenantProcess::~CotenantProcess() {
  if (pid_ > 0) {
    kill(pid_, SIGTERM);
    int status = 0;
    while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
  }
  if (stdout_fd_ >= 0) {
    close(stdout_fd_);
    stdout_fd_ = -1;
  }
}

Result<CotenantProcess> CotenantProcess::Spawn(const CotenantConfig& config,
                                               std::string executable) {
  if (executable.empty()) executable = FindCotenantExecutable();
  // ZM_COTENANT_LAUNCHER (space-separated, e.g. "qemu-aarch64 -L /sysroot") runs the program
  // through an emulator when the kernel cannot execute it directly.
  std::vector<std::string> args;
  if (const char* l = std::getenv("ZM_COTENANT_LAUNCHER"); l != nullptr && *l != '\0') {
    std::string launcher(l);
    std::size_t pos = 0;
    while (pos < launcher.size()) {
      const std::size_t end = launcher.find(' ', pos);
      const std::string word = launcher.substr(pos, end == std::string::npos ? end : end - pos);
      if (!word.empty()) args.push_back(word);
      if (end == std::string::npos) break;
      pos = end + 1;
    }
  }
  args.push_back(executable);
  for (std::string& a : CotenantCommandLine(config)) args.push_back(std::move(a));
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) return IoError(std::string("pipe: ") + std::strerror(errno));
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(fds[1]);
  if (rc != 0) {
    close(fds[0]);
    return IoError("cannot start co-tenant stand-in '" + args.front() + "': " + std::strerror(rc));
  }
  CotenantProcess p;
  p.pid_ = pid;
  p.stdout_fd_ = fds[0];
  return p;
}

void CotenantProcess::RequestStop() noexcept {
  if (pid_ > 0) kill(pid_, SIGTERM);
}

Result<CotenantResult> CotenantProcess::Wait() {
  if (pid_ <= 0) return FailedPrecondition("co-tenant stand-in process not running");
  std::string out;
  char buf[4096];
  for (;;) {
    const ssize_t n = read(stdout_fd_, buf, sizeof buf);
    if (n > 0) {
      out.append(buf, static_cast<std::size_t>(n));
    } else if (n == 0 || errno != EINTR) {
      break;
    }
  }
  close(stdout_fd_);
  stdout_fd_ = -1;
  int status = 0;
  while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
  }
  const pid_t pid = pid_;
  pid_ = -1;
  if (!WIFEXITED(status)) {
    return Internal("co-tenant stand-in (pid " + std::to_string(pid) + ") was killed by signal " +
                    std::to_string(WIFSIGNALED(status) ? WTERMSIG(status) : 0));
  }
  const nlohmann::json j = nlohmann::json::parse(out, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    return Internal("co-tenant stand-in (pid " + std::to_string(pid) + ") exited with status " +
                    std::to_string(WEXITSTATUS(status)) + " without a JSON result");
  }
  return CotenantResultFromJson(j);
}

}  // namespace zm
