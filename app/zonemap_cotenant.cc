// zonemap-cotenant: the co-tenant STAND-IN program (harness/cotenant.h). It is a stand-in for
// VLM decoding, not a model: it allocates model-sized weights, registers them in the device
// ledger, streams all of them once per generated token and reports tokens/s, request latency
// and the outcome (○ completed, △ stalled, × failed to start).
//
// Exit status: 0 completed, 2 stalled, 3 failed to start, 1 bad arguments. SIGINT/SIGTERM stop
// it between tokens; it then prints its results like a normal end.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "harness/cotenant.h"
#include "harness/experiment_profile.h"
#include "runtime/stop_signal.h"

int main(int argc, char** argv) {
  CLI::App app{
      "zonemap-cotenant: a STAND-IN for VLM decoding beside the map (streams model-sized weights "
      "once per token; memory-bandwidth bound). Not a real model."};
  zm::CotenantConfig config;
  std::string profile_name;
  std::string weights_text;
  std::string overhead_text;
  std::string ledger_device_text;
  bool json = false;
  bool list = false;
  app.add_option("--profile", profile_name,
                 "read the [cotenant] section of this profile first (flags override it)");
  app.add_option("--model", config.model, "model: " + zm::CotenantModelNames());
  app.add_option("--weights-bytes", weights_text, "weights size override (e.g. 1.9GB, 512MiB)");
  app.add_option("--overhead-bytes", overhead_text, "KV cache/activations besides the weights");
  app.add_option("--scale", config.scale, "multiply weights and overhead (tests, CI)")
      ->check(CLI::PositiveNumber);
  app.add_option("--prompt-tokens", config.prompt_tokens, "prompt length per request");
  app.add_option("--answer-tokens", config.answer_tokens, "generated tokens per request")
      ->check(CLI::PositiveNumber);
  app.add_option("--prompt-batch", config.prompt_batch_tokens,
                 "prompt tokens per pass over the weights (batched prefill)")
      ->check(CLI::PositiveNumber);
  app.add_option("--requests", config.requests, "requests to serve (0 = until SIGTERM)");
  app.add_option("--period-s", config.request_period_s, "start a request every S seconds");
  app.add_option("--deadline-s", config.request_deadline_s,
                 "a request slower than this is a stall (0 = none)");
  app.add_option("--ledger", config.ledger_path, "device ledger file to register in");
  app.add_option("--ledger-device-bytes", ledger_device_text,
                 "device total when the ledger file is created (e.g. 8GiB)");
  app.add_option("--ledger-name", config.ledger_name, "tenant name in the ledger");
  app.add_flag("--json", json, "print the result as JSON on stdout");
  app.add_flag("--list-models", list, "print the model table and exit");
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
    for (const zm::CotenantModel& m : zm::CotenantModels()) {
      std::printf("%-14s %-14s %s\n", std::string(m.name).c_str(), std::string(m.display).c_str(),
                  zm::FormatBytes(m.weights_bytes).c_str());
    }
    std::printf("(sizes of the real models' weights; zonemap-cotenant is a stand-in)\n");
    return 0;
  }
  if (!profile_name.empty()) {
    zm::Result<zm::ExperimentProfile> profile = zm::LoadExperimentProfile(profile_name);
    if (!profile.ok()) return fail(profile.status().message());
    zm::CotenantConfig from = zm::CotenantConfigFromProfile(*profile);
    // Flags given explicitly win over the profile.
    if (app.count("--model") == 0) config.model = from.model;
    if (app.count("--prompt-tokens") == 0) config.prompt_tokens = from.prompt_tokens;
    if (app.count("--answer-tokens") == 0) config.answer_tokens = from.answer_tokens;
    if (app.count("--prompt-batch") == 0) config.prompt_batch_tokens = from.prompt_batch_tokens;
    if (app.count("--period-s") == 0) config.request_period_s = from.request_period_s;
    if (app.count("--deadline-s") == 0) config.request_deadline_s = from.request_deadline_s;
    if (weights_text.empty() && app.count("--model") == 0) config.weights_bytes = from.weights_bytes;
    if (overhead_text.empty()) config.overhead_bytes = from.overhead_bytes;
    if (config.ledger_device_bytes == 0 && ledger_device_text.empty()) {
      config.ledger_device_bytes = profile->core.device.memory_bytes;
    }
  }
  if (!weights_text.empty()) {
    zm::Result<std::uint64_t> b = zm::ParseBytes(weights_text);
    if (!b.ok() || *b == 0) return fail("--weights-bytes: " + (b.ok() ? "must be > 0" : b.status().message()));
    config.weights_bytes = *b;
  }
  if (!overhead_text.empty()) {
    zm::Result<std::uint64_t> b = zm::ParseBytes(overhead_text);
    if (!b.ok()) return fail("--overhead-bytes: " + b.status().message());
    config.overhead_bytes = *b;
  }
  if (!ledger_device_text.empty()) {
    zm::Result<std::uint64_t> b = zm::ParseBytes(ledger_device_text);
    if (!b.ok()) return fail("--ledger-device-bytes: " + b.status().message());
    config.ledger_device_bytes = *b;
  }
  if (config.weights_bytes == 0) {
    if (zm::Result<zm::CotenantModel> m = zm::FindCotenantModel(config.model); !m.ok()) {
      return fail(m.status().message());
    }
  }

  zm::InstallStopSignals();
  const zm::CotenantResult r = zm::RunCotenant(config, zm::StopFlag());

  if (json) {
    std::printf("%s\n", zm::ToJson(r).dump(2).c_str());
  } else {
    std::printf("co-tenant STAND-IN (%s)\n", std::string(zm::kCotenantNote).c_str());
    std::printf("  model %s: %s of weights (scale %g of %s)%s\n", r.model.c_str(),
                zm::FormatBytes(r.weights_bytes).c_str(), r.scale,
                zm::FormatBytes(r.model_weights_bytes).c_str(),
                r.overhead_bytes ? (" + " + zm::FormatBytes(r.overhead_bytes) + " overhead").c_str()
                                 : "");
    std::printf("  outcome: %s %s%s%s\n", std::string(zm::CotenantOutcomeSymbol(r.outcome)).c_str(),
                std::string(zm::CotenantOutcomeName(r.outcome)).c_str(),
                r.reason.empty() ? "" : " - ", r.reason.c_str());
    if (r.requests > 0) {
      std::printf("  %u requests, %llu tokens: %.2f tokens/s (median decode), prefill %.1f tokens/s\n",
                  r.requests, static_cast<unsigned long long>(r.tokens_generated), r.tokens_per_s,
                  r.prefill_tokens_per_s);
      std::printf("  latency p50 %.1f ms, p95 %.1f ms; streaming %.2f GB/s; touch %.1f ms; "
                  "stalled %.1f ms\n",
                  r.latency_ms_p50, r.latency_ms_p95, r.stream_gbps, r.touch_ms, r.stall_ms);
    }
  }
  switch (r.outcome) {
    case zm::CotenantOutcome::kCompleted: return 0;
    case zm::CotenantOutcome::kStalled: return 2;
    case zm::CotenantOutcome::kFailedToStart: return 3;
  }
  return 1;
}
