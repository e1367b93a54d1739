// Time-sliced zone loads (BeginZoneLoad / StepZoneLoad / AbortZoneLoad, map_db.h): each step
// keeps to its budget, a load split over many steps delivers exactly the zone's wanted members
// once each, in order, in one transaction held across the steps; abort and errors end the load
// with no slot leaked and no lock held; other loads are refused meanwhile; warm steps allocate
// nothing. The contract checks run against MapDb and against the fake the memory tests use.
#include <doctest/doctest.h>
#include <sqlite3.h>

#include <chrono>
#include <cstring>
#include <functional>
#include <memory>

#include "mapdb/map_db.h"
#include "mapdb/mapdb_test_util.h"
#include "support/counting_allocator.h"
#include "support/fake_keyframe_source.h"

namespace zm {
namespace {

using test::MakeArena;
using test::RecordingSink;
using test::TempDir;

// Zone 0 = keyframes 1..20, zone 1 = 15..25, zone 2 = 26..30.
test::MapSpec Spec() {
  test::MapSpec s;
  s.count = 30;
  s.members = {{}, {}, {26, 27, 28, 29, 30}};
  for (std::int64_t i = 1; i <= 20; ++i) s.members[0].push_back(i);
  for (std::int64_t i = 15; i <= 25; ++i) s.members[1].push_back(i);
  return s;
}

// A source under test: MapDb over a built map, or the fake with the same zones.
struct Rig {
  TempDir dir;
  std::string path = dir.File("map.db");
  test::BuiltMap built;
  std::unique_ptr<MapDb> db;
  std::unique_ptr<test::FakeKeyframeSource> fake;
  KeyframeSource* source = nullptr;
  std::uint64_t slot_bytes = 0;

