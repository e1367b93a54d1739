// predictive: route prefetch, farthest-next-use eviction, learned transitions, the order of
// its batches (current zone nearest-first, then the prefetch), and a property walk (never
// above K_max).
#include "memory/predictive_policy.h"

#include <doctest/doctest.h>

#include <random>

#include "memory/memory_test_util.h"

namespace zm {
namespace {

using test::At;
using test::Harness;
using test::Ids;
using test::Zones;
using V = std::vector<std::int64_t>;
using Zv = std::vector<std::int32_t>;

Harness::Factory Predictive(std::uint32_t k_max, bool prefetch = true) {
  return [=](const MapIndex& index) {
    PredictiveOptions o;
    o.k_max = k_max;
    o.prefetch = prefetch;
    return std::make_unique<PredictivePolicy>(index, o);
  };
}

PredictivePolicy& Predictive(Harness& h) { return *static_cast<PredictivePolicy*>(h.policy.get()); }

std::vector<std::vector<ZoneId>> Chain(int zones) {
  std::vector<std::vector<ZoneId>> adj(static_cast<std::size_t>(zones));
  for (int z = 0; z + 1 < zones; ++z) adj[static_cast<std::size_t>(z)].push_back(ZoneId{z + 1});
  return adj;
}

TEST_CASE("predictive: prefetches the next zone of the route / evicts the farthest next use") {
  test::MapSpec s = test::LineMap({3, 3, 3, 3});
  s.adjacency = Chain(4);
  Harness h(s, 9, 9, Predictive(9));
  const std::vector<ZoneId> route{ZoneId{0}, ZoneId{1}, ZoneId{2}, ZoneId{3}};
  TickContext c = At(0, 0);
  c.route = route;
  h.Start(c);
  CHECK(Zones(h.before.zones_loaded()) == Zv{0, 1});  // current, then the route's next
  CHECK(h.before.batches().size() == 2);
  c = At(1, 1);
  c.route = route;
  h.Tick(c);
  CHECK(Zones(h.before.zones_loaded()) == Zv{2});
  c = At(2, 2);
  c.route = route;
  h.Tick(c);  // zone 3 needs room: zone 0 is no longer on the route, zone 1 is behind us
  CHECK(Zones(h.before.zones_unloaded()) == Zv{0});
  CHECK(Zones(h.before.zones_loaded()) == Zv{3});
  CHECK(h.ResidentIds() == V{4, 5, 6, 7, 8, 9, 10, 11, 12});
}

TEST_CASE("predictive: without a route it learns transitions from what it has seen") {
  test::MapSpec s = test::LineMap({2, 2, 2, 2});
  s.adjacency = {{ZoneId{1}}, {ZoneId{2}, ZoneId{3}}, {}, {}};  // 1 is a hub: 0, 2, 3
  Harness h(s, 4, 4, Predictive(4));
  h.Start(At(0, 0));
  CHECK(Predictive(h).last_prefetch() == ZoneId{1});  // the only neighbour
  // Walk 1 -> 3 twice, so from 1 the likeliest next zone is 3, not 2.
  std::uint64_t t = 1;
  for (int z : {1, 3, 1, 3, 1}) h.Tick(At(t++, z));
  CHECK(Predictive(h).Transitions(ZoneId{1}, ZoneId{3}) == 2);
  CHECK(Predictive(h).last_prefetch() == ZoneId{3});
  CHECK(h.ws.resident_count() <= 4);
}

TEST_CASE("predictive: one plan holds the current zone nearest-first, then the prefetch") {
  test::MapSpec s = test::LineMap({10, 10, 10});
  s.adjacency = Chain(3);
  Harness h(s, 20, 20, Predictive(20));
  // From x = 9.5 (the far end of zone 0) the nearest keyframes come first; the batches are the
  // current zone, then the next one (the WorkingSet loads them in this order, time-sliced).
  const std::vector<ZoneId> route{ZoneId{0}, ZoneId{1}, ZoneId{2}};
  TickContext c = At(0, 0, {9.5, 0, 0});
  c.route = route;
  h.Start(c);
  CHECK(Zones(h.before.zones_loaded()) == Zv{0, 1});
  REQUIRE(h.before.batches().size() == 2);
  CHECK(h.before.batches()[0].zone == ZoneId{0});
  CHECK(Ids(h.index, h.before.acquires().first(3)) == V{10, 9, 8});
  CHECK(h.before.batches()[1].zone == ZoneId{1});
  CHECK(h.ws.resident_count() == 20);
  // Entering zone 1 (already resident): zone 0 is behind, zone 2 is prefetched in its place.
  c = At(1, 1, {10.5, 0, 0});
  c.route = route;
  h.Tick(c);
  CHECK(Zones(h.before.zones_unloaded()) == Zv{0});
  CHECK(Zones(h.before.zones_loaded()) == Zv{2});
  CHECK(h.policy->zone_loads() == 3);
  CHECK(h.ws.max_resident_seen() <= 20);
}

TEST_CASE("predictive: with time-sliced loads the prefetched zone is resident on arrival") {
  test::MapSpec s = test::LineMap({8, 8, 8});
  s.adjacency = Chain(3);
  Harness h(s, 16, 16, Predictive(16), /*sliced=*/true);
  const std::vector<ZoneId> route{ZoneId{0}, ZoneId{1}, ZoneId{2}};
  TickContext c = At(0, 0, {0, 0, 0});
  c.route = route;
  h.Start(c);
  LoadSlice own_zone;  // what the loop's start-up does: the robot's zone, to the end
  own_zone.zone = ZoneId{0};
  h.Step(own_zone);
  CHECK(h.ResidentIds() == V{1, 2, 3, 4, 5, 6, 7, 8});
  CHECK(h.ws.loading_zone() == ZoneId{1});  // the prefetch waits for the idle part
  h.Drain();                                // the idle part
  for (int zone = 1; zone <= 2; ++zone) {
    c = At(static_cast<std::uint64_t>(zone), zone, {8.0 * zone, 0, 0});
    c.route = route;
    // Before the tick the zone the robot walks into is complete: nothing of it to load.
    for (KfIndex k : h.index.ZoneMembers(ZoneId{zone})) CHECK(h.ws.IsResident(k));
    h.Tick(c);
    CHECK(h.ws.pending_count() <= 8);  // at most the next prefetch is queued
    CHECK(h.ws.loading_zone() != ZoneId{zone});
    h.Drain();
  }
  CHECK(h.ws.max_resident_seen() <= 16);
}

TEST_CASE("predictive property: random walks / overlaps / slices never exceed K_max") {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 30; ++trial) {
    const int zones = 3 + static_cast<int>(rng() % 7);
    const int n = 10 + static_cast<int>(rng() % 60);
    test::MapSpec s;
    for (int i = 0; i < n; ++i) s.positions.emplace_back(rng() % 50, rng() % 50, 0);
    s.zones.resize(static_cast<std::size_t>(zones));
    for (int i = 1; i <= n; ++i) {
      const int copies = 1 + static_cast<int>(rng() % 2);
      for (int c = 0; c < copies; ++c) s.zones[rng() % s.zones.size()].push_back(i);
    }
    for (auto& z : s.zones) {
      std::sort(z.begin(), z.end());
      z.erase(std::unique(z.begin(), z.end()), z.end());
    }
    s.adjacency.resize(static_cast<std::size_t>(zones));
    for (int e = 0; e < zones * 2; ++e) {
      s.adjacency[rng() % s.adjacency.size()].push_back(
          ZoneId{static_cast<std::int32_t>(rng() % static_cast<std::uint32_t>(zones))});
    }
    const auto k_max = static_cast<std::uint32_t>(1 + rng() % static_cast<std::uint32_t>(n));
    Harness h(s, k_max, k_max, Predictive(k_max, rng() % 4 != 0));
    h.Start(At(0, 0));
    for (std::uint64_t tick = 1; tick < 60; ++tick) {
      const int z = static_cast<int>(rng() % static_cast<std::uint32_t>(zones + 1)) - 1;
      auto t = h.Tick(At(tick, z, {static_cast<double>(rng() % 50), 0, 0}));
      REQUIRE(t.peak_resident_keyframes <= k_max);
      REQUIRE(t.refused_acquisitions == 0);
      for (KfIndex k = 0; k < h.index.keyframe_count(); ++k) {
        REQUIRE(h.ws.refcount(k) == Predictive(h).residency().held(k));
      }
    }
    CHECK(h.ws.max_resident_seen() <= k_max);
  }
}

}  // namespace
}  // namespace zm
