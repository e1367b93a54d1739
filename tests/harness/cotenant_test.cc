// Co-tenant stand-in (harness/cotenant.h), one process: the model table and its KV geometry, the
// device scale, the outcomes measured in-process (completed; failed to start on an unmappable
// weights path, on a KV cache above an RLIMIT in a forked child, on a ledger refusal), file-backed
// weights, a KV cache that grows with the context, per-request lines parsed back, the ledger's
// refused grant failing a request, and the child process (self-paced; its move assignment).
// Stalls and kills need a process to freeze or kill: cotenant_supervisor_test.cc.
#include "harness/cotenant.h"

#include <doctest/doctest.h>
#include <linux/capability.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "harness/device_ledger.h"
#include "runtime/memory_cap.h"
#include "support/cotenant_test_support.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::kMiB;

using test::SmallCotenant;

std::string TempLedgerPath() {
  static std::atomic<int> n{0};
  const std::string p =
      (std::filesystem::temp_directory_path() /
       ("zm-cotenant-test-" + std::to_string(getpid()) + "-" + std::to_string(n++)))
          .string();
  (void)DeviceLedger::Remove(p);
  return p;
}

// RunCotenant with every event line kept.
struct Run {
  CotenantResult result;
  std::vector<nlohmann::json> events;
  std::vector<nlohmann::json> Of(const std::string& name) const {
    std::vector<nlohmann::json> out;
    for (const auto& e : events) {
      if (e["event"] == name) out.push_back(e);
    }
    return out;
  }
};
Run RunAndKeep(const CotenantConfig& c, const std::atomic<bool>* stop = nullptr,
               std::function<void(const nlohmann::json&)> on_event = {}) {
  Run run;
  CotenantHooks hooks;
  hooks.emit = [&](std::string_view line) {
    nlohmann::json j = nlohmann::json::parse(line);
    if (on_event) on_event(j);
    run.events.push_back(std::move(j));
  };
  run.result = RunCotenant(c, stop, std::move(hooks));
  return run;
}

