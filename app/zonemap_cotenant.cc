// zonemap-cotenant: the co-tenant STAND-IN program (harness/cotenant.h). A stand-in for a VLM
// served by llama.cpp / Ollama, not a model: it maps model-sized weights from a file, keeps a KV
// cache that grows with each request's context, streams all the weights once per generated token,
// and reports tokens/s, request latency and the outcome (○ completed, △ stalled, × failed to start;
// a kill is seen by whoever reaps it).
//
// Modes: self-paced (--requests N --period-s S), or --serve: commands on stdin ("start",
// "request ID SUBMITTED_MONO_S", "stop"), as the supervisor drives it. --jsonl streams one JSON
// line per event as it happens (what a supervisor reads, so nothing is lost to a kill); --json
// prints the final report; otherwise a summary in text.
//
// Exit status: 0 completed, 2 stalled, 3 failed to start, 1 bad arguments. SIGINT/SIGTERM stop it
// between passes; it then writes its "end" line like a normal end.
#include <poll.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstdio>
#include <deque>
#include <nlohmann/json.hpp>
#include <string>

#include "harness/cotenant.h"
#include "harness/experiment_profile.h"
#include "harness/weights_file.h"
#include "runtime/budget.h"
#include "runtime/stop_signal.h"

namespace {

// Writes one line to stdout in a single write (lines are far below PIPE_BUF... or close enough:
// the reader reassembles partial lines anyway).
void WriteLine(std::string_view line) {
  std::string s(line);
  s.push_back('\n');
  std::size_t done = 0;
  while (done < s.size()) {
    const ssize_t n = write(STDOUT_FILENO, s.data() + done, s.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    done += static_cast<std::size_t>(n);
  }
}

// The --serve command channel on stdin.
class Commands {
 public:
  enum class Kind { kStart, kRequest, kStop };
  // Blocks until a command (polling the stop flag); kStop at end of input or on a stop signal.
  Kind Next(zm::CotenantTicket& ticket) {
    for (;;) {
      if (const std::size_t nl = buf_.find('\n'); nl != std::string::npos) {
        const std::string line = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        if (line == "start") return Kind::kStart;
        if (line == "stop") return Kind::kStop;
        unsigned long long id = 0;
        double submitted = 0.0;
        if (std::sscanf(line.c_str(), "request %llu %lf", &id, &submitted) == 2) {
          ticket.id = id;
          ticket.submitted_mono_s = submitted;
          return Kind::kRequest;
        }
        std::fprintf(stderr, "zonemap-cotenant (stand-in): ignoring command '%s'\n", line.c_str());
        continue;
      }
      if (zm::StopRequested()) return Kind::kStop;
      pollfd p{STDIN_FILENO, POLLIN, 0};
      if (poll(&p, 1, 100) <= 0) continue;
      char chunk[4096];
      const ssize_t n = read(STDIN_FILENO, chunk, sizeof chunk);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) return Kind::kStop;
      buf_.append(chunk, static_cast<std::size_t>(n));
    }
  }

 private:
  std::string buf_;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "zonemap-cotenant: a STAND-IN for a VLM served beside the map (weights read from a file "
      "and streamed once per token, a KV cache growing with the context). Not a real model."};
  zm::CotenantConfig flags;
  std::string profile_name, weights_text, kv_text, ledger_device_text;
  std::string kv_allocation = "per_request", weights = "pinned";
  bool serve = false, jsonl = false, json = false, list = false, create_weights = false;
  app.add_option("--profile", profile_name,
                 "start from the profile's [model] and [cotenant] (flags given override them)");
  app.add_option("--model", flags.model,
                 "model (KV geometry and weights): " + zm::CotenantModelNames());
  app.add_option("--weights-bytes", weights_text, "weights size override (e.g. 1.9GB, 512MiB)");
  app.add_option(
         "--device-scale", flags.device_scale,
         "0 < S <= 1: scales weights and KV cache together (the experiment's --device-scale)")
      ->check(CLI::Range(1e-9, 1.0));
  app.add_option("--prompt-tokens", flags.options.prompt_tokens, "prompt length per request");
  app.add_option("--answer-tokens", flags.options.answer_tokens, "generated tokens per request")
      ->check(CLI::PositiveNumber);
  app.add_option("--prompt-batch", flags.options.prompt_batch_tokens,
                 "prompt tokens per pass over the weights (batched prompt processing)")
      ->check(CLI::PositiveNumber);
  app.add_option("--context-tokens", flags.options.context_tokens,
                 "n_ctx: KV cache reserved at start-up (Ollama's default 4096)")
      ->check(CLI::PositiveNumber);
  app.add_option("--requests", flags.requests, "self-paced: requests to serve (0 = until SIGTERM)");
  app.add_option("--period-s", flags.options.request_period_s,
                 "self-paced: a request every S seconds");
  app.add_option("--watchdog-s", flags.options.watchdog_s,
                 "no token for this long inside a request = a stall, at full size: times "
                 "--device-scale (0 = no watchdog)");
  app.add_option("--kv-bytes-per-token", kv_text,
                 "KV cache bytes per token of context (0 = the model's)");
  app.add_option("--kv-allocation", kv_allocation,
                 "per_request (grows and is freed per request) | at_load (llama.cpp)")
      ->check(CLI::IsMember({"per_request", "at_load"}));
  app.add_option("--weights", weights,
                 "pinned (GPU offload: read once, mlock'ed, KV cache locked too; default) | mmap "
                 "(CPU backend: page cache, evictable) | read (anonymous, swappable)")
      ->check(CLI::IsMember({"pinned", "mmap", "read"}));
  app.add_option("--weights-dir", flags.options.weights_dir,
                 "weights file cache (default " + zm::DefaultWeightsDir() + ")");
  app.add_flag("--prefetch,!--no-prefetch", flags.options.prefetch,
               "MAP_POPULATE + MADV_WILLNEED at load, as llama.cpp (default on)");
  app.add_flag("--cold-start,!--no-cold-start", flags.options.cold_start,
               "drop the file's cached pages before mapping (default on)");
  app.add_option("--ledger", flags.ledger_path, "device ledger file (the portable fallback)");
  app.add_option("--ledger-device-bytes", ledger_device_text,
                 "device total when the ledger file is created (e.g. 8GiB)");
  app.add_option("--ledger-name", flags.ledger_name, "tenant name in the ledger");
  app.add_flag("--serve", serve,
               "take commands on stdin (start, request ID T, stop); implies --jsonl");
  app.add_flag("--jsonl", jsonl, "stream one JSON line per event on stdout as it happens");
  app.add_flag("--json", json, "print the final report as JSON on stdout");
  app.add_flag("--list-models", list, "print the model table and exit");
  app.add_flag("--create-weights", create_weights,
               "create (or find) the weights file, print how long it took, and exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  auto fail = [](const std::string& message) {
    std::fprintf(stderr, "zonemap-cotenant (stand-in): %s\n", message.c_str());
    return 1;
  };
  if (list) {
    std::printf("%-14s %-14s %12s %14s %s\n", "name", "model", "weights", "KV B/token",
                "(window, fixed state)");
    for (const zm::CotenantModel& m : zm::CotenantModels()) {
      std::printf("%-14s %-14s %12s %14llu", std::string(m.name).c_str(),
                  std::string(m.display).c_str(), zm::FormatBytes(m.weights_bytes).c_str(),
                  static_cast<unsigned long long>(m.kv_bytes_per_token));
      if (m.window_tokens != 0) {
        std::printf("  + %llu B/token for %u tokens",
                    static_cast<unsigned long long>(m.window_bytes_per_token), m.window_tokens);
      }
      if (m.state_bytes != 0) std::printf("  + %s state", zm::FormatBytes(m.state_bytes).c_str());
      std::printf("\n");
    }
    std::printf("(the real models' sizes; zonemap-cotenant is a stand-in)\n");
    return 0;
  }

