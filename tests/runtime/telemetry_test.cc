// ticks.jsonl: one valid JSON object per tick, written without allocation.
#include "runtime/telemetry.h"

#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/counting_allocator.h"

namespace zm {
namespace {

TEST_CASE("each tick is one parseable JSON line and writing allocates nothing") {
  const auto path = std::filesystem::temp_directory_path() / "zm_telemetry_test.jsonl";
  TelemetryWriter w;
  REQUIRE(w.Open(path.string()).ok());
  TickRecord r;
  r.zone = ZoneId{3};
  r.resident_keyframes = 120;
  r.over_budget = true;
  r.step_ms[static_cast<int>(TickStep::kApply)] = 1.5;
  {
    test::AllocationCounter counter;
    for (std::uint64_t t = 0; t < 50; ++t) {
      r.tick = t;
      REQUIRE(w.Write(r));
    }
    CHECK(counter.allocations() == 0);
  }
  w.Close();
  std::ifstream in(path);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    const auto j = nlohmann::json::parse(line);
    CHECK(j["tick"] == n);
    CHECK(j["zone"] == 3);
    CHECK(j["resident_keyframes"] == 120);
    CHECK(j["over_budget"] == true);
    CHECK(j["steps_ms"]["apply"] == doctest::Approx(1.5));
    ++n;
  }
  CHECK(n == 50);
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
  const std::string huge(4096, 'x');
  CHECK_FALSE(w.Write(r, huge));
  w.Close();
  std::ifstream in(path);
  std::string line;
  REQUIRE(std::getline(in, line));
  auto j = nlohmann::json::parse(line);
  CHECK(j["oom_kills"] == 2);
  CHECK(j["cgroup_bytes"] == 123);
  CHECK(j["startup"] == true);
  REQUIRE(std::getline(in, line));
  j = nlohmann::json::parse(line);
  CHECK_FALSE(j.contains("oom_kills"));
  CHECK_FALSE(std::getline(in, line));
  std::filesystem::remove(path);
}

TEST_CASE("opening an unwritable path is a clear error") {
  TelemetryWriter w;
  const Status s = w.Open("/nonexistent-dir/ticks.jsonl");
  CHECK(s.code() == StatusCode::kIoError);
  CHECK(s.message().find("/nonexistent-dir/ticks.jsonl") != std::string::npos);
}

}  // namespace
}  // namespace zm
