// WorkingSet: unload-before-load against a full arena, pinning of shared keyframes, rollback
// when the source fails or does not deliver, telemetry, and the resident view.
#include "memory/working_set.h"

#include <doctest/doctest.h>

#include "memory/memory_test_util.h"

namespace zm {
namespace {

using V = std::vector<std::int64_t>;

struct Rig {
  explicit Rig(const test::MapSpec& s, std::uint32_t slots, std::uint32_t k_max)
      : index(test::BuildIndex(s)),
        arena(test::MakeArena(slots)),
        source(test::ZoneIds(s), 100),
        ws(index, arena, source, k_max),
        plan(index) {}
  KfIndex K(std::int64_t id) const { return index.Find(KeyframeId{id}); }
  MapIndex index;
  Arena arena;
  test::FakeKeyframeSource source;
  WorkingSet ws;
  Plan plan;
};

TEST_CASE("working set: unloads happen before loads / so a full arena is never exceeded") {
  Rig r(test::LineMap({3, 3}), 3, 3);
  TickTelemetry t;
  r.plan.BeginBatch(ZoneId{0});
  for (std::int64_t id : {1, 2, 3}) r.plan.Acquire(r.K(id));
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  CHECK(r.arena.available() == 0);
  r.plan.Clear();
  for (std::int64_t id : {1, 2, 3}) r.plan.Release(r.K(id));
  r.plan.BeginBatch(ZoneId{1});
  for (std::int64_t id : {4, 5, 6}) r.plan.Acquire(r.K(id));
  t = {};
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  CHECK(t.keyframes_unloaded == 3);
  CHECK(t.keyframes_loaded == 3);
  CHECK(t.db_transactions == 1);
  CHECK(t.db_bytes_read == 300);
  CHECK(t.resident_bytes == 300);
  CHECK(t.peak_resident_keyframes == 3);
  CHECK_FALSE(t.over_budget);
  CHECK(t.refused_acquisitions == 0);
  CHECK(r.ws.max_resident_seen() == 3);
  for (const auto& res : r.ws.resident()) {
    CHECK(test::FakeKeyframeSource::SlotHolds(r.arena, res.slot, res.id));
    CHECK(r.ws.slot(res.index) == res.slot);
  }
}

TEST_CASE("working set: load-then-unload on a full arena fails cleanly and rolls back") {
  Rig r(test::LineMap({3, 3}), 3, 3);
  TickTelemetry t;
  r.plan.BeginBatch(ZoneId{0});
  for (std::int64_t id : {1, 2, 3}) r.plan.Acquire(r.K(id));
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  r.plan.Clear();
  r.plan.order = PlanOrder::kLoadThenUnload;
  r.plan.Release(r.K(1));
  r.plan.BeginBatch(kNoZone);
  r.plan.Acquire(r.K(4));
  t = {};
  Status s = r.ws.Apply(r.plan, &t);
  CHECK(s.code() == StatusCode::kResourceExhausted);
  CHECK(s.message().find("loading keyframes") != std::string::npos);
  CHECK(t.refused_acquisitions == 1);
  CHECK(r.ws.refcount(r.K(4)) == 0);  // rolled back
  CHECK(r.ws.resident_count() == r.arena.in_use());
}

TEST_CASE("working set: a keyframe released and acquired in one plan is not re-read") {
  Rig r(test::LineMap({3}), 3, 3);
  TickTelemetry t;
  r.plan.BeginBatch(ZoneId{0});
  for (std::int64_t id : {1, 2}) r.plan.Acquire(r.K(id));
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  const SlotIndex before = r.ws.slot(r.K(2));
  r.plan.Clear();
  r.plan.Release(r.K(1));
  r.plan.Release(r.K(2));
  r.plan.BeginBatch(ZoneId{0});
  for (std::int64_t id : {2, 3}) r.plan.Acquire(r.K(id));
  t = {};
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  CHECK(t.keyframes_unloaded == 1);
  CHECK(t.keyframes_loaded == 1);
  CHECK(test::Ids(r.source.calls.back().loaded) == V{3});
  CHECK(r.ws.slot(r.K(2)) == before);
  CHECK(r.ws.refcount(r.K(2)) == 1);
}

TEST_CASE("working set: a batch with nothing new costs no transaction - undelivered is an error") {
  test::MapSpec s = test::LineMap({2, 2});
  Rig r(s, 4, 4);
  TickTelemetry t;
  r.plan.BeginBatch(ZoneId{0});
  for (std::int64_t id : {1, 2}) r.plan.Acquire(r.K(id));
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  r.plan.Clear();
  r.plan.BeginBatch(ZoneId{0});
  r.plan.Acquire(r.K(1));
  t = {};
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  CHECK(t.db_transactions == 0);
  CHECK(r.ws.refcount(r.K(1)) == 2);
  // Acquires of resident keyframes only count references (refcount(1) becomes 3).
  r.plan.Clear();
  r.plan.BeginBatch(ZoneId{1});
  r.plan.Acquire(r.K(3));
  r.plan.Acquire(r.K(1));  // already resident: pinned, fine
  r.plan.BeginBatch(ZoneId{1});
  r.plan.Acquire(r.K(2));  // resident too
  t = {};
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  r.plan.Clear();
  for (std::int64_t id : {1, 1, 1}) r.plan.Release(r.K(id));
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  r.plan.Clear();
  for (std::int64_t id : {2, 2, 3}) r.plan.Release(r.K(id));
  REQUIRE(r.ws.Apply(r.plan, &t).ok());
  CHECK(r.ws.resident_count() == 0);
  r.plan.Clear();
  r.plan.BeginBatch(ZoneId{1});
  r.plan.Acquire(r.K(1));  // keyframe 1 is not in zone 1: the source never delivers it
  Status st = r.ws.Apply(r.plan, &t);
  CHECK(st.code() == StatusCode::kNotFound);
  CHECK(st.message().find("LoadZone(1)") != std::string::npos);
  CHECK(r.ws.refcount(r.K(1)) == 0);
  CHECK(r.arena.in_use() == 0);
}

}  // namespace
}  // namespace zm