TEST_CASE("the model table holds the paper's weight sizes and each model's KV geometry") {
  CHECK(CotenantModels().size() == 5);
  CHECK(FindCotenantModel("qwen3-vl-2b")->weights_bytes == 1'900'000'000ULL);
  CHECK(FindCotenantModel("qwen3-vl-4b")->weights_bytes == 3'300'000'000ULL);
  CHECK(FindCotenantModel("qwen3.5-0.8b")->weights_bytes == 1'000'000'000ULL);
  CHECK(FindCotenantModel("qwen3.5-2b")->weights_bytes == 2'700'000'000ULL);
  CHECK(FindCotenantModel("gemma3-4b")->weights_bytes == 3'300'000'000ULL);
  CHECK(FindCotenantModel("gpt-9").status().code() == StatusCode::kNotFound);
  // f16 K and V: 2 * layers * kv_heads * head_dim * 2 bytes.
  CHECK(FindCotenantModel("qwen3-vl-2b")->kv_bytes_per_token == 2ULL * 28 * 8 * 128 * 2);
  CHECK(FindCotenantModel("qwen3-vl-4b")->kv_bytes_per_token == 2ULL * 36 * 8 * 128 * 2);
  // gemma3: the 29 sliding-window layers stop growing at 1024 tokens, the 5 global ones do not.
  const CotenantModel gemma = *FindCotenantModel("gemma3-4b");
  CHECK(KvCacheBytes(gemma, 512) == 512ULL * 2 * 34 * 4 * 256 * 2);
  CHECK(KvCacheBytes(gemma, 4096) ==
        4096ULL * 2 * 5 * 4 * 256 * 2 + 1024ULL * 2 * 29 * 4 * 256 * 2);
  // qwen3.5: a fixed recurrent state besides the 6 attention layers' cache.
  const CotenantModel q35 = *FindCotenantModel("qwen3.5-0.8b");
  CHECK(KvCacheBytes(q35, 0) == q35.state_bytes);
  CHECK(KvCacheBytes(q35, 100) == q35.state_bytes + 100ULL * 2 * 6 * 2 * 256 * 2);
}

TEST_CASE(
    "the device scale multiplies weights and KV cache together, and must be above 0 and at most "
    "1") {
  CotenantConfig c;
  c.options.context_tokens = 4096;
  Result<CotenantSizes> full = ResolveCotenantSizes(c);
  REQUIRE(full.ok());
  CHECK(full->weights_bytes == 1'900'000'000ULL / 4096 * 4096);
  CHECK(full->kv_reserved_bytes == 4096ULL * 114'688);
  c.device_scale = 0.125;
  Result<CotenantSizes> eighth = ResolveCotenantSizes(c);
  REQUIRE(eighth.ok());
  CHECK(eighth->weights_bytes == 237'500'000ULL / 4096 * 4096);
  CHECK(eighth->kv_reserved_bytes == 4096ULL * 114'688 / 8);
  CHECK(*CotenantKvReserveBytes(c) == full->kv_reserved_bytes);  // planned at scale 1
  // The watchdog scales with the weights a token streams: 10 s at full size, 1.25 s at 1/8.
  CHECK(full->watchdog_s == doctest::Approx(10.0));
  CHECK(eighth->watchdog_s == doctest::Approx(1.25));
  for (double bad : {0.0, -1.0, 1.5}) {
    c.device_scale = bad;
    Result<CotenantSizes> r = ResolveCotenantSizes(c);
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().message().find("must be > 0 and <= 1") != std::string::npos);
  }
  c.device_scale = 1.0;
  c.options.context_tokens = 100;
  CHECK(ResolveCotenantSizes(c).status().message().find("context_tokens") != std::string::npos);
  c = CotenantConfig{};
  c.model = "llama-9";
  CHECK(ResolveCotenantSizes(c).status().message().find("kv_bytes_per_token") != std::string::npos);
  c.weights_bytes = 8 * kMiB;
  c.options.kv_bytes_per_token = 1000;
  CHECK(ResolveCotenantSizes(c)->request_kv_bytes == 1000ULL * (256 + 64));
}

TEST_CASE("alone it completes, and every request streams a line that parses back") {
  const Run run = RunAndKeep(SmallCotenant());
  const CotenantResult& r = run.result;
  CHECK(r.outcome == CotenantOutcome::kCompleted);
  CHECK(r.reason.empty());
  CHECK(r.starts == 1);
  CHECK(r.requests == 2);
  CHECK(r.tokens_generated == 8);
  CHECK(r.tokens_per_s > 0.0);
  CHECK(r.latency_ms_p95 >= r.latency_ms_p50);
  CHECK(r.weights_bytes == 3'800'000ULL / 4096 * 4096);
  CHECK(r.device_scale == 0.002);
  REQUIRE(run.events.size() == 6);  // start, (request_start, request) x 2, end
  CHECK(run.events.front()["event"] == "start");
  CHECK(run.events.back()["event"] == "end");
  for (const nlohmann::json& e : run.events) {
    CHECK(e["stand_in"] == true);
    CHECK(e["device_scale"] == 0.002);
    CHECK(e["mono_s"].get<double>() > 0.0);
  }
  // The lines alone rebuild the same report (what a supervisor does after a kill).
  CotenantReportBuilder builder(r.origin_mono_s);
  for (const nlohmann::json& e : run.events) REQUIRE(builder.AddLine(e.dump()).ok());
  const CotenantResult again = builder.Report();
  CHECK(again.requests == 2);
  CHECK(again.latency_ms_p50 == r.latency_ms_p50);
  CHECK(again.checksum == r.checksum);
  REQUIRE(r.per_request.size() == 2);
  CHECK(r.per_request[0].ok);
  CHECK(r.per_request[1].id == 1);
  CHECK(r.per_request[0].ended_s <= r.per_request[1].started_s);
  const nlohmann::json j = ToJson(r);
  CHECK(j["stand_in"] == true);
  CHECK(j["note"].get<std::string>().find("stand-in") != std::string::npos);
  CHECK(j["outcome"] == "completed");
  CHECK(j["outcome_symbol"] == "\u25cb");
  CHECK(j["device_scale"] == 0.002);
  CHECK(j["per_request"].size() == 2);
  CHECK(j["requests_detail"][1]["id"] == 1);
}

TEST_CASE("pinned weights: read once into locked anonymous memory, the KV cache locked too") {
  CotenantConfig c = SmallCotenant();
  c.options.weights = CotenantWeights::kPinned;
  const Run run = RunAndKeep(c);
  REQUIRE(run.result.outcome == CotenantOutcome::kCompleted);
  CHECK_FALSE(run.result.file_backed);
  CHECK_FALSE(run.result.evictable);
  CHECK(run.result.weights_load == "read");
  const nlohmann::json& start = run.events.front();
  REQUIRE(start["event"] == "start");
  CHECK(start["kv_allocation"] == "at_load");  // a device buffer made with the context
  if (run.result.weights == "pinned_refused") {
    MESSAGE("SKIPPED: mlock is refused here: " << run.result.lock_error);
    CHECK_FALSE(run.result.lock_error.empty());
    return;
  }
  CHECK(run.result.weights == "pinned");
  CHECK(start["mlocked"] == true);
  CHECK(ToJson(run.result)["weights"] == "pinned");
}

// Drops CAP_IPC_LOCK (root's exemption from RLIMIT_MEMLOCK) from the calling process.
bool DropIpcLock() {
  __user_cap_header_struct header{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct data[2]{};
  if (syscall(SYS_capget, &header, data) != 0) return false;
  const unsigned word = CAP_IPC_LOCK / 32, bit = 1U << (CAP_IPC_LOCK % 32);
  data[word].effective &= ~bit;
  data[word].permitted &= ~bit;
  data[word].inheritable &= ~bit;
  return syscall(SYS_capset, &header, data) == 0;
}

TEST_CASE("a locked-memory limit too small: pinned_refused, one line, the co-tenant still serves") {
  if (test::EmulatorLauncher::active()) {
    MESSAGE("SKIPPED: under qemu-user the capability and rlimit calls are the emulator's");
    return;
  }
  CotenantConfig c = SmallCotenant();
  c.options.weights = CotenantWeights::kPinned;
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    // 64 KiB of locked memory for 3.8 MB of weights: refused, as with a default RLIMIT_MEMLOCK
    // and a full-size model.
    const rlimit small{64 * 1024, 64 * 1024};
    if (!DropIpcLock() || setrlimit(RLIMIT_MEMLOCK, &small) != 0) _exit(3);
    const Run run = RunAndKeep(c);
    const bool refused = run.result.weights == "pinned_refused" &&
                         run.result.lock_error.find("RLIMIT_MEMLOCK 65536 B") != std::string::npos;
    if (!refused || run.result.outcome != CotenantOutcome::kCompleted) {
      std::fprintf(stderr, "weights %s, lock error '%s', outcome %s\n", run.result.weights.c_str(),
                   run.result.lock_error.c_str(),
                   std::string(CotenantOutcomeName(run.result.outcome)).c_str());
      _exit(1);
    }
    _exit(0);
  }
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
}

TEST_CASE("the same bytes give the same checksum") {
  CHECK(RunCotenant(SmallCotenant()).checksum == RunCotenant(SmallCotenant()).checksum);
}

TEST_CASE("the weights are a real file, mapped read-only and shared while it runs") {
  std::string perms, path;
  const Run run = RunAndKeep(SmallCotenant(), nullptr, [&](const nlohmann::json& e) {
    if (e["event"] != "start") return;
    path = e["weights_path"].get<std::string>();
    perms = test::MappingPerms(test::ProcMaps(), path);
  });
  REQUIRE(run.result.outcome == CotenantOutcome::kCompleted);
  CHECK(run.result.file_backed);
  CHECK(run.result.weights_load == "mmap");
  if (test::EmulatorLauncher::active()) {
    MESSAGE("under qemu-user /proc/self/maps is the emulator's view: the mapping check is skipped");
  } else {
    CHECK(perms == "r--s");  // MAP_SHARED, PROT_READ
  }
  struct stat st {};
  REQUIRE(stat(path.c_str(), &st) == 0);
  CHECK(static_cast<std::uint64_t>(st.st_size) == run.result.weights_bytes);
  CHECK(static_cast<std::uint64_t>(st.st_blocks) * 512 >= run.result.weights_bytes);  // not sparse
  CHECK(test::MappingPerms(test::ProcMaps(), path).empty());  // unmapped at the end
}

TEST_CASE("the KV cache grows with each request's context and is resident while it is used") {
  auto kv_of = [](std::uint32_t answer, KvAllocation alloc) {
    CotenantConfig c = SmallCotenant();
    c.device_scale = 0.01;         // 1146.88 B of KV cache per token,
    c.weights_bytes = 100 * kMiB;  // 1 MiB of weights: quick passes
    c.options.answer_tokens = answer;
    c.options.kv_allocation = alloc;
    c.requests = 1;
    const Run run = RunAndKeep(c);
    REQUIRE(run.result.outcome == CotenantOutcome::kCompleted);
    const std::vector<nlohmann::json> req = run.Of("request");
    REQUIRE(req.size() == 1);
    return std::pair{req[0]["kv_bytes"].get<std::uint64_t>(),
                     req[0]["kv_resident_bytes"].get<std::uint64_t>()};
  };
  const auto [short_kv, short_resident] = kv_of(16, KvAllocation::kPerRequest);
  const auto [long_kv, long_resident] = kv_of(160, KvAllocation::kPerRequest);
  // (64 + 16) and (64 + 160) tokens of 114688 B, at device scale 0.01.
  CHECK(short_kv == static_cast<std::uint64_t>(std::llround(80 * 114688 * 0.01)));
  CHECK(long_kv == static_cast<std::uint64_t>(std::llround(224 * 114688 * 0.01)));
  if (test::EmulatorLauncher::active()) {
    MESSAGE("under qemu-user mincore() is not the guest's view: the residency check is skipped");
  } else {
    CHECK(short_resident >= short_kv / 4096 * 4096);
    CHECK(long_resident >= long_kv / 4096 * 4096);
  }
  // llama.cpp's way: the whole n_ctx cache is written at load and stays.
  const auto [at_load_kv, at_load_resident] = kv_of(16, KvAllocation::kAtLoad);
  CHECK(at_load_kv ==
        (static_cast<std::uint64_t>(std::llround(256 * 114688 * 0.01)) + 4095) / 4096 * 4096);
  (void)at_load_resident;
}

TEST_CASE("weights that cannot be mapped: failed to start, and nothing to report but the reason") {
  CotenantConfig c = SmallCotenant();
  c.options.weights_dir = "/proc/self/zm-weights";  // cannot be created
  const Run run = RunAndKeep(c);
  const CotenantResult& r = run.result;
  CHECK(r.outcome == CotenantOutcome::kFailedToStart);
  CHECK(r.starts == 0);
  CHECK(r.failed_starts == 1);
  CHECK(r.reason.find("weights could not be mapped") != std::string::npos);
  CHECK(r.reason.find("/proc/self/zm-weights") != std::string::npos);
  REQUIRE(run.events.size() == 1);
  CHECK(run.events[0]["event"] == "failed_to_start");
  const nlohmann::json j = ToJson(r);
  CHECK(j["outcome"] == "failed_to_start");
  CHECK(j["outcome_symbol"] == "\u00d7");
  CHECK(j["tokens_per_s"].is_null());
  CHECK(j["stand_in"] == true);
}

TEST_CASE("a KV cache larger than the process may allocate: failed to start (forked child)") {
  // The child caps itself (RLIMIT_AS, or RLIMIT_DATA under ASan: memory_cap.h) at 64 MiB of
  // growth and asks for a 512 MiB KV cache; it reports through a pipe and _exits.
  int fds[2];
  REQUIRE(pipe(fds) == 0);
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    close(fds[0]);
    auto say = [&](const std::string& s) {
      (void)!write(fds[1], s.data(), s.size());
      _exit(0);
    };
    const std::uint64_t cap =
        BuiltWithAddressSanitizer() ? 64 * kMiB : ProcessAddressSpaceBytes() + 64 * kMiB;
    Result<CapReport> capped = ApplyProcessCap(cap);
    if (!capped.ok()) say("SKIP setrlimit: " + capped.status().message());
    if (!capped->enforced) say("SKIP " + capped->note);
    CotenantConfig c = SmallCotenant();
    c.device_scale = 1.0;
    c.weights_bytes = 4 * kMiB;
    c.options.context_tokens = 4096;
    c.options.kv_bytes_per_token = 128 * 1024;  // 512 MiB for the context
    const CotenantResult r = RunCotenant(c);
    say(std::string(CotenantOutcomeName(r.outcome)) + "|" + r.reason);
  }
  close(fds[1]);
  std::string got;
  char buf[512];
  for (ssize_t n; (n = read(fds[0], buf, sizeof buf)) > 0;)
    got.append(buf, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  if (got.rfind("SKIP", 0) == 0) {
    MESSAGE("skipped: the process cap is not enforced here (" << got.substr(5) << ")");
    return;
  }
  CHECK(got.rfind("failed_to_start|", 0) == 0);
  CHECK(got.find("KV cache could not be allocated") != std::string::npos);
}

TEST_CASE("ledger: weights the device cannot hold are refused, so it fails to start") {
  const std::string path = TempLedgerPath();
  Result<DeviceLedger> ledger = DeviceLedger::Open(path, 8 * kMiB);
  REQUIRE(ledger.ok());
  Result<LedgerTenant> map = ledger->Register("map", 7 * kMiB);
  REQUIRE(map.ok());
  CotenantConfig c = SmallCotenant();
  c.ledger_path = path;
  const CotenantResult r = RunCotenant(c);
  CHECK(r.outcome == CotenantOutcome::kFailedToStart);
  CHECK(r.reason.find("refused the weights") != std::string::npos);
  CHECK(ledger->oom_events() == 1);
  CHECK(ledger->sum_bytes() == 7 * kMiB);
  (void)DeviceLedger::Remove(path);
}

TEST_CASE("ledger: a refused KV grant fails that request at once, and nothing sleeps") {
  const std::string path = TempLedgerPath();
  CotenantConfig c = SmallCotenant();
  c.device_scale = 0.01;  // 19 MB of weights, 78 KB of KV per request
  const CotenantSizes sz = *ResolveCotenantSizes(c);
  Result<DeviceLedger> ledger = DeviceLedger::Open(path, sz.weights_bytes + 16 * kMiB);
  REQUIRE(ledger.ok());
  Result<LedgerTenant> map = ledger->Register("map", 16 * kMiB - 1000);  // leaves 1000 B
  REQUIRE(map.ok());
  c.ledger_path = path;
  c.requests = 3;
  const auto t0 = std::chrono::steady_clock::now();
  const CotenantResult refused = RunCotenant(c);
  CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(20));
  CHECK(refused.starts == 1);
  CHECK(refused.requests == 0);
  CHECK(refused.requests_failed == 3);
  CHECK(refused.per_request.at(0).reason.find("refused") != std::string::npos);
  CHECK(refused.outcome == CotenantOutcome::kStalled);  // none of the requests completed
  CHECK(ledger->oom_events() == 3);
  REQUIRE(map->Update(1 * kMiB).ok());  // the map gives memory back: requests go through
  const CotenantResult served = RunCotenant(c);
  CHECK(served.requests == 3);
  CHECK(served.outcome == CotenantOutcome::kCompleted);
  CHECK(ledger->sum_bytes() == 1 * kMiB);  // the co-tenant's grant went back
  (void)DeviceLedger::Remove(path);
}

TEST_CASE("stopped between requests: it ends cleanly with its end line") {
  std::atomic<bool> stop{false};
  CotenantConfig c = SmallCotenant();
  c.requests = 0;
  const Run run = RunAndKeep(c, &stop, [&](const nlohmann::json& e) {
    if (e["event"] == "request" && e["id"] == 2) stop.store(true);
  });
  CHECK(run.result.requests == 3);
  CHECK(run.result.requests_failed == 0);
  CHECK(run.result.outcome == CotenantOutcome::kCompleted);
  CHECK(run.Of("end").size() == 1);
}

TEST_CASE("the outcome follows the counts, in one place") {
  CotenantResult r;
  CHECK(DecideCotenantOutcome(r).outcome == CotenantOutcome::kFailedToStart);
  r.start_failure = "the KV cache could not be allocated";
  CHECK(DecideCotenantOutcome(r).reason == r.start_failure);
  r.kills = 1;  // an OOM kill while loading is still a failure to start
  CHECK(DecideCotenantOutcome(r).outcome == CotenantOutcome::kFailedToStart);
  CHECK(DecideCotenantOutcome(r).reason.find("killed 1 time while loading") != std::string::npos);
  r.kills = 0;
  r.starts = 1;
  CHECK(DecideCotenantOutcome(r).outcome == CotenantOutcome::kCompleted);
  r.requests_failed = 2;
  CHECK(DecideCotenantOutcome(r).outcome == CotenantOutcome::kStalled);  // none completed
  r.requests = 5;
  CHECK(DecideCotenantOutcome(r).outcome == CotenantOutcome::kCompleted);
  CHECK(DecideCotenantOutcome(r).reason == "2 requests failed");
  r.stalls = 1;
  r.watchdog_s = 10;
  const OutcomeDecision stalled = DecideCotenantOutcome(r);
  CHECK(stalled.outcome == CotenantOutcome::kStalled);
  CHECK(stalled.reason.find("no token for 10 s 1 time") != std::string::npos);
  r.kills = 2;
  r.restarts = 2;
  const OutcomeDecision killed = DecideCotenantOutcome(r);
  CHECK(killed.outcome == CotenantOutcome::kKilled);
  CHECK(killed.reason.find("SIGKILL 2 times") != std::string::npos);
  CHECK(killed.reason.find("restarted 2 times") != std::string::npos);
  CHECK(CotenantOutcomeName(CotenantOutcome::kFailedToStart) == "failed_to_start");
  CHECK(CotenantOutcomeSymbol(CotenantOutcome::kKilled) == "\u2020");
}

TEST_CASE("the report's aggregate tokens/s, mean and p95 latency from a request log") {
  // Ten requests of 100 answer tokens: nine decode in 1 s (100 tokens/s), one in 9 s (11.1): the
  // median rate stays 100, the aggregate is 1,000 tokens over 18 s = 55.6 tokens/s.
  CotenantReportBuilder b(1000.0);
  REQUIRE(b.Add({{"event", "start"}, {"model", "qwen3-vl-2b"}}).ok());
  for (int i = 0; i < 10; ++i) {
    const double decode_ms = i == 9 ? 9000.0 : 1000.0;
    const double latency_ms = decode_ms + 500.0;  // 500 ms of prompt processing each
    REQUIRE(b.Add({{"event", "request"},
                   {"id", i},
                   {"started_s", 1000.0 + 10 * i},
                   {"ended_s", 1000.0 + 10 * i + latency_ms / 1000.0},
                   {"answer_tokens", 100},
                   {"decode_ms", decode_ms},
                   {"latency_ms", latency_ms},
                   {"tokens_per_s", 100 * 1000.0 / decode_ms}})
                .ok());
  }
  const CotenantResult r = b.Report();
  CHECK(r.requests == 10);
  CHECK(r.tokens_generated == 1000);
  CHECK(r.decode_ms_total == doctest::Approx(18000.0));
  CHECK(r.tokens_per_s_aggregate == doctest::Approx(1000.0 / 18.0));
  CHECK(r.tokens_per_s == doctest::Approx(100.0).epsilon(0.005));  // median, StreamingStats
  CHECK(r.latency_ms_mean == doctest::Approx((9 * 1500.0 + 9500.0) / 10));
  // p95 nearest rank: the 10th of 10, the slow one.
  CHECK(r.latency_ms_p95 == doctest::Approx(9500.0).epsilon(0.005));
  CHECK(r.latency_ms_p50 == doctest::Approx(1500.0).epsilon(0.005));
  const nlohmann::json j = ToJson(r);
  CHECK(j["tokens_per_s_aggregate"].get<double>() == doctest::Approx(1000.0 / 18.0));
  CHECK(j["latency_ms"]["mean"].get<double>() == doctest::Approx(2300.0));
  CHECK(j["latency_ms"]["p95"].get<double>() == doctest::Approx(9500.0).epsilon(0.005));
  // No completed request: no rates at all, not zeros.
  CHECK(ToJson(CotenantReportBuilder(0.0).Report())["tokens_per_s_aggregate"].is_null());
}

TEST_CASE("a malformed line is an error, an unknown event is ignored") {
  CotenantReportBuilder b;
  CHECK_FALSE(b.AddLine("{not json").ok());
  CHECK_FALSE(b.AddLine("{\"id\": 3}").ok());
  CHECK(b.AddLine("{\"event\": \"hello\"}").ok());
  CHECK(b.Report().starts == 0);
}

TEST_CASE("the command line carries the configuration") {
  CotenantConfig c = SmallCotenant();
  c.weights_bytes = 123456;
  c.ledger_path = "/tmp/x";
  c.options.kv_allocation = KvAllocation::kAtLoad;
  c.options.prefetch = false;
  const std::vector<std::string> args = CotenantCommandLine(c, /*serve=*/true);
  auto has = [&](const std::string& flag, const std::string& value) {
    for (std::size_t i = 0; i + 1 < args.size(); ++i) {
      if (args[i] == flag && args[i + 1] == value) return true;
    }
    return false;
  };
  auto flag = [&](const std::string& f) {
    return std::find(args.begin(), args.end(), f) != args.end();
  };
  CHECK(has("--model", "qwen3-vl-2b"));
  CHECK(has("--device-scale", "0.002"));
  CHECK(has("--weights-bytes", "123456"));
  CHECK(has("--ledger", "/tmp/x"));
  CHECK(has("--answer-tokens", "4"));
  CHECK(has("--kv-allocation", "at_load"));
  CHECK(has("--weights-dir", test::TestWeightsDir()));
  CHECK(flag("--no-prefetch"));
  CHECK(flag("--serve"));
  CHECK(flag("--jsonl"));
}

TEST_CASE("as a self-paced child process it streams its lines and registers in the ledger") {
  test::EmulatorLauncher launcher;
  const std::string path = TempLedgerPath();
  Result<DeviceLedger> ledger = DeviceLedger::Open(path, 64 * kMiB);
  REQUIRE(ledger.ok());
  CotenantConfig c = SmallCotenant();
  c.ledger_path = path;
  c.ledger_name = "cotenant-child";
  Result<CotenantProcess> child = CotenantProcess::Spawn(c, ZM_TEST_COTENANT_EXE);
  REQUIRE_MESSAGE(child.ok(), child.status().ToString());
  Result<CotenantResult> r = child->Wait();
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  CHECK(r->outcome == CotenantOutcome::kCompleted);
  CHECK(r->requests == 2);
  CHECK(r->starts == 1);
  CHECK(r->note.find("stand-in") != std::string::npos);
  CHECK(ledger->peak_sum_bytes() >= r->weights_bytes);  // registered while it ran
  CHECK(ledger->sum_bytes() == 0);                      // and released at exit
  (void)DeviceLedger::Remove(path);
}

TEST_CASE("move-assigning a process stops and reaps the one it replaces") {
  test::EmulatorLauncher launcher;
  CotenantConfig c = SmallCotenant();
  c.requests = 0;  // until stopped
  Result<CotenantProcess> a = CotenantProcess::Spawn(c, ZM_TEST_COTENANT_EXE);
  Result<CotenantProcess> b = CotenantProcess::Spawn(c, ZM_TEST_COTENANT_EXE);
  REQUIRE(a.ok());
  REQUIRE(b.ok());
  // Both have started (their signal handlers are installed), so SIGTERM is a clean stop.
  for (CotenantProcess* p : {&*a, &*b}) {
    std::vector<std::string> lines;
    bool started = false;
    for (int i = 0; i < 120 && !started && p->ReadLines(lines, 1000); ++i) {
      for (const std::string& l : lines)
        started = started || l.find("\"event\":\"start\"") != std::string::npos;
    }
    REQUIRE(started);
  }
  const pid_t old_pid = a->pid();
  const pid_t new_pid = b->pid();
  *a = std::move(*b);
  CHECK(a->pid() == new_pid);
  CHECK(b->pid() == -1);
  errno = 0;
  CHECK(kill(old_pid, 0) == -1);  // reaped: no process, not even a zombie
  CHECK(errno == ESRCH);
  a->RequestStop();
  Result<CotenantResult> r = a->Wait();
  REQUIRE(r.ok());
  CHECK(r->kills == 0);
  CHECK(r->crashes == 0);
}

}  // namespace
}  // namespace zm
