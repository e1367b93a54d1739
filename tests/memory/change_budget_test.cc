// MemoryPolicy::ChangeBudget (zonemapd's `budget` line) for every policy: down, the bounded
// policies release until they fit, in their own eviction order, and never acquire a keyframe
// that is not resident (so residency never exceeds the new budget at any instant, and nothing is
// read); up, nothing loads at once and the next zone entries use the room. basic lowers its
// MemoryThr and transfers over the next ticks; unbounded ignores it. No allocation.
#include <doctest/doctest.h>

#include <random>

#include "memory/basic_policy.h"
#include "memory/memory_test_util.h"
#include "memory/oracle_policy.h"
#include "memory/predictive_policy.h"
#include "memory/radius_policy.h"
#include "memory/semantic_policy.h"
#include "memory/unbounded_policy.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

using test::At;
using test::Harness;
using V = std::vector<std::int64_t>;

struct Changed {
  std::uint32_t unloaded = 0;
  std::uint32_t loaded = 0;
  std::uint32_t peak = 0;
  std::uint64_t source_calls = 0;  // loads the source saw during the change
};

// Applies policy->ChangeBudget like TickLoop::SetBudget and checks what must hold of any change.
Changed ChangeBudget(Harness& h, std::uint32_t k_max, const TickContext& ctx) {
  const std::uint32_t before = h.ws.resident_count();
  const std::uint64_t calls = h.source.load_zone_calls + h.source.load_keyframes_calls;
  Plan plan(h.index);
  h.policy->ChangeBudget(k_max, ctx, &plan);
  TickTelemetry t;
  const Status s = h.ws.Apply(plan, &t);
  REQUIRE_MESSAGE(s.ok(), s.ToString());
  REQUIRE(h.ws.resident_count() == h.arena.in_use());
  Changed c;
  c.unloaded = t.keyframes_unloaded;
  c.loaded = t.keyframes_loaded;
  c.peak = t.peak_resident_keyframes;
  c.source_calls = h.source.load_zone_calls + h.source.load_keyframes_calls - calls;
  CHECK(c.loaded == 0);          // a change never reads
  CHECK(c.source_calls == 0);
  CHECK(c.peak <= before);       // ... so never holds more than before, at any instant
  return c;
}

TEST_CASE("semantic: a lower budget evicts LRU zones at once, then trims the current zone") {
  // Zones of 3 along x: z0 = {1,2,3} at x 0..2, z1 = {4,5,6}, z2 = {7,8,9}, z3 = {10,11,12}.
  Harness h(test::LineMap({3, 3, 3, 3}), 9, 9, [](const MapIndex& index) {
    return std::make_unique<SemanticPolicy>(index, SemanticOptions{9});
  });
  h.Start(At(0, 0));
  h.Tick(At(1, 1));
  h.Tick(At(2, 2, {7.0, 0, 0}));
  REQUIRE(h.ResidentIds() == V{1, 2, 3, 4, 5, 6, 7, 8, 9});

  Changed c = ChangeBudget(h, 4, At(2, 2, {7.0, 0, 0}));  // z0 (LRU), then z1 go
  CHECK(c.unloaded == 6);
  CHECK(h.ResidentIds() == V{7, 8, 9});

  c = ChangeBudget(h, 2, At(2, 2, {8.9, 0, 0}));  // the current zone alone: nearest 2 kept
  CHECK(c.unloaded == 1);
  CHECK(h.ResidentIds() == V{8, 9});

  c = ChangeBudget(h, 9, At(2, 2, {8.9, 0, 0}));  // up: nothing loads now
  CHECK(c.unloaded == 0);
  CHECK(h.ResidentIds() == V{8, 9});
  h.Tick(At(3, 3, {10.0, 0, 0}));  // ... the next zone entry uses the room
  CHECK(h.ResidentIds() == V{8, 9, 10, 11, 12});
}