  explicit Rig(bool real) {
    const test::MapSpec spec = Spec();
    if (real) {
      built = test::BuildMap(path, spec);
      auto opened = MapDb::Open(path);
      REQUIRE_MESSAGE(opened.ok(), opened.status().ToString());
      db = std::move(opened).value();
      source = db.get();
      slot_bytes = db->metadata().largest_payload_bytes;
    } else {
      std::vector<std::vector<KeyframeId>> zones;
      for (const auto& z : spec.members) {
        zones.emplace_back();
        for (auto id : z) zones.back().push_back(KeyframeId{id});
      }
      fake = std::make_unique<test::FakeKeyframeSource>(zones, 1000);
      source = fake.get();
      slot_bytes = 1000;
    }
  }
  [[nodiscard]] bool real() const { return db != nullptr; }
  [[nodiscard]] std::uint64_t Bytes(std::int64_t id) const {
    return real() ? built.payloads.at(id).size() : 1000;
  }
};

std::vector<std::int64_t> Ids(const RecordingSink& sink) {
  std::vector<std::int64_t> ids;
  for (const auto& e : sink.loaded()) ids.push_back(e.id.value);
  return ids;
}

// Steps the load in flight to its end with `budget`, checking every step with `check`;
// returns the sum of the steps and the number of steps.
std::pair<LoadStats, int> StepToEnd(KeyframeSource& src, const LoadBudget& budget,
                                    const std::function<void(const LoadStats&)>& check) {
  LoadStats sum;
  int steps = 0;
  while (true) {
    auto step = src.StepZoneLoad(budget);
    REQUIRE_MESSAGE(step.ok(), step.status().ToString());
    ++steps;
    check(step->stats);
    sum += step->stats;
    if (step->done) break;
    CHECK(src.ZoneLoadInFlight() == ZoneId{0});
    REQUIRE(steps < 100);
  }
  CHECK(src.ZoneLoadInFlight() == kNoZone);
  return {sum, steps};
}

TEST_CASE("stepped zone load: a keyframe budget per step, exactly the wanted members, one transaction") {
  for (bool real : {true, false}) {
    CAPTURE(real);
    Rig r(real);
    Arena arena = MakeArena(32, r.slot_bytes);
    RecordingSink sink;
    sink.MarkResident(KeyframeId{15});  // shared with a resident zone: skipped, not read
    sink.MarkResident(KeyframeId{16});
    auto begin = r.source->BeginZoneLoad(ZoneId{0}, arena, sink);
    REQUIRE(begin.ok());
    CHECK(begin->transactions == 1);
    CHECK(begin->queries == 1);
    CHECK(begin->keyframes == 0);
    CHECK(r.source->ZoneLoadInFlight() == ZoneId{0});
    const auto [sum, steps] = StepToEnd(*r.source, LoadBudget{.max_keyframes = 3}, [](const LoadStats& s) {
      CHECK(s.keyframes >= 1);
      CHECK(s.keyframes <= 3);
      CHECK(s.transactions == 0);  // the transaction began in BeginZoneLoad
      CHECK(s.queries == 0);
    });
    CHECK(steps == 6);  // 18 wanted members, 3 a step
    std::vector<std::int64_t> want;
    for (std::int64_t i = 1; i <= 20; ++i) {
      if (i != 15 && i != 16) want.push_back(i);
    }
    CHECK(Ids(sink) == want);
    CHECK(sum.keyframes == 18);
    CHECK(sum.skipped == 2);
    CHECK(sum.blob_reads == 18);
    CHECK(arena.in_use() == 18);
    std::uint64_t bytes = 0;
    for (auto id : want) bytes += r.Bytes(id);
    CHECK(sum.bytes == bytes);
    if (real) {
      for (const auto& e : sink.loaded()) {
        const auto& p = r.built.payloads.at(e.id.value);
        CHECK(std::memcmp(arena.Slot(e.slot).data(), p.data(), p.size()) == 0);
      }
      CHECK(r.db->total_transactions() == 1);
    } else {
      CHECK(test::FakeKeyframeSource::SlotHolds(arena, sink.loaded()[4].slot, sink.loaded()[4].id));
      CHECK(r.fake->transactions == 1);
    }
  }
}

TEST_CASE("stepped zone load: byte budgets and deadlines, and every step makes progress") {
  for (bool real : {true, false}) {
    CAPTURE(real);
    Rig r(real);
    Arena arena = MakeArena(32, r.slot_bytes);
    RecordingSink sink;
    SUBCASE("max_bytes: a step takes keyframes while their bytes fit, and never goes past it") {
      const std::uint64_t max_bytes = 2 * r.Bytes(10) + r.Bytes(10) / 2;
      // Steps a greedy budget gives (payload sizes grow with the id in the real map).
      int expect_steps = 0;
      std::uint64_t acc = 0;
      for (std::int64_t id = 1; id <= 20; ++id) {
        if (acc > 0 && acc + r.Bytes(id) > max_bytes) {
          ++expect_steps;
          acc = 0;
        }
        acc += r.Bytes(id);
      }
      ++expect_steps;
      REQUIRE(r.source->BeginZoneLoad(ZoneId{0}, arena, sink).ok());
      const auto [sum, steps] = StepToEnd(*r.source, LoadBudget{.max_bytes = max_bytes},
                                          [&](const LoadStats& s) {
                                            CHECK(s.keyframes >= 1);
                                            CHECK(s.bytes <= max_bytes);
                                          });
      CHECK(steps == expect_steps);
      CHECK(steps > 6);
      CHECK(sum.keyframes == 20);
    }
    SUBCASE("a byte budget smaller than any keyframe still loads one keyframe a step") {
      REQUIRE(r.source->BeginZoneLoad(ZoneId{2}, arena, sink).ok());
      int steps = 0;
      for (bool done = false; !done; ++steps) {
        auto step = r.source->StepZoneLoad(LoadBudget{.max_bytes = 1});
        REQUIRE(step.ok());
        CHECK(step->stats.keyframes == 1);
        done = step->done;
      }
      CHECK(steps == 5);
      CHECK(Ids(sink) == std::vector<std::int64_t>{26, 27, 28, 29, 30});
    }
    SUBCASE("a deadline already passed: one keyframe a step") {
      REQUIRE(r.source->BeginZoneLoad(ZoneId{2}, arena, sink).ok());
      const LoadBudget past{.deadline = std::chrono::steady_clock::now() - std::chrono::seconds(1)};
      int steps = 0;
      for (bool done = false; !done; ++steps) {
        auto step = r.source->StepZoneLoad(past);
        REQUIRE(step.ok());
        CHECK(step->stats.keyframes == 1);
        done = step->done;
      }
      CHECK(steps == 5);
    }
    SUBCASE("a zone whose members are all resident finishes in one step reading nothing") {
      for (std::int64_t i = 26; i <= 30; ++i) sink.MarkResident(KeyframeId{i});
      REQUIRE(r.source->BeginZoneLoad(ZoneId{2}, arena, sink).ok());
      auto step = r.source->StepZoneLoad(LoadBudget{.max_keyframes = 1});
      REQUIRE(step.ok());
      CHECK(step->done);
      CHECK(step->stats.keyframes == 0);
      CHECK(step->stats.skipped == 5);
      CHECK(step->stats.blob_reads == 0);
    }
  }
}

TEST_CASE("stepped zone load: abort ends the load, keeps what was delivered, leaks nothing") {
  for (bool real : {true, false}) {
    CAPTURE(real);
    Rig r(real);
    Arena arena = MakeArena(32, r.slot_bytes);
    RecordingSink sink;
    REQUIRE(r.source->BeginZoneLoad(ZoneId{0}, arena, sink).ok());
    auto step = r.source->StepZoneLoad(LoadBudget{.max_keyframes = 2});
    REQUIRE(step.ok());
    CHECK_FALSE(step->done);
    if (real) CHECK(test::TryWrite(r.path) == SQLITE_BUSY);
    r.source->AbortZoneLoad();
    CHECK(r.source->ZoneLoadInFlight() == kNoZone);
    CHECK(arena.in_use() == 2);  // the two delivered keyframes belong to the sink; nothing else
    if (real) CHECK(test::TryWrite(r.path) == SQLITE_OK);  // the read transaction ended
    auto after = r.source->StepZoneLoad(LoadBudget{});
    CHECK(after.status().code() == StatusCode::kFailedPrecondition);
    r.source->AbortZoneLoad();  // a second abort is a no-op
    // A new load starts cleanly and skips what the sink already holds.
    auto again = r.source->LoadZone(ZoneId{0}, arena, sink);
    REQUIRE_MESSAGE(again.ok(), again.status().ToString());
    CHECK(again->keyframes == 18);
    CHECK(again->skipped == 2);
    CHECK(arena.in_use() == 20);
  }
}

TEST_CASE("stepped zone load: an error in the middle ends the load, its slot released") {
  for (bool real : {true, false}) {
    CAPTURE(real);
    Rig r(real);
    std::string expect;
    std::uint32_t slots = 32;
    SUBCASE("a corrupt payload") {
      expect = "keyframe 4";
      if (real) {
        r.db.reset();
        test::EditPayload(r.path, 4, [](auto& b) { b[100] ^= 0x01; });  // a body byte
        auto opened = MapDb::Open(r.path);
        REQUIRE(opened.ok());
        r.db = std::move(opened).value();
        r.source = r.db.get();
      } else {
        r.fake->fail_on = KeyframeId{4};
      }
    }
    SUBCASE("a full arena") {
      expect = "arena full";
      slots = 3;
    }
    Arena arena = MakeArena(slots, r.slot_bytes);
    RecordingSink sink;
    REQUIRE(r.source->BeginZoneLoad(ZoneId{0}, arena, sink).ok());
    REQUIRE(r.source->StepZoneLoad(LoadBudget{.max_keyframes = 2}).ok());  // 1, 2
    auto failed = r.source->StepZoneLoad(LoadBudget{.max_keyframes = 2});  // 3, then 4 fails
    REQUIRE_FALSE(failed.ok());
    INFO(failed.status().ToString());
    CHECK(failed.status().message().find(expect) != std::string::npos);
    CHECK(Ids(sink) == std::vector<std::int64_t>{1, 2, 3});
    CHECK(arena.in_use() == 3);  // 4's slot (when one was taken) went back
    CHECK(r.source->ZoneLoadInFlight() == kNoZone);
    if (real) CHECK(test::TryWrite(r.path) == SQLITE_OK);
    CHECK(r.source->StepZoneLoad(LoadBudget{}).status().code() == StatusCode::kFailedPrecondition);
  }
}

TEST_CASE("stepped zone load: one transaction spans the steps (a writer waits for the whole load)") {
  Rig r(true);
  Arena arena = MakeArena(32, r.slot_bytes);
  RecordingSink sink;
  CHECK(test::TryWrite(r.path) == SQLITE_OK);
  REQUIRE(r.db->BeginZoneLoad(ZoneId{1}, arena, sink).ok());
  int steps = 0;
  for (bool done = false; !done; ++steps) {
    // Between steps the read lock is held: no writer can commit, so every step sees the map
    // exactly as it was when the load began.
    CHECK(test::TryWrite(r.path) == SQLITE_BUSY);
    auto step = r.db->StepZoneLoad(LoadBudget{.max_keyframes = 4});
    REQUIRE(step.ok());
    done = step->done;
  }
  CHECK(steps == 3);  // 11 members, 4 a step
  CHECK(test::TryWrite(r.path) == SQLITE_OK);
  CHECK(r.db->total_transactions() == 1);
}

TEST_CASE("stepped zone load: other loads are refused while one is in flight") {
  for (bool real : {true, false}) {
    CAPTURE(real);
    Rig r(real);
    Arena arena = MakeArena(32, r.slot_bytes);
    RecordingSink sink;
    REQUIRE(r.source->BeginZoneLoad(ZoneId{0}, arena, sink).ok());
    const KeyframeId ids[] = {KeyframeId{26}};
    const auto refused = [](const Status& s) {
      INFO(s.ToString());
      CHECK(s.code() == StatusCode::kFailedPrecondition);
      CHECK(s.message().find("zone 0") != std::string::npos);
      CHECK(s.message().find("in flight") != std::string::npos);
    };
    refused(r.source->BeginZoneLoad(ZoneId{2}, arena, sink).status());
    refused(r.source->LoadZone(ZoneId{2}, arena, sink).status());
    refused(r.source->LoadKeyframes(ids, arena, sink).status());
    refused(r.source->ReadGraphNodes(ids, nullptr).status());
    CHECK(arena.in_use() == 0);
    // The load in flight is unharmed.
    const auto [sum, steps] = StepToEnd(*r.source, LoadBudget{.max_keyframes = 7}, [](const LoadStats&) {});
    CHECK(sum.keyframes == 20);
    CHECK(steps == 3);
  }
}

TEST_CASE("stepped zone load: warm steps allocate nothing") {
  Rig r(true);
  Arena arena = MakeArena(32, r.slot_bytes);
  RecordingSink sink;
  const auto cycle = [&] {
    for (std::int32_t z = 0; z < 3; ++z) {
      REQUIRE(r.db->BeginZoneLoad(ZoneId{z}, arena, sink).ok());
      bool done = false;
      while (!done) {
        auto step = r.db->StepZoneLoad(LoadBudget{.max_keyframes = 2});
        REQUIRE(step.ok());
        done = step->done;
      }
    }
    REQUIRE(r.db->BeginZoneLoad(ZoneId{0}, arena, sink).ok());
    REQUIRE(r.db->StepZoneLoad(LoadBudget{.max_keyframes = 1}).ok());
    r.db->AbortZoneLoad();
    sink.ReleaseAll(arena);
  };
  cycle();  // warm-up
  const std::int64_t sqlite_before = sqlite3_memory_used();
  test::AllocationCounter counter;
  for (int i = 0; i < 10; ++i) cycle();
  CHECK(counter.allocations() == 0);
  CHECK(sqlite3_memory_used() == sqlite_before);
  CHECK(arena.in_use() == 0);
}

}  // namespace
}  // namespace zm
