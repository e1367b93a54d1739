// radius = Autoware-style distance tiles: exact tile loads/evictions on a line, the update
// distance, the budget (nearest tiles first, then nearest keyframes), and a property walk.
#include "memory/radius_policy.h"

#include <doctest/doctest.h>

#include <random>

#include "memory/memory_test_util.h"

namespace zm {
namespace {

using test::At;
using test::Harness;
using test::Ids;
using V = std::vector<std::int64_t>;

Harness::Factory Radius(std::uint32_t k_max, double radius) {
  return [=](const MapIndex& index) {
    RadiusOptions o;
    o.k_max = k_max;
    o.map_radius_m = radius;
    return std::make_unique<RadiusPolicy>(index, o);
  };
}

V Range(std::int64_t a, std::int64_t b) {
  V v;
  for (auto i = a; i <= b; ++i) v.push_back(i);
  return v;
}

TEST_CASE("radius: tiles of 20 m around the robot / updated every 20 m") {
  // Keyframe id i+1 at x = i (0..99): tiles [0,20) = ids 1..20, [20,40) = 21..40, ...
  Harness h(test::LineMap({100}), 60, 60, Radius(60, 25));
  h.Start(At(0, -1, {10, 0, 0}));       // circle [-15, 35]: tiles 0 and 1
  CHECK(h.ResidentIds() == Range(1, 40));
  auto t = h.Tick(At(1, -1, {25, 0, 0}));  // moved 15 m < 20: no update
  CHECK(h.before.empty());
  t = h.Tick(At(2, -1, {31, 0, 0}));       // circle [6, 56]: tiles 1 (0 m), 2 (9 m), 0 (11 m)
  CHECK(h.before.releases().empty());
  CHECK(Ids(h.index, h.before.acquires()) == Range(41, 60));
  t = h.Tick(At(3, -1, {52, 0, 0}));       // circle [27, 77]: tiles 2, 3, 1; tile 0 evicted
  CHECK(t.keyframes_unloaded == 20);
  CHECK(h.ResidentIds() == Range(21, 80));
  CHECK(t.db_queries == 4 * 20);           // tiles are per-keyframe loads (4 statements each)
  CHECK(static_cast<RadiusPolicy*>(h.policy.get())->updates() == 3);
}

TEST_CASE("radius: never exceeds the budget - the tile that does not fit is taken nearest-first") {
  Harness h(test::LineMap({100}), 30, 30, Radius(30, 25));
  auto t = h.Start(At(0, -1, {10, 0, 0}));  // tile 0 (20) fits, tile 1 only 10 of 20
  CHECK(h.ResidentIds() == Range(1, 30));    // x = 20..29 are the nearest of tile 1
  CHECK(t.peak_resident_keyframes == 30);
}

TEST_CASE("radius property: random walks never exceed K_max") {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    test::MapSpec s;
    const int n = 50 + static_cast<int>(rng() % 150);
    for (int i = 0; i < n; ++i) s.positions.emplace_back(rng() % 200, rng() % 200, 0);
    const auto k_max = static_cast<std::uint32_t>(1 + rng() % static_cast<std::uint32_t>(n));
    Harness h(s, k_max, k_max, Radius(k_max, 10.0 + static_cast<double>(rng() % 60)));
    Eigen::Vector3d p(100, 100, 0);
    h.Start(At(0, -1, p));
    for (std::uint64_t tick = 1; tick < 60; ++tick) {
      p += Eigen::Vector3d(static_cast<double>(rng() % 21) - 10.0, static_cast<double>(rng() % 21) - 10.0, 0);
      auto t = h.Tick(At(tick, -1, p));
      REQUIRE(t.peak_resident_keyframes <= k_max);
      REQUIRE(h.ws.resident_count() <= k_max);
      REQUIRE(t.refused_acquisitions == 0);
    }
    CHECK(h.ws.max_resident_seen() <= k_max);
  }
}

}  // namespace
}  // namespace zm