TEST_CASE("oracle: a lower budget evicts the zone needed farthest in the future first") {
  // Future: 0 1 2 then 0 again, 1 never: z1 goes before z0 although z0 is the LRU.
  const std::vector<ZoneId> future{ZoneId{0}, ZoneId{1}, ZoneId{2}, ZoneId{0}};
  Harness h(test::LineMap({3, 3, 3}), 9, 9, [&](const MapIndex& index) {
    return std::make_unique<OraclePolicy>(index, OracleOptions{9, future});
  });
  h.Start(At(0, 0));
  h.Tick(At(1, 1));
  h.Tick(At(2, 2));
  ChangeBudget(h, 6, At(2, 2));
  CHECK(h.ResidentIds() == V{1, 2, 3, 7, 8, 9});
}

TEST_CASE("predictive: a lower budget evicts the least valuable zones, then the load order") {
  Harness h(test::LineMap({4, 4, 4}), 12, 12, [](const MapIndex& index) {
    PredictiveOptions o;
    o.k_max = 12;
    o.prefetch = false;
    return std::make_unique<PredictivePolicy>(index, o);
  });
  TickContext c = At(0, 0, {0, 0, 0});
  h.Start(c);
  h.Tick(At(1, 1, {4, 0, 0}));
  h.Tick(At(2, 2, {8, 0, 0}));  // entered at its first keyframe: load order 9, 10, 11, 12
  REQUIRE(h.ws.resident_count() == 12);
  ChangeBudget(h, 5, At(2, 2, {8, 0, 0}));
  CHECK(h.ResidentIds() == V{9, 10, 11, 12});
  ChangeBudget(h, 2, At(2, 2, {8, 0, 0}));
  CHECK(h.ResidentIds() == V{9, 10});
  // Up again: the current zone is topped up on the next tick (its target grows back).
  ChangeBudget(h, 12, At(2, 2, {8, 0, 0}));
  CHECK(h.ResidentIds() == V{9, 10});
  h.Tick(At(3, 2, {8, 0, 0}));
  CHECK(h.ResidentIds() == V{9, 10, 11, 12});
}

TEST_CASE("radius: a lower budget keeps the nearest tiles of the last update") {
  // 40 keyframes 1 m apart along x: 20 m tiles [0, 20) and [20, 40).
  Harness h(test::LineMap({20, 20}), 40, 40, [](const MapIndex& index) {
    RadiusOptions o;
    o.k_max = 40;
    o.tile_m = 20.0;
    o.map_radius_m = 30.0;
    o.update_distance_m = 5.0;
    return std::make_unique<RadiusPolicy>(index, o);
  });
  h.Start(At(0, 0, {5, 0, 0}));
  REQUIRE(h.ws.resident_count() == 40);
  ChangeBudget(h, 25, At(0, 0, {5, 0, 0}));  // tile 0 whole, tile 1 nearest-first: 20..24
  CHECK(h.ws.resident_count() == 25);
  CHECK(h.ResidentIds().back() == 25);
  ChangeBudget(h, 10, At(0, 0, {5, 0, 0}));  // tile 0 only, nearest to x = 5
  CHECK(h.ws.resident_count() == 10);
}

TEST_CASE("basic: a lower MemoryThr is reached by its transfer, a few nodes a tick") {
  BasicOptions o;
  o.memory_thr = 12;
  o.init_wm_with_all_nodes = true;
  Harness h(test::LineMap({4, 4, 4}), 12, 12, [o](const MapIndex& index) {
    return std::make_unique<BasicPolicy>(index, o);
  });
  h.Start(At(0, 0));
  REQUIRE(h.ws.resident_count() == 12);
  const Changed c = ChangeBudget(h, 6, At(0, 0));
  CHECK(c.unloaded == 0);  // RTAB-Map does not unload in bulk
  std::uint32_t last = h.ws.resident_count();
  for (std::uint64_t i = 1; i < 20; ++i) {
    h.Tick(At(i, 0));
    CHECK(h.ws.resident_count() <= last);
    last = h.ws.resident_count();
  }
  CHECK(h.ws.resident_count() == 6);
}

