// Co-tenant stand-in: small weights (a few MiB) so it runs in well under a second, even under
// qemu. Checks the three outcomes (○ completed, △ stalled, × failed to start), the ledger
// registration, the thread and child-process runners, and that every output says "stand-in".
#include "harness/cotenant.h"

#include <doctest/doctest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "harness/device_ledger.h"

namespace zm {
namespace {

constexpr std::uint64_t kMiB = 1ULL << 20;

std::string TempLedgerPath() {
  static std::atomic<int> n{0};
  const std::string p = (std::filesystem::temp_directory_path() /
                         ("zm-cotenant-test-" + std::to_string(getpid()) + "-" +
                          std::to_string(n++)))
                            .string();
  (void)DeviceLedger::Remove(p);
  return p;
}

// qwen3.5-0.8b (1.0 GB) scaled to 2 MB.
CotenantConfig Small() {
  CotenantConfig c;
  c.model = "qwen3.5-0.8b";
  c.scale = 0.002;
  c.prompt_tokens = 64;
  c.prompt_batch_tokens = 64;
  c.answer_tokens = 4;
  c.requests = 2;
  return c;
}

TEST_CASE("the model table holds the paper's weight sizes") {
  CHECK(CotenantModels().size() == 5);
  CHECK(FindCotenantModel("qwen3-vl-2b")->weights_bytes == 1'900'000'000ULL);
  CHECK(FindCotenantModel("qwen3-vl-4b")->weights_bytes == 3'300'000'000ULL);
  CHECK(FindCotenantModel("qwen3.5-0.8b")->weights_bytes == 1'000'000'000ULL);
  CHECK(FindCotenantModel("qwen3.5-2b")->weights_bytes == 2'700'000'000ULL);
  CHECK(FindCotenantModel("gemma3-4b")->weights_bytes == 3'300'000'000ULL);
  CHECK(FindCotenantModel("gpt-9").status().code() == StatusCode::kNotFound);
}

TEST_CASE("alone, it completes and reports tokens/s and latency as a stand-in") {
  const CotenantResult r = RunCotenant(Small());
  CHECK(r.outcome == CotenantOutcome::kCompleted);
  CHECK(r.reason.empty());
  CHECK(r.weights_bytes == 2'000'000);
  CHECK(r.requests == 2);
  CHECK(r.tokens_generated == 8);
  CHECK(r.tokens_per_s > 0.0);
  CHECK(r.latency_ms_p50 > 0.0);
  CHECK(r.latency_ms_p95 >= r.latency_ms_p50);
  const nlohmann::json j = ToJson(r);
  CHECK(j["stand_in"] == true);
  CHECK(j["note"].get<std::string>().find("stand-in") != std::string::npos);
  CHECK(j["outcome"] == "completed");
  CHECK(j["outcome_symbol"] == "\u25cb");
  for (const char* key : {"model", "tokens_per_s", "latency_ms", "outcome", "weights_bytes"}) {
    CHECK(j.contains(key));
  }
  Result<CotenantResult> back = CotenantResultFromJson(j);
  REQUIRE(back.ok());
  CHECK(back->requests == 2);
  CHECK(back->checksum == r.checksum);
  CHECK(back->latency_ms_p95 == r.latency_ms_p95);
}

TEST_CASE("the weights stream is deterministic") {
  CHECK(RunCotenant(Small()).checksum == RunCotenant(Small()).checksum);
}

TEST_CASE("weights that do not fit in the ledger: failed to start, one OOM event") {
  const std::string path = TempLedgerPath();
  Result<DeviceLedger> ledger = DeviceLedger::Open(path, 8 * kMiB);
  REQUIRE(ledger.ok());
  Result<LedgerTenant> map = ledger->Register("map", 7 * kMiB);
  REQUIRE(map.ok());
  CotenantConfig c = Small();
  c.ledger_path = path;
  const CotenantResult r = RunCotenant(c);
  CHECK(r.outcome == CotenantOutcome::kFailedToStart);
  CHECK(r.reason.find("do not fit") != std::string::npos);
  CHECK(ledger->oom_events() == 1);
  CHECK(ledger->sum_bytes() == 7 * kMiB);
  const nlohmann::json j = ToJson(r);
  CHECK(j["outcome_symbol"] == "\u00d7");
  CHECK(j["tokens_per_s"].is_null());
  CHECK(j["stand_in"] == true);
  (void)DeviceLedger::Remove(path);
}

TEST_CASE("weights the process cannot map: failed to start") {
  CotenantConfig c = Small();
  c.weights_bytes = 1ULL << 62;
  c.scale = 1.0;
  const CotenantResult r = RunCotenant(c);
  CHECK(r.outcome == CotenantOutcome::kFailedToStart);
  CHECK(r.reason.find("allocating") != std::string::npos);
}

TEST_CASE("an out-of-memory event while it runs makes it stall, and it waits while over-committed") {
  const std::string path = TempLedgerPath();
  Result<DeviceLedger> ledger = DeviceLedger::Open(path, 16 * kMiB);
  REQUIRE(ledger.ok());
  Result<LedgerTenant> map = ledger->Register("map", 4 * kMiB);
  REQUIRE(map.ok());
  CotenantConfig c = Small();
  c.requests = 0;  // until stopped
  c.ledger_path = path;
  CotenantThread thread;
  REQUIRE(thread.Start(c).ok());
  // Wait until the stand-in holds its grant, then let the map ask for more than is left.
  for (int i = 0; i < 10000 && ledger->sum_bytes() == 4 * kMiB; ++i) usleep(500);
  REQUIRE(ledger->sum_bytes() > 4 * kMiB);
  CHECK_FALSE(map->TryUpdate(15 * kMiB));
  CHECK(ledger->OverCommitted());
  std::this_thread::sleep_for(std::chrono::milliseconds(60));
  CHECK(map->Update(4 * kMiB).ok());  // the map backs off
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  thread.RequestStop();
  Result<CotenantResult> r = thread.Join();
  REQUIRE(r.ok());
  CHECK(r->outcome == CotenantOutcome::kStalled);
  CHECK(r->oom_events_seen == 1);
  CHECK(r->stall_ms > 10.0);
  CHECK(r->reason.find("out-of-memory") != std::string::npos);
  CHECK(ToJson(*r)["outcome_symbol"] == "\u25b3");
  CHECK(ledger->sum_bytes() == 4 * kMiB);  // its grant went back
  (void)DeviceLedger::Remove(path);
}

TEST_CASE("a request past its deadline is a stall") {
  CotenantConfig c = Small();
  c.request_deadline_s = 1e-7;
  const CotenantResult r = RunCotenant(c);
  CHECK(r.outcome == CotenantOutcome::kStalled);
  CHECK(r.requests_late == 2);
  CHECK(r.reason.find("deadline") != std::string::npos);
}

TEST_CASE("stopped before any request completes: no progress, a stall") {
  std::atomic<bool> stop{true};
  const CotenantResult r = RunCotenant(Small(), &stop);
  CHECK(r.outcome == CotenantOutcome::kStalled);
  CHECK(r.requests == 0);
  CHECK(ToJson(r)["latency_ms"].is_null());
}

TEST_CASE("as a child process it registers in the ledger and reports JSON") {
  const std::string emulator = ZM_TEST_EMULATOR;
  if (!emulator.empty()) setenv("ZM_COTENANT_LAUNCHER", emulator.c_str(), 1);
  const std::string path = TempLedgerPath();
  Result<DeviceLedger> ledger = DeviceLedger::Open(path, 64 * kMiB);
  REQUIRE(ledger.ok());
  CotenantConfig c = Small();
  c.ledger_path = path;
  c.ledger_name = "cotenant-child";
  Result<CotenantProcess> child = CotenantProcess::Spawn(c, ZM_TEST_COTENANT_EXE);
  REQUIRE_MESSAGE(child.ok(), child.status().ToString());
  Result<CotenantResult> r = child->Wait();
  unsetenv("ZM_COTENANT_LAUNCHER");
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  CHECK(r->outcome == CotenantOutcome::kCompleted);
  CHECK(r->requests == 2);
  CHECK(r->note.find("stand-in") != std::string::npos);
  CHECK(ledger->peak_sum_bytes() >= r->weights_bytes);  // it was registered while it ran
  CHECK(ledger->sum_bytes() == 0);                      // and released at exit
  (void)DeviceLedger::Remove(path);
}

TEST_CASE("the command line round-trips the configuration") {
  CotenantConfig c = Small();
  c.weights_bytes = 123456;
  c.ledger_path = "/tmp/x";
  const std::vector<std::string> args = CotenantCommandLine(c);
  auto has = [&](const std::string& flag, const std::string& value) {
    for (std::size_t i = 0; i + 1 < args.size(); ++i) {
      if (args[i] == flag && args[i + 1] == value) return true;
    }
    return false;
  };
  CHECK(has("--model", "qwen3.5-0.8b"));
  CHECK(has("--weights-bytes", "123456"));
  CHECK(has("--ledger", "/tmp/x"));
  CHECK(has("--answer-tokens", "4"));
  CHECK(std::find(args.begin(), args.end(), "--json") != args.end());
}

}  // namespace
}  // namespace zm
