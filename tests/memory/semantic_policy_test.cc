// Algorithm 1 on hand-made zone sequences: exact load/unload lists, union counting with
// overlaps, the oversize fallback, the start-up load, and no allocation once warm.
#include "memory/semantic_policy.h"

#include <doctest/doctest.h>

#include <random>

#include "memory/memory_test_util.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

using test::At;
using test::Harness;
using test::Ids;
using test::Zones;
using V = std::vector<std::int64_t>;
using Zv = std::vector<std::int32_t>;

Harness::Factory Semantic(std::uint32_t k_max) {
  return [k_max](const MapIndex& index) {
    return std::make_unique<SemanticPolicy>(index, SemanticOptions{k_max});
  };
}

TEST_CASE("semantic: zone-level LRU / unload before load / one transaction per zone") {
  // Zones of 3: z0 = {1,2,3}, z1 = {4,5,6}, z2 = {7,8,9}, z3 = {10,11,12}; two zones fit.
  Harness h(test::LineMap({3, 3, 3, 3}), 6, 6, Semantic(6));
  auto t = h.Start(At(0, 0));
  CHECK(Zones(h.before.zones_loaded()) == Zv{0});
  CHECK(h.ResidentIds() == V{1, 2, 3});
  CHECK(t.db_transactions == 1);

  t = h.Tick(At(1, 1));
  CHECK(Zones(h.before.zones_unloaded()).empty());
  CHECK(Zones(h.before.zones_loaded()) == Zv{1});
  CHECK(h.ResidentIds() == V{1, 2, 3, 4, 5, 6});

  t = h.Tick(At(2, 2));  // K_pred = 9 > 6: the LRU zone (0) goes first
  CHECK(Zones(h.before.zones_unloaded()) == Zv{0});
  CHECK(Ids(h.index, h.before.releases()) == V{1, 2, 3});
  CHECK(Zones(h.before.zones_loaded()) == Zv{2});
  CHECK(Ids(h.index, h.before.acquires()) == V{7, 8, 9});
  CHECK(t.keyframes_unloaded == 3);
  CHECK(t.keyframes_loaded == 3);
  CHECK(t.db_transactions == 1);
  CHECK(t.peak_resident_keyframes == 6);

  t = h.Tick(At(3, 1));  // back into a resident zone: nothing to do
  CHECK(h.before.empty());
  CHECK(t.db_transactions == 0);

  t = h.Tick(At(4, 3));  // z1 was entered last, so z2 is the LRU
  CHECK(Zones(h.before.zones_unloaded()) == Zv{2});
  CHECK(Zones(h.before.zones_loaded()) == Zv{3});
  CHECK(h.ResidentIds() == V{4, 5, 6, 10, 11, 12});

  // The fake saw exactly these zone loads, in order, each delivering the whole zone.
  REQUIRE(h.source.calls.size() == 4);
  CHECK(h.source.calls[0].zone == ZoneId{0});
  CHECK(h.source.calls[1].zone == ZoneId{1});
  CHECK(h.source.calls[2].zone == ZoneId{2});
  CHECK(h.source.calls[3].zone == ZoneId{3});
  CHECK(Ids(h.source.calls[3].loaded) == V{10, 11, 12});
  CHECK(h.source.transactions == 4);
  CHECK(h.policy->zone_loads() == 4);
  CHECK(h.ws.max_resident_seen() == 6);
}

TEST_CASE("semantic: a pose outside every zone keeps the current zone") {
  Harness h(test::LineMap({3, 3}), 3, 3, Semantic(3));
  h.Start(At(0, 0));
  for (std::uint64_t i = 1; i < 5; ++i) {
    h.Tick(At(i, -1));
    CHECK(h.before.empty());
  }
  CHECK(h.ResidentIds() == V{1, 2, 3});
  auto* p = static_cast<SemanticPolicy*>(h.policy.get());
  CHECK(p->current_zone() == ZoneId{0});
}

TEST_CASE("semantic: start-up loads only the initial zone / or nothing outside zones") {
  Harness h(test::LineMap({2, 2, 2, 2}), 8, 8, Semantic(8));
  h.Start(At(0, 2));
  CHECK(h.ResidentIds() == V{5, 6});
  Harness h2(test::LineMap({2, 2}), 4, 4, Semantic(4));
  h2.Start(At(0, -1));
  CHECK(h2.ResidentIds().empty());
  h2.Tick(At(1, 1));
  CHECK(h2.ResidentIds() == V{3, 4});
}

TEST_CASE("semantic: overlapping zones are counted as unions") {
  test::MapSpec s = test::LineMap({8});
  s.zones = {{1, 2, 3, 4}, {4, 5, 6}, {6, 7, 8}};
  Harness h(s, 6, 6, Semantic(6));
  h.Start(At(0, 0));
  auto t = h.Tick(At(1, 1));  // K_pred = 4 + |{5,6}| = 6: fits, nothing unloaded
  CHECK(h.before.zones_unloaded().empty());
  CHECK(t.keyframes_loaded == 2);
  CHECK(Ids(h.source.calls.back().loaded) == V{5, 6});  // 4 is not read twice
  CHECK(h.ws.refcount(h.index.Find(KeyframeId{4})) == 2);

  t = h.Tick(At(2, 2));  // K_pred = 6 + |{7,8}| = 8 > 6: evict z0, which frees 1,2,3 (4 stays)
  CHECK(Zones(h.before.zones_unloaded()) == Zv{0});
  CHECK(t.keyframes_unloaded == 3);
  CHECK(t.keyframes_loaded == 2);
  CHECK(h.ResidentIds() == V{4, 5, 6, 7, 8});
  CHECK(h.ws.refcount(h.index.Find(KeyframeId{6})) == 2);
  CHECK(h.ws.refcount(h.index.Find(KeyframeId{4})) == 1);
}

