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
  s.loop_closures = 53;
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

  auto back = RunSummaryFromJson(j);
  REQUIRE(back.ok());
  CHECK(ToJson(*back) == j);
  REQUIRE(back->replay.has_value());
  CHECK(back->replay->trajectory.associated_poses == 4128u);
  CHECK(back->first_error == "I/O error: disk");
}

TEST_CASE("summary.json: a live session has no replay part; its metrics keys are absent") {
  RunSummary s = Example();
  s.replay.reset();
  s.ledger_refusals.reset();
  const nlohmann::json j = ToJson(s);
  CHECK_FALSE(j.contains("wall_s"));
  CHECK_FALSE(j.contains("ate_rmse_m"));
  CHECK_FALSE(j.contains("ledger_refusals"));
  auto back = RunSummaryFromJson(j);
  REQUIRE(back.ok());
  CHECK_FALSE(back->replay.has_value());
}

TEST_CASE("summary.json: an older file keeps defaults; a wrong type or a newer version is named") {
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
