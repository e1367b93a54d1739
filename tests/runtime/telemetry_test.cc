// ticks.jsonl: one valid JSON object per tick, written without allocation.
#include "runtime/telemetry.h"

#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "support/counting_allocator.h"

namespace zm {
namespace {

// The JSON object of each line of `path`, which is then removed.
std::vector<nlohmann::json> ReadAndRemove(const std::filesystem::path& path) {
  std::vector<nlohmann::json> lines;
  {
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);) lines.push_back(nlohmann::json::parse(line));
  }
  std::filesystem::remove(path);
  return lines;
}

TEST_CASE("each tick is one parseable JSON line and writing allocates nothing") {
  const auto path = std::filesystem::temp_directory_path() / "zm_telemetry_test.jsonl";
  TelemetryWriter w;
  REQUIRE(w.Open(path.string()).ok());
  TickRecord r;
  r.zone = ZoneId{3};
  r.resident_keyframes = 120;
  r.over_budget = true;
  r.step_ms[static_cast<int>(TickStep::kApply)] = 1.5;
  r.stage_ms[static_cast<int>(LoopStage::kFeatures)] = 3.25;
  r.stage_ms[static_cast<int>(LoopStage::kLikelihood)] = 0.5;
  r.features = 812;
  r.has_image = true;
  r.vocabulary = true;
  r.likelihood = 0.125f;
  r.postings_walked = 4600;
  {
    test::AllocationCounter counter;
    for (std::uint64_t t = 0; t < 50; ++t) {
      r.tick = t;
      REQUIRE(w.Write(r));
    }
    CHECK(counter.allocations() == 0);
  }
  w.Close();
  int n = 0;
  for (const nlohmann::json& j : ReadAndRemove(path)) {
    CHECK(j["tick"] == n);
    CHECK(j["zone"] == 3);
    CHECK(j["resident_keyframes"] == 120);
    CHECK(j["over_budget"] == true);
    CHECK(j["steps_ms"]["apply"] == doctest::Approx(1.5));
    // The stages (issue 26), by name, and what localization worked on.
    CHECK(j["stages_ms"].size() == kLoopStageCount);
    CHECK(j["stages_ms"]["features"] == doctest::Approx(3.25));
    CHECK(j["stages_ms"]["likelihood"] == doctest::Approx(0.5));
    CHECK(j["stages_ms"]["verify"] == 0.0);
    CHECK(j["features"] == 812);
    CHECK(j["image_refused"] == false);
    CHECK(j["likelihood"] == doctest::Approx(0.125));
    CHECK(j["postings_walked"] == 4600);
    ++n;
  }
  CHECK(n == 50);
}

TEST_CASE("a frame with features and no vocabulary: only the members that exist") {
  const auto path = std::filesystem::temp_directory_path() / "zm_telemetry_plain_test.jsonl";
  TelemetryWriter w;
  REQUIRE(w.Open(path.string()).ok());
  TickRecord r;
  r.features = 30;
  REQUIRE(w.Write(r));
  w.Close();
  const std::vector<nlohmann::json> lines = ReadAndRemove(path);
  REQUIRE(lines.size() == 1);
  const nlohmann::json& j = lines[0];
  CHECK(j["features"] == 30);
  CHECK(j["stages_ms"]["memory"] == 0.0);
  CHECK_FALSE(j.contains("image_refused"));  // no image: nothing to refuse
  CHECK_FALSE(j.contains("likelihood"));     // no vocabulary: no likelihood
  CHECK_FALSE(j.contains("postings_walked"));
}

TEST_CASE("the widest record with the publisher's longest extra still fits one line") {
  const auto path = std::filesystem::temp_directory_path() / "zm_telemetry_wide_test.jsonl";
  TelemetryWriter w;
  REQUIRE(w.Open(path.string()).ok());
  TickRecord r;
  constexpr std::uint64_t k64 = ~std::uint64_t{0};
  constexpr std::uint32_t k32 = ~std::uint32_t{0};
  r.tick = k64;
  r.stamp_s = -4.0e9;
  r.x_m = r.y_m = -1.0e9;
  r.yaw_rad = -3.14159;
  r.zone = ZoneId{-2147483647};
  r.resident_keyframes = r.keyframes_loaded = r.keyframes_unloaded = k32;
  r.db_transactions = r.db_queries = r.db_blob_reads = r.search_queries = k32;
  r.search_transactions = r.startup_db_queries = r.startup_db_transactions = k32;
  r.startup_db_blob_reads = r.pending_keyframes = r.idle_keyframes_loaded = k32;
  r.resident_bytes = r.db_bytes_read = r.refused_acquisitions = r.postings_walked = k64;
  r.load_ms = r.unload_ms = r.idle_load_ms = r.late_ms = r.tick_ms = 1.0e9;
  r.matched_keyframe = r.highest_hypothesis = -9223372036854775807LL;
  r.inliers = r.candidates = r.features = k32;
  r.startup = r.over_budget = r.loop_closure = r.stalled = true;
  r.has_image = r.image_refused = r.vocabulary = true;
  r.likelihood = 1.0f;
  for (double& ms : r.step_ms) ms = 1.0e9;
  for (double& ms : r.stage_ms) ms = 1.0e9;
  const std::string extra(1535, ' ');  // TickPublisher's extra buffer, full
  CHECK(w.Write(r, extra));
  w.Close();
  std::filesystem::remove(path);
}

TEST_CASE("a caller's extra members land inside the same JSON object") {
  const auto path = std::filesystem::temp_directory_path() / "zm_telemetry_extra_test.jsonl";
  TelemetryWriter w;
  REQUIRE(w.Open(path.string()).ok());
  TickRecord r;
  r.startup = true;
  REQUIRE(w.Write(r, "\"oom_kills\":2,\"cgroup_bytes\":123"));
  REQUIRE(w.Write(r));
  // A fragment that does not fit the fixed line buffer is refused, never truncated into bad JSON.
  const std::string huge(8192, 'x');
  CHECK_FALSE(w.Write(r, huge));
  w.Close();
  const std::vector<nlohmann::json> lines = ReadAndRemove(path);
  REQUIRE(lines.size() == 2);
  CHECK(lines[0]["oom_kills"] == 2);
  CHECK(lines[0]["cgroup_bytes"] == 123);
  CHECK(lines[0]["startup"] == true);
  CHECK_FALSE(lines[1].contains("oom_kills"));
}

TEST_CASE("opening an unwritable path is a clear error") {
  TelemetryWriter w;
  const Status s = w.Open("/nonexistent-dir/ticks.jsonl");
  CHECK(s.code() == StatusCode::kIoError);
  CHECK(s.message().find("/nonexistent-dir/ticks.jsonl") != std::string::npos);
}

}  // namespace
}  // namespace zm