TEST_CASE("semantic: a keyframe shared by the evicted and the new zone is not re-read") {
  test::MapSpec s = test::LineMap({5});
  s.zones = {{1, 2, 3}, {3, 4, 5}};
  Harness h(s, 4, 4, Semantic(4));
  h.Start(At(0, 0));
  auto t = h.Tick(At(1, 1));  // K_pred = 3 + 2 = 5 > 4: evict z0; frees 1, 2 only
  CHECK(Zones(h.before.zones_unloaded()) == Zv{0});
  CHECK(t.keyframes_unloaded == 2);
  CHECK(Ids(h.source.calls.back().loaded) == V{4, 5});
  CHECK(h.ResidentIds() == V{3, 4, 5});
  CHECK(h.ws.max_resident_seen() <= 4);
}

TEST_CASE("semantic: a zone larger than K_max loads nearest-first up to the budget") {
  Harness h(test::LineMap({2, 10}), 4, 4, Semantic(4));
  h.Start(At(0, 0));
  // Keyframe id i+1 sits at x = i; the robot is at x = 6.2 in zone 1 (ids 3..12).
  auto t = h.Tick(At(1, 1, {6.2, 0, 0}));
  CHECK(Zones(h.before.zones_unloaded()) == Zv{0});
  CHECK(Ids(h.index, h.before.acquires()) == V{7, 8, 6, 9});
  CHECK(h.ResidentIds() == V{6, 7, 8, 9});
  CHECK(t.peak_resident_keyframes == 4);
  CHECK_FALSE(t.over_budget);
  // Leaving it releases exactly what it held.
  h.Tick(At(2, 0));
  CHECK(h.ResidentIds() == V{1, 2});
}

TEST_CASE("semantic property: random walks / overlaps and budgets never exceed K_max") {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 40; ++trial) {
    const int zones = 3 + static_cast<int>(rng() % 8);
    const int n = 10 + static_cast<int>(rng() % 60);
    test::MapSpec s;
    for (int i = 0; i < n; ++i) s.positions.emplace_back(rng() % 50, rng() % 50, 0);
    s.zones.resize(static_cast<std::size_t>(zones));
    for (int i = 1; i <= n; ++i) {  // each keyframe in 1..3 zones
      const int copies = 1 + static_cast<int>(rng() % 3);
      for (int c = 0; c < copies; ++c) s.zones[rng() % s.zones.size()].push_back(i);
    }
    for (auto& z : s.zones) {
      std::sort(z.begin(), z.end());
      z.erase(std::unique(z.begin(), z.end()), z.end());
    }
    const auto k_max = static_cast<std::uint32_t>(1 + rng() % static_cast<std::uint32_t>(n));
    Harness h(s, k_max, k_max, Semantic(k_max));
    h.Start(At(0, 0));
    for (std::uint64_t tick = 1; tick < 60; ++tick) {
      const int z = static_cast<int>(rng() % static_cast<std::uint32_t>(zones + 1)) - 1;
      auto t = h.Tick(At(tick, z, {static_cast<double>(rng() % 50), 0, 0}));
      REQUIRE(h.ws.resident_count() <= k_max);
      REQUIRE(t.peak_resident_keyframes <= k_max);
      REQUIRE_FALSE(t.over_budget);
      REQUIRE(t.refused_acquisitions == 0);
      // The current zone is resident (whole if it fits).
      auto* p = static_cast<SemanticPolicy*>(h.policy.get());
      if (p->current_zone() != kNoZone) {
        const auto members = h.index.ZoneMembers(p->current_zone());
        std::uint32_t in = 0;
        for (KfIndex k : members) in += h.ws.IsResident(k) ? 1U : 0U;
        CHECK(in == std::min<std::uint32_t>(static_cast<std::uint32_t>(members.size()), k_max));
      }
      // WorkingSet counts equal the policy's union bookkeeping.
      for (KfIndex k = 0; k < h.index.keyframe_count(); ++k) {
        REQUIRE(h.ws.refcount(k) == p->residency().held(k));
      }
    }
    CHECK(h.ws.max_resident_seen() <= k_max);
  }
}

TEST_CASE("semantic: no heap allocation per tick once warm") {
  test::MapSpec s = test::LineMap({20, 30, 25, 40, 10, 35});
  s.zones[1].push_back(1);  // an overlap
  Harness h(s, 70, 70, Semantic(70));
  h.source.log_calls = false;
  h.verify_slots = false;
  h.Start(At(0, 0));
  std::mt19937 rng(3);
  std::uint64_t tick = 1;
  for (; tick < 50; ++tick) h.Tick(At(tick, static_cast<int>(rng() % 7) - 1));
  test::AllocationCounter counter;
  std::uint64_t loads = 0;
  for (; tick < 2050; ++tick) {
    auto t = h.Tick(At(tick, static_cast<int>(rng() % 7) - 1, {static_cast<double>(tick % 100), 0, 0}));
    loads += t.keyframes_loaded;
  }
  CHECK(counter.allocations() == 0);
  CHECK(loads > 1000);  // the walk really moved zones in and out
}

}  // namespace
}  // namespace zm
