// `zonemap run`'s replay (harness/run.h): every recorded frame of a simulated scenario passes
// the input gate zonemapd applies (none refused, so a replay's figures are what they were), and
// each tick's one record reaches ticks.jsonl and estimate.tum once (TickPublisher).
#include "harness/run.h"

#include <doctest/doctest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "runtime/profile.h"
#include "tests/support/small_scenario.h"

namespace zm {
namespace {

namespace fs = std::filesystem;

std::uint64_t Lines(const fs::path& p) {
  std::ifstream in(p);
  std::uint64_t n = 0;
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

TEST_CASE("run: the recorded frames pass the input gate; each tick is published once") {
  const fs::path dir =
      fs::temp_directory_path() / ("zm_run_test_" + std::to_string(static_cast<long>(getpid())));
  fs::remove_all(dir);
  auto b = sim::GenerateHospital(test::SmallHospital(5));
  REQUIRE(b.ok());
  auto scenario = sim::WriteScenario(*b, test::SmallReplayScenario(5, 1), (dir / "scenario").string());
  REQUIRE_MESSAGE(scenario.ok(), scenario.status().ToString());

  RunRequest r;
  r.scenario_dir = (dir / "scenario").string();
  r.out_dir = (dir / "run").string();
  r.loop.policy.kind = PolicyKind::kSemantic;
  r.loop.map.memory_thr_keyframes = 20;
  auto s = RunScenario(r);
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  const std::uint64_t ticks = s->ticks;
  CHECK(ticks > 10);
  REQUIRE(s->replay.has_value());
  CHECK(s->replay->frames_refused == 0);
  CHECK(s->replay->frames_arrived == ticks);
  CHECK(Lines(dir / "run" / "ticks.jsonl") == ticks);
  CHECK(Lines(dir / "run" / "estimate.tum") == ticks + 1);  // + the TUM header
  fs::remove_all(dir);
}

}  // namespace
}  // namespace zm
