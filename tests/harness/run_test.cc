// `zonemap run`'s replay (harness/run.h): every recorded frame of a simulated scenario passes
// the input gate zonemapd applies (none refused, so a replay's figures are what they were), and
// each tick's one record reaches ticks.jsonl and estimate.tum once (TickPublisher). From pixels
// (issue 26): every stage of the tick runs and is reported, per tick and in summary.json.
#include "harness/run.h"

#include <doctest/doctest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
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

// A one-task patrol of a 300 m² hospital in a fresh temporary directory (removed after), with
// `o`'s camera, images and features; and a semantic replay of it at MemoryThr `k_max`.
struct SmallRun {
  fs::path dir;
  sim::ScenarioReport scenario;
  RunRequest request;

  SmallRun(const std::string& tag, sim::ScenarioOptions o, std::uint64_t k_max)
      : dir(fs::temp_directory_path() /
            ("zm_run_" + tag + "_" + std::to_string(static_cast<long>(getpid())))) {
    fs::remove_all(dir);
    auto b = sim::GenerateHospital(test::SmallHospital(o.seed));
    REQUIRE(b.ok());
    o.camera.range_m = 6.0;
    o.tasks = 1;
    o.rate_hz = 1.0;
    o.threads = 2;
    auto written = sim::WriteScenario(*b, o, (dir / "scenario").string());
    REQUIRE_MESSAGE(written.ok(), written.status().ToString());
    scenario = *written;
    request.scenario_dir = (dir / "scenario").string();
    request.out_dir = (dir / "run").string();
    request.loop.policy.kind = PolicyKind::kSemantic;
    request.loop.map.memory_thr_keyframes = k_max;
  }
  ~SmallRun() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

TEST_CASE("run: the recorded frames pass the input gate, and each tick is published once") {
  sim::ScenarioOptions o = test::SmallReplayScenario(5, 1);
  // The harness's bookkeeping is under test, not localization: the oracle's features, named
  // (issue 26: it is the default nowhere), keep the scenario small and fast under ASan.
  o.features = sim::FeatureSource::kOracle;
  const SmallRun run("gate", o, 20);
  auto s = RunScenario(run.request);
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  const std::uint64_t ticks = s->ticks;
  CHECK(ticks > 10);
  REQUIRE(s->replay.has_value());
  CHECK(s->replay->frames_refused == 0);
  CHECK(s->replay->frames_arrived == ticks);
  CHECK(Lines(run.dir / "run" / "ticks.jsonl") == ticks);
  CHECK(Lines(run.dir / "run" / "estimate.tum") == ticks + 1);  // + the TUM header
}

TEST_CASE("run from pixels: every stage timed, closures beside frames localized" *
          doctest::test_suite("slow")) {
  sim::ScenarioOptions o;
  o.seed = 3;
  o.features = sim::FeatureSource::kOrb;
  o.camera.intrinsics = sim::MakeIntrinsics(256, 192, 90.0);
  o.dense.width = 256;
  o.dense.height = 192;
  o.keyframe_distance_m = 1.0;
  o.keyframe_angle_deg = 30.0;
  o.vocabulary_max_keyframes = 40;
  const SmallRun run("orb", o, 40);
  const sim::ScenarioReport& scenario = run.scenario;
  REQUIRE(scenario.vocabulary_words > 0);
  auto s = RunScenario(run.request);
  REQUIRE_MESSAGE(s.ok(), s.status().ToString());
  CHECK(s->ticks == scenario.frames);
  CHECK(s->images_refused == 0);
  CHECK_FALSE(s->first_image_error.has_value());
  CHECK(s->frames_localized > 0);
  CHECK(s->closures_accepted == s->frames_localized);  // at most one closure a frame
  // Every stage ran: the front-end, the frame's bag, the likelihood over the index, the
  // candidates' verification, memory management.
  for (int i = 0; i < kLoopStageCount; ++i) {
    CHECK_MESSAGE(s->stages[static_cast<std::size_t>(i)].p50_ms > 0.0,
                  LoopStageName(static_cast<LoopStage>(i)));
  }
  // The budget counted the vocabulary, the index and the scratch, and the loop reserved exactly
  // those (TickLoop::Create refuses otherwise).
  CHECK(s->vocabulary_bytes == scenario.vocabulary_bytes);
  CHECK(s->index_bytes > 0);
  CHECK(s->frame_scratch_bytes > 0);
  // The frame scratch took OpenCV's per-frame allocations without missing one.
  REQUIRE(s->frame_scratch.has_value());
  CHECK(s->frame_scratch->capacity_bytes == s->frame_scratch_bytes);
  CHECK(s->frame_scratch->allocations > 0);
  CHECK(s->frame_scratch->overflows == 0);
  CHECK(s->frame_scratch->blocks_outliving_scope == 0);

  // Each tick's line: its stages (summing to at most its time, within the 4 printed decimals),
  // its features, its image used, its likelihood and the postings walked.
  std::ifstream in(run.dir / "run" / "ticks.jsonl");
  std::uint64_t lines = 0, walked = 0;
  for (std::string line; std::getline(in, line); ++lines) {
    const nlohmann::json t = nlohmann::json::parse(line);
    double sum = 0.0;
    for (const auto& [name, ms] : t["stages_ms"].items()) sum += ms.get<double>();
    CHECK(sum <= t["tick_ms"].get<double>() + 3e-4);
    CHECK(t["features"].get<std::uint64_t>() > 0);
    CHECK(t["image_refused"] == false);
    CHECK(t.contains("likelihood"));
    walked += t["postings_walked"].get<std::uint64_t>();
  }
  CHECK(lines == s->ticks);
  CHECK(walked > 0);
}

}  // namespace
}  // namespace zm
