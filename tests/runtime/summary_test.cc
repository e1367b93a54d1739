// summary.json (lib/runtime/summary.h): TimeTotal four ways (the one derivation LoopSummary and
// the summary of a killed run share, on counts worked by hand), and the one codec: what ToJson
// writes RunSummaryFromJson reads back, keys the docs quote stay, bad input is named.
#include "runtime/summary.h"

#include <doctest/doctest.h>

namespace zm {
namespace {

TEST_CASE("TimeTotal with and without the start-up tick and the idle-time loads") {
  // Four steady ticks averaging 10 ms, of which 8 ms in all were waits on idle-time loads; the
  // idle parts ran 40 ms of loads; the start-up tick took 1,000 ms.
  const TimeTotal t = TimeTotalOf({.steady_mean_ms = 10.0,
                                   .steady_ticks = 4,
                                   .has_startup = true,
                                   .startup_tick_ms = 1000.0,
                                   .late_ms = 8.0,
                                   .idle_load_ms = 40.0});
  CHECK(t.steady == doctest::Approx(10.0));
  CHECK(t.with_startup == doctest::Approx((4 * 10.0 + 1000.0) / 5));  // 208
  CHECK(t.without_idle_loads == doctest::Approx(10.0 - 2.0));
  CHECK(t.with_idle_loads == doctest::Approx(10.0 - 2.0 + 10.0));
}

TEST_CASE("TimeTotal of a run that only had its start-up tick, and of none") {
  const TimeTotal only = TimeTotalOf({.has_startup = true, .startup_tick_ms = 500.0});
  CHECK(only.steady == 0.0);
  CHECK(only.with_startup == doctest::Approx(500.0));
  CHECK(only.with_idle_loads == 0.0);
  const TimeTotal none = TimeTotalOf({});
  CHECK(none.with_startup == 0.0);
}

RunSummary Example() {
  RunSummary s;
  s.policy = "semantic";
  s.k_max = 410;
  s.slot_bytes = 2156992;
  s.ticks = 4128;
  s.update_rate_hz = 0.97;
  s.tick_ms = {.mean = 5.5, .p50 = 4.25, .p99 = 31.0, .max = 240.5, .count = 4127};
  s.time_total_ms = {.steady = 5.5, .with_startup = 5.6, .without_idle_loads = 5.0,
                     .with_idle_loads = 7.25};
  s.startup.keyframes_loaded = 120;
  s.steady_state.db_transactions = 77;
  s.closures_accepted = 53;
  s.frames_localized = 53;
  s.closures_rejected = 12;
  s.images_refused = 2;
  s.first_image_error = "invalid argument: frame 7: colour image is empty";
  s.stages[static_cast<std::size_t>(LoopStage::kFeatures)] = {
      .p50_ms = 3.5, .p99_ms = 6.0, .mean_ms = 3.75};
  s.stages[static_cast<std::size_t>(LoopStage::kLikelihood)] = {
      .p50_ms = 0.25, .p99_ms = 1.5, .mean_ms = 0.5};
  s.frame_scratch = FrameScratchStats{.capacity_bytes = 2682880,
                                      .high_water_bytes = 610304,
                                      .allocations = 512000,
                                      .overflows = 0,
                                      .scopes = 4128,
                                      .blocks_outliving_scope = 0};
  s.loads.late_ms_total = 12.5;
  s.first_error = "I/O error: disk";
  ReplaySummary r;
  r.profile = "profiles/orin-nano-8gb.toml";
  r.scenario = "out/demo/scenarios/hospital";
  r.time_compression = 20.0;
  r.realtime_frames = true;
  r.frames_arrived = 4200;
  r.frames_dropped = 72;
  r.wall_s = 210.0;
  r.update_rate_model_hz = 1.0;
  r.trajectory.ate_rmse_m = 0.14;
  r.trajectory.ate_se3_rmse_m = 0.12;
  r.trajectory.associated_poses = 4128;
  s.replay = r;
  s.ledger_refusals = 3;
  return s;
}

TEST_CASE("summary.json: versioned, and what ToJson writes reads back the same") {
  const RunSummary s = Example();
  const nlohmann::json j = ToJson(s);
  CHECK(j["schema_version"] == kSummarySchemaVersion);
  // Keys the README, docs and scripts quote.
  CHECK(j["tick_ms"]["p99"] == 31.0);
  CHECK(j["time_total_ms"]["with_idle_loads"] == 7.25);
  CHECK(j["steady_state"]["db_transactions"] == 77);
  CHECK(j["loads"]["late_ms_total"] == 12.5);
  CHECK(j["ate_rmse_m"] == 0.14);
  CHECK(j["rpe_trans_rmse_m"].is_null());  // not measured: null, but present
  CHECK(j["frames_dropped"] == 72);
  CHECK(j["ledger_refusals"] == 3);
  CHECK_FALSE(j.contains("partial"));
  CHECK(j["stages"]["features"]["p50_ms"] == 3.5);
  CHECK(j["stages"]["likelihood"]["p99_ms"] == 1.5);
  CHECK(j["stages"]["verify"]["p99_ms"] == 0.0);  // every stage, also one that took no time
  CHECK(j["stages"].size() == kLoopStageCount);
  CHECK(j["closures_accepted"] == 53);
  CHECK(j["frames_localized"] == 53);
  CHECK_FALSE(j.contains("loop_closures"));  // version 2: the count has its explicit name
  CHECK(j["images_refused"] == 2);
  CHECK(j["frame_scratch"]["high_water_bytes"] == 610304);

  auto back = RunSummaryFromJson(j);
  REQUIRE(back.ok());
  CHECK(ToJson(*back) == j);
  REQUIRE(back->replay.has_value());
  CHECK(back->replay->trajectory.associated_poses == 4128u);
  CHECK(back->first_error == "I/O error: disk");
  CHECK(back->stages[static_cast<std::size_t>(LoopStage::kFeatures)].mean_ms == 3.75);
  REQUIRE(back->frame_scratch.has_value());
  CHECK(back->frame_scratch->capacity_bytes == 2682880u);
}

TEST_CASE("summary.json: a version-1 file's loop_closures is read as both counts") {
  // Version 1 counted the frames whose closure was accepted (at most one a frame).
  auto v1 = RunSummaryFromJson({{"schema_version", 1},
                                {"policy", "semantic"},
                                {"loop_closures", 35},
                                {"closures_rejected", 9}});
  REQUIRE(v1.ok());
  CHECK(v1->closures_accepted == 35u);
  CHECK(v1->frames_localized == 35u);
  CHECK(v1->closures_rejected == 9u);
  CHECK(v1->stages[0].p50_ms == 0.0);  // no stages before version 2
  CHECK_FALSE(v1->frame_scratch.has_value());
  // A version-2 file has no loop_closures: one there is not read.
  auto v2 = RunSummaryFromJson({{"schema_version", 2}, {"loop_closures", 35}});
  REQUIRE(v2.ok());
  CHECK(v2->closures_accepted == 0u);
}

TEST_CASE("summary.json: a live session has no replay part, and its metrics keys are absent") {
  RunSummary s = Example();
  s.replay.reset();
  s.ledger_refusals.reset();
  s.frame_scratch.reset();
  const nlohmann::json j = ToJson(s);
  CHECK_FALSE(j.contains("frame_scratch"));  // frames without images: no front-end
  CHECK_FALSE(j.contains("wall_s"));
  CHECK_FALSE(j.contains("ate_rmse_m"));
  CHECK_FALSE(j.contains("ledger_refusals"));
  auto back = RunSummaryFromJson(j);
  REQUIRE(back.ok());
  CHECK_FALSE(back->replay.has_value());
  CHECK_FALSE(back->frame_scratch.has_value());
}

TEST_CASE("summary.json: an older file keeps defaults, a wrong type or a newer version is named") {
  auto old = RunSummaryFromJson({{"policy", "basic"}, {"ticks", 7}});
  REQUIRE(old.ok());
  CHECK(old->schema_version == 0);
  CHECK(old->ticks == 7u);
  CHECK(old->tick_ms.count == 0u);

  auto typed = RunSummaryFromJson({{"tick_ms", {{"p99", "slow"}}}});
  REQUIRE_FALSE(typed.ok());
  CHECK(typed.status().message().find("tick_ms.p99") != std::string::npos);

  auto negative = RunSummaryFromJson({{"ticks", -1}});
  REQUIRE_FALSE(negative.ok());
  CHECK(negative.status().message().find("ticks") != std::string::npos);

  auto newer = RunSummaryFromJson({{"schema_version", kSummarySchemaVersion + 1}});
  REQUIRE_FALSE(newer.ok());
  CHECK(newer.status().message().find("schema_version") != std::string::npos);

  CHECK_FALSE(RunSummaryFromJson(nlohmann::json::array()).ok());
}

}  // namespace
}  // namespace zm