  zm::CotenantConfig config;
  if (!profile_name.empty()) {
    zm::Result<zm::ExperimentProfile> profile = zm::LoadExperimentProfile(profile_name);
    if (!profile.ok()) return fail(profile.status().message());
    config = zm::CotenantConfigFromProfile(*profile);
    if (config.ledger_device_bytes == 0 && !flags.ledger_path.empty()) {
      config.ledger_device_bytes = profile->core.device.memory_bytes;
    }
  }
  auto given = [&](const char* name) { return app.count(name) > 0; };
  if (profile_name.empty() || given("--model")) {
    config.model = flags.model;
    if (!profile_name.empty() && weights_text.empty()) config.weights_bytes = 0;  // the table's
  }
  zm::CotenantOptions& o = config.options;
  const zm::CotenantOptions& f = flags.options;
  if (profile_name.empty() || given("--prompt-tokens")) o.prompt_tokens = f.prompt_tokens;
  if (profile_name.empty() || given("--answer-tokens")) o.answer_tokens = f.answer_tokens;
  if (profile_name.empty() || given("--prompt-batch"))
    o.prompt_batch_tokens = f.prompt_batch_tokens;
  if (profile_name.empty() || given("--context-tokens")) o.context_tokens = f.context_tokens;
  if (profile_name.empty() || given("--period-s")) o.request_period_s = f.request_period_s;
  if (profile_name.empty() || given("--watchdog-s")) o.watchdog_s = f.watchdog_s;
  if (profile_name.empty() || given("--weights-dir")) o.weights_dir = f.weights_dir;
  if (profile_name.empty() || given("--prefetch")) o.prefetch = f.prefetch;
  if (profile_name.empty() || given("--cold-start")) o.cold_start = f.cold_start;
  if (profile_name.empty() || given("--kv-allocation")) {
    o.kv_allocation =
        kv_allocation == "at_load" ? zm::KvAllocation::kAtLoad : zm::KvAllocation::kPerRequest;
  }
  if (profile_name.empty() || given("--weights"))
    (void)zm::ParseCotenantWeights(weights, &o.weights);
  config.device_scale = flags.device_scale;
  config.requests = flags.requests;
  config.ledger_path = flags.ledger_path;
  config.ledger_name = flags.ledger_name;
  if (!weights_text.empty()) {
    zm::Result<std::uint64_t> b = zm::ParseBytes(weights_text);
    if (!b.ok() || *b == 0) {
      return fail("--weights-bytes: " +
                  (b.ok() ? std::string("must be > 0") : b.status().message()));
    }
    config.weights_bytes = *b;
  }
  if (!kv_text.empty()) {
    zm::Result<std::uint64_t> b = zm::ParseBytes(kv_text);
    if (!b.ok()) return fail("--kv-bytes-per-token: " + b.status().message());
    o.kv_bytes_per_token = *b;
  }
  if (!ledger_device_text.empty()) {
    zm::Result<std::uint64_t> b = zm::ParseBytes(ledger_device_text);
    if (!b.ok()) return fail("--ledger-device-bytes: " + b.status().message());
    config.ledger_device_bytes = *b;
  }
  zm::Result<zm::CotenantSizes> sizes = zm::ResolveCotenantSizes(config);
  if (!sizes.ok()) return fail(sizes.status().message());

