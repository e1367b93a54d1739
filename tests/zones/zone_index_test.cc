// GetZone: the grid agrees with brute force, hysteresis stops flip-flop along a shared edge,
// floors separate identical outlines, and lookups allocate nothing.
#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "support/counting_allocator.h"
#include "zones/polygon.h"
#include "zones/zone_index.h"
#include "zones_test_util.h"

namespace zm {
namespace {

using test::MakeSet;
using test::MakeZone;
using test::Rect;

ZoneId BruteForce(const ZoneSet& set, const Eigen::Vector3d& p) {
  for (const Zone& z : set.zones()) {
    if (z.ContainsZ(p.z()) && PointInPolygon(z.polygon, p.head<2>())) return z.id;
  }
  return kNoZone;
}

TEST_CASE("grid lookup agrees with brute force on random rooms and points" *
          doctest::test_suite("slow")) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Zone> zones;
  for (int i = 0; i < 300; ++i) {
    const double x = 100.0 * u(rng), y = 60.0 * u(rng);
    const double w = 1.0 + 9.0 * u(rng), h = 1.0 + 9.0 * u(rng);
    std::vector<Eigen::Vector2d> poly;
    if (i % 3 == 0) {  // an L-shaped room
      poly = {{x, y}, {x + w, y}, {x + w, y + h / 2}, {x + w / 2, y + h / 2}, {x + w / 2, y + h},
              {x, y + h}};
    } else if (i % 3 == 1) {  // a triangle
      poly = {{x, y}, {x + w, y}, {x + w * u(rng), y + h}};
    } else {
      poly = Rect(x, y, x + w, y + h);
    }
    zones.push_back(MakeZone(test::Numbered("z", i), poly, i % 2, i % 2 ? 1.5 : -1.5,
                             i % 2 ? 4.5 : 1.5));
  }
  const ZoneSet set = MakeSet(zones);
  const ZoneIndex index(set);
  CHECK(index.cell_count() > 0);
  int inside = 0;
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d p(-5.0 + 115.0 * u(rng), -5.0 + 75.0 * u(rng), u(rng) < 0.5 ? 0.0 : 3.0);
    const ZoneId expected = BruteForce(set, p);
    REQUIRE(index.Lookup(p) == expected);
    if (expected != kNoZone) ++inside;
  }
  CHECK(inside > 5000);  // the test exercises hits as well as misses
}

TEST_CASE("hysteresis: no flip-flop along a shared edge, switch once well inside") {
  const ZoneSet set = MakeSet({MakeZone("A", Rect(0, 0, 10, 5)), MakeZone("B", Rect(10, 0, 20, 5))});
  const ZoneIndex index(set, {.hysteresis_m = 0.5});
  const ZoneId a{0}, b{1};
  CHECK(index.GetZone(PoseFromXYYaw(9.9, 2.5, 0), kNoZone) == a);  // start: containing zone

  // Weaving across the shared edge by up to 0.4 m never leaves A.
  ZoneId cur = a;
  int switches = 0;
  for (int t = 0; t < 1000; ++t) {
    const ZoneId next = index.GetZone(PoseFromXYYaw(10.0 + 0.4 * std::sin(0.1 * t), 2.5, 0), cur);
    if (next != cur) ++switches;
    cur = next;
  }
  CHECK(switches == 0);
  CHECK(cur == a);

  CHECK(index.GetZone(PoseFromXYYaw(10.4, 2.5, 0), a) == a);  // 0.4 m inside B: stay
  CHECK(index.GetZone(PoseFromXYYaw(10.6, 2.5, 0), a) == b);  // 0.6 m inside B: switch
  CHECK(index.GetZone(PoseFromXYYaw(9.7, 2.5, 0), b) == b);   // and not back at 0.3 m
  CHECK(index.GetZone(PoseFromXYYaw(9.4, 2.5, 0), b) == a);
  // Outside every zone: keep the current zone.
  CHECK(index.GetZone(PoseFromXYYaw(50, 50, 0), b) == b);
  CHECK(index.GetZone(PoseFromXYYaw(50, 50, 0), kNoZone) == kNoZone);
  CHECK(index.Lookup({-1e12, 0.0, 0.0}) == kNoZone);
  CHECK(index.Lookup({std::nan(""), 0.0, 0.0}) == kNoZone);
}

