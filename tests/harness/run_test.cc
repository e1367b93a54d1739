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
#include "sim/building.h"
#include "sim/scenario.h"

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
  sim::HospitalOptions h;
  h.seed = 5;
  h.area_m2 = 300.0;
  h.resolution_m = 0.1;
  auto b = sim::GenerateHospital(h);
  REQUIRE(b.ok());
  sim::ScenarioOptions o;
  o.seed = 5;
  o.camera.intrinsics = sim::MakeIntrinsics(320, 240, 90.0);
  o.dense.width = 160;
  o.dense.height = 120;
  o.dense.cloud_step = 1;
  o.noise.max_features = 80;
  // The harness's bookkeeping is under test, not localization: the oracle's features, named
  // (issue 26: it is the default nowhere), keep the scenario small and fast under ASan.
  o.features = sim::FeatureSource::kOracle;
  o.camera.range_m = 6.0;
  o.tasks = 1;
  o.rate_hz = 1.0;
  o.keyframe_distance_m = 1.5;
  o.keyframe_angle_deg = 60.0;
  o.threads = 2;
  auto scenario = sim::WriteScenario(*b, o, (dir / "scenario").string());
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