TEST_CASE("unbounded ignores a budget") {
  Harness h(test::LineMap({4, 4}), 8, 8, [](const MapIndex& index) {
    return std::make_unique<UnboundedPolicy>(index);
  });
  h.Start(At(0, 0));
  const Changed c = ChangeBudget(h, 2, At(0, 0));
  CHECK(c.unloaded == 0);
  CHECK(h.ws.resident_count() == 8);
}

TEST_CASE("random walks with random budget changes: every bounded policy stays within budget") {
  const test::MapSpec spec = test::LineMap({5, 7, 3, 9, 4, 6});
  for (const char* name : {"semantic", "oracle", "predictive", "radius"}) {
    CAPTURE(name);
    std::mt19937 rng(11);
    std::vector<ZoneId> future;
    for (int i = 0; i < 400; ++i) future.push_back(ZoneId{static_cast<std::int32_t>(rng() % 6)});
    Harness h(spec, 20, 20, [&](const MapIndex& index) -> std::unique_ptr<MemoryPolicy> {
      const std::string n = name;
      if (n == "semantic") return std::make_unique<SemanticPolicy>(index, SemanticOptions{20});
      if (n == "oracle") return std::make_unique<OraclePolicy>(index, OracleOptions{20, future});
      if (n == "predictive") {
        PredictiveOptions o;
        o.k_max = 20;
        return std::make_unique<PredictivePolicy>(index, o);
      }
      RadiusOptions o;
      o.k_max = 20;
      o.tile_m = 4.0;
      o.map_radius_m = 6.0;
      o.update_distance_m = 2.0;
      return std::make_unique<RadiusPolicy>(index, o);
    });
    h.verify_slots = false;
    const auto start_of = [&](std::int32_t z) {
      std::int64_t first = 0;
      for (std::size_t i = 0; i < static_cast<std::size_t>(z); ++i) {
        first += static_cast<std::int64_t>(spec.zones[i].size());
      }
      return static_cast<double>(first);
    };
    std::uint32_t k = 20;
    h.Start(At(0, future[0].value, {start_of(future[0].value), 0, 0}));
    for (std::uint64_t i = 1; i < future.size(); ++i) {
      const std::int32_t z = future[i].value;
      const TickContext ctx = At(i, z, {start_of(z) + 0.5, 0, 0});
      if (rng() % 5 == 0) {
        k = 1 + static_cast<std::uint32_t>(rng() % 20);
        ChangeBudget(h, k, ctx);
        CHECK(h.ws.resident_count() <= k);
      }
      const std::uint32_t seen_before = h.ws.max_resident_seen();
      const TickTelemetry t = h.Tick(ctx);
      CHECK(t.peak_resident_keyframes <= k);
      CHECK(h.ws.resident_count() <= k);
      CHECK(h.ws.max_resident_seen() <= std::max(seen_before, k));
    }
  }
}

TEST_CASE("a budget change allocates nothing") {
  Harness h(test::LineMap({3, 3, 3, 3}), 9, 9, [](const MapIndex& index) {
    return std::make_unique<SemanticPolicy>(index, SemanticOptions{9});
  });
  h.Start(At(0, 0));
  h.Tick(At(1, 1));
  h.Tick(At(2, 2));
  Plan plan(h.index);
  TickTelemetry t;
  test::AllocationCounter counter;
  for (std::uint32_t k : {6u, 9u, 2u, 9u}) {
    plan.Clear();
    h.policy->ChangeBudget(k, At(2, 2), &plan);
    REQUIRE(h.ws.Apply(plan, &t).ok());
  }
  CHECK(counter.allocations() == 0);
}

}  // namespace
}  // namespace zm