  if (create_weights) {
    zm::Result<zm::WeightsFileInfo> file =
        zm::EnsureWeightsFile(o.weights_dir, sizes->weights_bytes);
    if (!file.ok()) return fail(file.status().message());
    std::printf("%s: %s on %s, %s%s\n", file->path.c_str(), zm::FormatBytes(file->bytes).c_str(),
                file->fs_type.c_str(),
                file->created
                    ? ("created in " + std::to_string(file->create_ms / 1000.0) + " s").c_str()
                    : "already there (reused)",
                file->evictable ? "" : " (tmpfs/ramfs: NOT evictable without swap)");
    return 0;
  }

  zm::InstallStopSignals();
  zm::CotenantHooks hooks;
  if (serve || jsonl) hooks.emit = WriteLine;
  Commands commands;
  std::deque<zm::CotenantTicket> early;  // requests that came before "start"
  if (serve) {
    hooks.await_start = [&] {
      for (;;) {
        zm::CotenantTicket t;
        switch (commands.Next(t)) {
          case Commands::Kind::kStart:
            return true;
          case Commands::Kind::kStop:
            return false;
          case Commands::Kind::kRequest:
            early.push_back(t);
            break;
        }
      }
    };
    hooks.next_request = [&](zm::CotenantTicket& t) {
      if (!early.empty()) {
        t = early.front();
        early.pop_front();
        return true;
      }
      for (;;) {
        switch (commands.Next(t)) {
          case Commands::Kind::kRequest:
            return true;
          case Commands::Kind::kStop:
            return false;
          case Commands::Kind::kStart:
            break;
        }
      }
    };
  }
  const zm::CotenantResult r = zm::RunCotenant(config, zm::StopFlag(), std::move(hooks));

  if (json) {
    std::printf("%s\n", zm::ToJson(r).dump(2).c_str());
  } else if (!serve && !jsonl) {
    std::printf("co-tenant STAND-IN (%s)\n", std::string(zm::kCotenantNote).c_str());
    std::printf(
        "  model %s at device scale %g: %s of weights (%s, %s) + KV cache %s reserved for %u "
        "tokens (%s per request, %s)\n",
        r.model.c_str(), r.device_scale, zm::FormatBytes(r.weights_bytes).c_str(),
        r.weights.c_str(), r.weights_path.c_str(), zm::FormatBytes(r.kv_reserved_bytes).c_str(),
        r.context_tokens, zm::FormatBytes(r.request_kv_bytes).c_str(), r.kv_allocation.c_str());
    if (r.starts > 0) {
      std::printf("  weights loaded in %.1f ms%s\n", r.load_ms,
                  r.weights_create_ms > 0.0 ? (" (file created first in " +
                                               std::to_string(r.weights_create_ms / 1000.0) + " s)")
                                                  .c_str()
                                            : "");
    }
    std::printf("  outcome: %s %s%s%s\n", std::string(zm::CotenantOutcomeSymbol(r.outcome)).c_str(),
                std::string(zm::CotenantOutcomeName(r.outcome)).c_str(),
                r.reason.empty() ? "" : " - ", r.reason.c_str());
    if (r.requests > 0) {
      std::printf(
          "  %u requests, %llu tokens: %.2f tokens/s (median decode), prompt %.1f tokens/s\n",
          r.requests, static_cast<unsigned long long>(r.tokens_generated), r.tokens_per_s,
          r.prefill_tokens_per_s);
      std::printf("  latency p50 %.1f ms, p95 %.1f ms; %llu major faults in requests; %u stalls\n",
                  r.latency_ms_p50, r.latency_ms_p95,
                  static_cast<unsigned long long>(r.major_faults), r.stalls);
    }
  }
  switch (r.outcome) {
    case zm::CotenantOutcome::kCompleted:
      return 0;
    case zm::CotenantOutcome::kStalled:
      return 2;
    case zm::CotenantOutcome::kFailedToStart:
      return 3;
    case zm::CotenantOutcome::kKilled:
      return 2;
  }
  return 1;
}
