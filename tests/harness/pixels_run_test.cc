// The default path localizes from pixels (issue 26): a scenario made with the default options
// renders every frame, extracts ORB at mapping and in the loop, trains the map's vocabulary, and
// the descriptor oracle (features read off landmark ids, sim/observe.h) never runs — neither
// while the scenario is written nor while the loop replays it.
#include <doctest/doctest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "harness/run.h"
#include "mapdb/map_db.h"
#include "sim/building.h"
#include "sim/observe.h"
#include "sim/scenario.h"
#include "tests/support/small_scenario.h"

namespace zm {
namespace {

namespace fs = std::filesystem;

TEST_CASE("default path: pixels in, pose out, the oracle never runs" *
          doctest::test_suite("slow")) {
  CHECK_MESSAGE(sim::ScenarioOptions{}.features == sim::FeatureSource::kOrb,
                "the oracle is the default nowhere (issue 26)");
  const fs::path dir =
      fs::temp_directory_path() / ("zm_pixels_run_" + std::to_string(static_cast<long>(getpid())));
  fs::remove_all(dir);
  auto b = sim::GenerateHospital(test::SmallHospital(5));
  REQUIRE(b.ok());
  // Default options but a small camera and a short patrol (the test runs under ASan and qemu):
  // 320 x 240 still leaves ORB its 31-pixel border and a few hundred features.
  sim::ScenarioOptions o = test::SmallScenario(5);
  o.noise = sim::NoiseOptions{};  // the default's features, not the small scenario's 80
  o.dense.width = 320;
  o.dense.height = 240;
  o.tasks = 1;
  o.rate_hz = 1.0;
  const std::uint64_t oracle_before = sim::OracleFeatureSets();
  auto report = sim::WriteScenario(*b, o, (dir / "scenario").string());
  REQUIRE_MESSAGE(report.ok(), report.status().ToString());
  CHECK(report->mean_features_per_keyframe > 100);
  CHECK(report->mean_features_per_frame == 0);  // frames carry images; the loop extracts
  CHECK(report->vocabulary_words > 0);
  auto info = sim::LoadScenario((dir / "scenario").string());
  REQUIRE(info.ok());
  CHECK(info->features == "orb");

  RunRequest r;
  r.scenario_dir = (dir / "scenario").string();
  r.out_dir = (dir / "run").string();
  r.loop.policy.kind = PolicyKind::kSemantic;
  r.loop.map.memory_thr_keyframes = 40;
  auto s = RunScenario(r);
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  CHECK(sim::OracleFeatureSets() == oracle_before);
  MESSAGE("pixels: ", s->ticks, " ticks, ", s->frames_localized, " frames localized, ATE ",
          s->replay->trajectory.ate_rmse_m.value_or(-1.0), " m");
  CHECK(s->ticks > 10);
  CHECK(s->step_errors == 0);
  // Closures from the frames' own ORB features against the keyframes': most frames close, and
  // the estimate stays on the ground truth (the oracle gave 0.02 m; pixels a few centimetres).
  CHECK(s->frames_localized * 2 > s->ticks);
  REQUIRE(s->replay.has_value());
  REQUIRE(s->replay->trajectory.ate_rmse_m.has_value());
  CHECK(*s->replay->trajectory.ate_rmse_m < 0.3);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace zm
