// Where a tick's time goes (issue 26): the five stages of every tick (TickRecord::stage_ms) sum
// to at most the tick's time, the run's statistics of each reach summary.json's `stages`, and the
// closures accepted beside the frames localized. On a map the localizer really closes loops on
// (rooms_map.h), so the verify and memory stages do work; the pixel path (features, quantize,
// likelihood) is tests/harness/run_test.cc's.
#include <doctest/doctest.h>

#include <numeric>

#include "rooms_map.h"
#include "runtime/frame_source.h"
#include "runtime/summary.h"
#include "runtime/tick_loop.h"

namespace zm {
namespace {

using test::RoomsMap;

TEST_CASE("stage times sum to at most the tick time, and the summary has every stage") {
  RoomsMap map(3, 8, "stages");
  auto db = MapDb::Open(map.db());
  REQUIRE(db.ok());
  StagedFrameSource frames(64);
  LoopConfig c;
  c.policy.kind = PolicyKind::kSemantic;
  c.map.memory_thr_keyframes = 16;
  c.localizer.reserve_features = 64;
  auto loop = TickLoop::Create(c, **db, frames);
  REQUIRE_MESSAGE(loop.ok(), loop.status().ToString());
  TickLoop& l = **loop;

  std::uint64_t localized = 0;
  for (int i = 0; i < 40; ++i) {
    // Every fourth frame unrecognisable: no candidate, the tick on odometry.
    frames.staging() = map.FrameAt(0.5 * i, 1.0 + 0.7 * i, i % 4 != 3);
    frames.Stage();
    REQUIRE(l.Tick().value());
    const TickRecord& r = l.last_record();
    const double stages = std::accumulate(std::begin(r.stage_ms), std::end(r.stage_ms), 0.0);
    CHECK(stages <= r.tick_ms + 1e-9);  // the stages leave out reading the frame and recording
    for (double ms : r.stage_ms) CHECK(ms >= 0.0);
    CHECK(r.stage_ms[static_cast<int>(LoopStage::kMemory)] > 0.0);
    CHECK(r.stage_ms[static_cast<int>(LoopStage::kFeatures)] == 0.0);  // features came with it
    CHECK_FALSE(r.has_image);
    CHECK_FALSE(r.vocabulary);
    if (r.loop_closure) {
      ++localized;
      CHECK(r.stage_ms[static_cast<int>(LoopStage::kVerify)] > 0.0);  // matching and PnP
    }
  }
  const LoopTotals& t = l.totals();
  CHECK(localized > 20);
  CHECK(t.frames_localized == localized);
  CHECK(t.closures_accepted == localized);  // at most one a frame
  CHECK(t.images_refused == 0);
  for (const StreamingStats& s : t.stage_ms) CHECK(s.count() == t.tick_ms.count());

  const RunSummary s = LoopSummary(l, false);
  const auto verify = static_cast<std::size_t>(LoopStage::kVerify);
  CHECK(s.stages[verify].p50_ms == doctest::Approx(t.stage_ms[verify].Quantile(0.5)));
  CHECK(s.stages[verify].p99_ms >= s.stages[verify].p50_ms);
  CHECK(s.frames_localized == localized);
  const nlohmann::json j = ToJson(s);
  for (int i = 0; i < kLoopStageCount; ++i) {
    const char* name = LoopStageName(static_cast<LoopStage>(i));
    CHECK_MESSAGE(j["stages"][name]["p50_ms"].is_number(), name);
    CHECK_MESSAGE(j["stages"][name]["p99_ms"].is_number(), name);
  }
  CHECK(j["stages"]["memory"]["p50_ms"].get<double>() > 0.0);
  CHECK(j["closures_accepted"] == localized);
  CHECK(j["images_refused"] == 0);
  CHECK_FALSE(j.contains("frame_scratch"));  // no images, no front-end
}

}  // namespace
}  // namespace zm