TEST_CASE("a corridor narrower than twice the hysteresis can still be entered") {
  const ZoneSet set =
      MakeSet({MakeZone("Room", Rect(0, 0, 10, 10)), MakeZone("Corridor", Rect(10, 4.7, 30, 5.3))});
  const ZoneIndex index(set, {.hysteresis_m = 0.5});
  CHECK(index.ZoneHysteresis(ZoneId{1}) < 0.3);
  CHECK(index.ZoneHysteresis(ZoneId{0}) == 0.5);
  CHECK(index.GetZone(PoseFromXYYaw(20, 5, 0), ZoneId{0}) == ZoneId{1});
}

TEST_CASE("floors: a pose is looked up only among its own floor's zones") {
  const ZoneSet set = MakeSet({MakeZone("G", Rect(0, 0, 10, 10), 0, -1.5, 1.5),
                               MakeZone("F1", Rect(0, 0, 10, 10), 1, 1.5, 4.5),
                               MakeZone("F1b", Rect(20, 0, 30, 10), 1, 1.5, 4.5)});
  const ZoneIndex index(set);
  CHECK(index.Lookup({5, 5, 0.2}) == ZoneId{0});
  CHECK(index.Lookup({5, 5, 3.0}) == ZoneId{1});
  CHECK(index.Lookup({25, 5, 0.0}) == kNoZone);  // F1b is upstairs only
  CHECK(index.Lookup({25, 5, 3.0}) == ZoneId{2});
  CHECK(index.GetZone(PoseFromXYYaw(5, 5, 0, 3.0), ZoneId{0}) == ZoneId{1});  // took the lift
  CHECK(index.Depth(ZoneId{0}, {5, 5, 3.0}) < 0.0);
  CHECK(index.Depth(ZoneId{1}, {5, 5, 3.0}) == doctest::Approx(5.0));
}

TEST_CASE("overlapping zones: lowest id wins a lookup, staying inside the current one") {
  const ZoneSet set = MakeSet({MakeZone("Hall", Rect(0, 0, 20, 10)), MakeZone("Bay", Rect(5, 2, 9, 8))});
  const ZoneIndex index(set);
  CHECK(index.Lookup({7, 5, 0}) == ZoneId{0});
  CHECK(index.GetZone(PoseFromXYYaw(7, 5, 0), ZoneId{1}) == ZoneId{1});
  CHECK(index.GetZone(PoseFromXYYaw(7, 5, 0), ZoneId{0}) == ZoneId{0});
}

TEST_CASE("GetZone and Lookup allocate nothing") {
  std::vector<Zone> zones;
  for (int i = 0; i < 100; ++i) {
    const double x = 5.0 * (i % 10), y = 5.0 * (i / 10);
    zones.push_back(MakeZone(test::Numbered("r", i), Rect(x, y, x + 5, y + 5)));
  }
  const ZoneSet set = MakeSet(zones);
  const ZoneIndex index(set);
  std::vector<Pose3> poses;
  for (int i = 0; i < 1000; ++i) poses.push_back(PoseFromXYYaw(0.05 * i, 0.049 * i, 0.0));
  ZoneId cur = kNoZone;
  int hits = 0;
  test::AllocationCounter counter;
  for (const Pose3& p : poses) {
    cur = index.GetZone(p, cur);
    if (index.Lookup(p.translation()) != kNoZone) ++hits;
  }
  CHECK(counter.allocations() == 0);
  CHECK(cur != kNoZone);
  CHECK(hits > 900);
}

}  // namespace
}  // namespace zm
