// The co-tenant supervisor (harness/cotenant_supervisor.h) with real child processes: paced
// requests (30 per run), a SIGKILL recorded as killed then restarted with every request kept, a
// frozen process seen by the watchdog as a stall, a child that cannot start, the placement hook
// running before anything is mapped, and (where a memory cgroup can be made) a real kernel OOM
// kill. Timings are small: the children map a few MiB.
#include "harness/cotenant_supervisor.h"

#include <doctest/doctest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "support/cotenant_test_support.h"

namespace zm {
namespace {

using test::SmallCotenant;

CotenantSupervisorOptions Options(double period_s = 0.0, std::uint32_t max_requests = 0) {
  CotenantSupervisorOptions o;
  o.config = SmallCotenant();
  o.executable = ZM_TEST_COTENANT_EXE;
  o.restart_delay_s = 0.05;
  o.request_period_s = period_s;
  o.max_requests = max_requests;
  return o;
}

// Polls `done` every 10 ms for up to `seconds` (children under ASan or qemu start slowly).
bool WaitFor(const std::function<bool()>& done, double seconds = 60.0) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < until) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return done();
}

// How many times `needle` occurs in `text`.
std::size_t Count(const std::string& text, const std::string& needle) {
  std::size_t n = 0;
  for (std::size_t at = text.find(needle); at != std::string::npos;
       at = text.find(needle, at + needle.size()))
    ++n;
  return n;
}

// "ended_s" of every completed request in a co-tenant events file (JSON lines), in order.
std::vector<double> RequestEnds(const std::string& jsonl) {
  std::vector<double> ends;
  std::istringstream lines(jsonl);
  for (std::string line; std::getline(lines, line);) {
    const nlohmann::json e = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (e.is_object() && e.value("event", "") == "request") ends.push_back(e.at("ended_s"));
  }
  return ends;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST_CASE("paced requests: 30 in a run, submitted on one schedule, all answered") {
  test::EmulatorLauncher launcher;
  CotenantSupervisor sup;
  REQUIRE(sup.Start(Options(0.02, 30)).ok());
  REQUIRE(WaitFor([&] { return sup.Snapshot().requests >= 30; }));
  Result<CotenantResult> r = sup.Stop();
  REQUIRE(r.ok());
  CHECK(r->outcome == CotenantOutcome::kCompleted);
  CHECK(r->requests == 30);
  CHECK(r->requests_failed == 0);
  CHECK(r->starts == 1);
  CHECK(r->restarts == 0);
  REQUIRE(r->per_request.size() == 30);
  for (std::size_t i = 0; i < 30; ++i) {
    CAPTURE(i);
    CHECK(r->per_request[i].id == i);
    CHECK(r->per_request[i].ok);
    // Request i is due at i * period from the supervisor's start, whatever the child does.
    CHECK(r->per_request[i].submitted_s ==
          doctest::Approx(0.02 * static_cast<double>(i)).epsilon(1e-6));
    CHECK(r->per_request[i].started_s >= r->per_request[i].submitted_s);
  }
}

TEST_CASE("a SIGKILL is recorded as killed, then it restarts and every request is kept") {
  test::EmulatorLauncher launcher;
  const std::string events = std::filesystem::temp_directory_path() /
                             ("zm-cotenant-events-" + std::to_string(getpid()) + ".jsonl");
  std::filesystem::remove(events);
  CotenantSupervisorOptions o = Options(0.03);
  o.events_path = events;
  CotenantSupervisor sup;
  REQUIRE(sup.Start(o).ok());
  REQUIRE(WaitFor([&] { return sup.Snapshot().requests >= 3; }));
  const pid_t first = sup.child_pid();
  REQUIRE(first > 0);
  REQUIRE(kill(first, SIGKILL) == 0);  // what the OOM killer sends
  REQUIRE(WaitFor([&] {
    const CotenantResult s = sup.Snapshot();
    std::uint32_t after = 0;
    for (const CotenantRequestRecord& q : s.per_request) after += q.ok && q.instance == 1;
    return after >= 3;
  }));
  Result<CotenantResult> r = sup.Stop();
  REQUIRE(r.ok());
  CHECK(r->kills == 1);
  CHECK(r->restarts == 1);
  CHECK(r->starts == 2);
  CHECK(r->outcome == CotenantOutcome::kKilled);
  CHECK(r->reason.find("SIGKILL 1 time") != std::string::npos);
  CHECK(ToJson(*r)["outcome_symbol"] == "\u2020");
  std::set<std::int64_t> pids;
  std::uint32_t before = 0;
  for (const CotenantRequestRecord& q : r->per_request) {
    if (q.ok) pids.insert(q.pid);
    before += q.ok && q.instance == 0;
    if (!q.ok) {
      CAPTURE(q.reason);
      CHECK((q.reason.find("not running") != std::string::npos ||
             q.reason.find("lost") != std::string::npos ||
             q.reason.find("stopped") != std::string::npos));
    }
  }
  CHECK(before >= 3);       // what the first instance did survives its kill
  CHECK(pids.size() == 2);  // both instances answered
  CHECK(pids.count(first) == 1);
  const std::string log = ReadFile(events);
  CHECK(log.find("\"kind\":\"killed\"") != std::string::npos);
  CHECK(log.find("\"event\":\"request\"") != std::string::npos);
  std::filesystem::remove(events);
}

TEST_CASE("a frozen co-tenant: the watchdog reports the stall, the request still completes") {
  test::EmulatorLauncher launcher;
  const std::string events = std::filesystem::temp_directory_path() /
                             ("zm-cotenant-stall-" + std::to_string(getpid()) + ".jsonl");
  std::filesystem::remove(events);
  CotenantSupervisorOptions o = Options();
  // Long enough to be frozen mid-request most of the time: the SIGSTOP below follows the
  // request_start event through the supervisor's pipe and a 10 ms poll. On an idle machine 2000
  // tokens have once all been decoded within that latency (largest gap 7 ms, no stall), so a stop
  // that missed the request is detected below and the attempt repeated.
  o.config.options.answer_tokens = 2000;
  o.config.options.context_tokens = 2304;
  // The watchdog is given at full size and scales with the device (ResolveCotenantSizes):
  // 0.2 s at this test's scale.
  o.config.options.watchdog_s = 0.2 / o.config.device_scale;
  o.events_path = events;
  CotenantSupervisor sup;
  REQUIRE(sup.Start(o).ok());
  REQUIRE(WaitFor([&] { return sup.Snapshot().starts == 1; }));
  const pid_t pid = sup.child_pid();
  constexpr std::size_t kAttempts = 5;
  std::size_t attempt = 0;
  bool frozen_mid_request = false;
  while (!frozen_mid_request && attempt < kAttempts) {
    ++attempt;
    (void)sup.SubmitRequest();
    REQUIRE(WaitFor([&] { return Count(ReadFile(events), "\"request_start\"") >= attempt; }));
    REQUIRE(kill(pid, SIGSTOP) == 0);  // no token for 0.6 s, as a process stuck in reclaim
    std::this_thread::sleep_for(std::chrono::milliseconds(600));
    const double resumed = MonotonicSeconds();
    REQUIRE(kill(pid, SIGCONT) == 0);
    REQUIRE(WaitFor([&] { return sup.Snapshot().requests >= attempt; }));
    // The stop froze the request only if its last token came after the resume: the child stamps
    // "ended_s" (the same monotonic clock) right after it. Whether its "request" event had
    // reached the file by then says nothing: a stop can land between the last token and the
    // event (seen under qemu).
    frozen_mid_request = RequestEnds(ReadFile(events)).at(attempt - 1) > resumed;
  }
  CAPTURE(attempt);
  REQUIRE(frozen_mid_request);  // in kAttempts tries, a stop never landed inside a request
  Result<CotenantResult> r = sup.Stop();
  REQUIRE(r.ok());
  CHECK(r->stalls >= 1);
  CHECK(r->outcome == CotenantOutcome::kStalled);
  CHECK(r->reason.find("no token for 0.2 s") != std::string::npos);
  REQUIRE(r->per_request.size() == attempt);
  const CotenantRequestRecord& frozen = r->per_request.back();
  CHECK(frozen.ok);
  CHECK(frozen.stalls >= 1);
  CHECK(frozen.max_token_gap_ms >= 500.0);
  CHECK(ToJson(*r)["outcome_symbol"] == "\u25b3");
  CHECK(ReadFile(events).find("\"event\":\"stall\"") !=
        std::string::npos);  // streamed as it happened
  std::filesystem::remove(events);
}

TEST_CASE("a co-tenant that cannot map its weights fails to start, again at every restart") {
  test::EmulatorLauncher launcher;
  CotenantSupervisorOptions o = Options(0.05);
  o.config.options.weights_dir = "/proc/self/zm-no-weights";
  CotenantSupervisor sup;
  REQUIRE(sup.Start(o).ok());
  REQUIRE(WaitFor([&] { return sup.Snapshot().failed_starts >= 2; }));
  Result<CotenantResult> r = sup.Stop();
  REQUIRE(r.ok());
  CHECK(r->starts == 0);
  CHECK(r->outcome == CotenantOutcome::kFailedToStart);
  CHECK(r->reason.find("weights could not be mapped") != std::string::npos);
  CHECK(r->requests == 0);
  CHECK(r->kills == 0);
}

TEST_CASE(
    "the placement hook runs before the child maps anything, and its failure is a failed start") {
  test::EmulatorLauncher launcher;
  CotenantSupervisorOptions o = Options();
  std::string maps_at_placement;
  std::string weights_path = o.config.options.weights_dir;
  o.place_child = [&](pid_t pid) {
    maps_at_placement = test::ProcMaps(std::to_string(pid));
    return Status::Ok();
  };
  {
    CotenantSupervisor sup;
    REQUIRE(sup.Start(o).ok());
    REQUIRE(WaitFor([&] { return sup.Snapshot().starts == 1; }));
    weights_path = sup.Snapshot().weights_path;
    REQUIRE(sup.Stop().ok());
  }
  CHECK_FALSE(weights_path.empty());
  CHECK(maps_at_placement.find(weights_path) == std::string::npos);

  o.place_child = PlaceInCgroupProcs("/proc/self/zm-no-such-cgroup/cgroup.procs");
  CotenantSupervisor sup;
  REQUIRE(sup.Start(o).ok());
  REQUIRE(WaitFor([&] { return sup.Snapshot().failed_starts >= 1; }));
  Result<CotenantResult> r = sup.Stop();
  REQUIRE(r.ok());
  CHECK(r->outcome == CotenantOutcome::kFailedToStart);
  CHECK(r->reason.find("placing the co-tenant") != std::string::npos);
  CHECK(r->kills == 0);  // the supervisor's own SIGKILL is not an OOM kill
}

// A memory cgroup (v1) of our own, removed at the end; empty when none can be made here.
struct TestCgroup {
  std::string dir;
  explicit TestCgroup(std::uint64_t limit_bytes) {
    std::ifstream self("/proc/self/cgroup");
    std::string line, own;
    while (std::getline(self, line)) {
      const auto a = line.find(":memory:");
      if (a != std::string::npos) own = line.substr(a + 8);
    }
    if (own.empty()) return;
    const std::string d =
        "/sys/fs/cgroup/memory" + own + "/zm-cotenant-test-" + std::to_string(getpid());
    if (mkdir(d.c_str(), 0755) != 0) return;
    std::ofstream(d + "/memory.limit_in_bytes") << limit_bytes;
    std::ifstream check(d + "/memory.limit_in_bytes");
    std::uint64_t got = 0;
    check >> got;
    if (got == 0 || got > limit_bytes + 4096) {
      rmdir(d.c_str());
      return;
    }
    dir = d;
  }
  ~TestCgroup() {
    if (!dir.empty()) rmdir(dir.c_str());
  }
  TestCgroup(const TestCgroup&) = delete;
  TestCgroup& operator=(const TestCgroup&) = delete;
};

TEST_CASE("in a memory cgroup too small for a request's KV cache, the kernel's OOM kill is seen") {
  if (test::EmulatorLauncher::active()) {
    MESSAGE("skipped under qemu-user: the emulator's own memory would be what the cgroup limits");
    return;
  }
  // 128 MiB: room for the child itself (an ASan build's runtime is ~45 MiB resident, its program
  // pages and 4 MiB of weights ~15 MiB) but not for a 272 MiB request.
  TestCgroup cg(128ull << 20);
  if (cg.dir.empty()) {
    MESSAGE(
        "skipped: no memory cgroup can be created here (needs a writable cgroup v1 memory "
        "controller under this process's own cgroup)");
    return;
  }
  test::EmulatorLauncher launcher;
  CotenantSupervisorOptions o = Options(0.05, 4);
  o.config.device_scale = 1.0;
  o.config.weights_bytes = 4ull << 20;
  o.config.options.kv_bytes_per_token = 4ull << 20;  // 68 tokens: a 272 MiB request
  o.place_child = PlaceInCgroupProcs(cg.dir + "/cgroup.procs");
  CotenantSupervisor sup;
  REQUIRE(sup.Start(o).ok());
  const bool killed = WaitFor([&] { return sup.Snapshot().kills >= 1; }, 30.0);
  Result<CotenantResult> r = sup.Stop();
  REQUIRE(r.ok());
  REQUIRE_MESSAGE(killed, "no OOM kill within 30 s; outcome " << CotenantOutcomeName(r->outcome)
                                                              << ": " << r->reason);
  CHECK(r->starts >= 1);  // it loaded (weights + reserved KV fit); the request did not
  CHECK(r->outcome == CotenantOutcome::kKilled);
  CHECK(r->requests == 0);
  CHECK(r->requests_failed >= 1);
  std::ifstream oom(cg.dir + "/memory.oom_control");
  std::ostringstream text;
  text << oom.rdbuf();
  MESSAGE("memory.oom_control: " << text.str());
}

}  // namespace
}  // namespace zm
