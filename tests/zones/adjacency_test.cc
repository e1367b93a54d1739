// The zone adjacency graph: touching polygons (same floor only, within tolerance), pose-graph
// links that cross zones, and shared doorway keyframes.
#include <doctest/doctest.h>

#include "zones/adjacency.h"
#include "zones_test_util.h"

namespace zm {
namespace {

using test::MakeSet;
using test::MakeZone;
using test::Rect;

LinkRecord Link(std::int64_t a, std::int64_t b) {
  LinkRecord l;
  l.from = KeyframeId{a};
  l.to = KeyframeId{b};
  return l;
}

TEST_CASE("touching polygons are neighbours, gaps and other floors are not") {
  auto ground = [](std::string name, std::vector<Eigen::Vector2d> ring) {
    return MakeZone(std::move(name), std::move(ring), 0, -1.5, 1.5);
  };
  const ZoneSet set = MakeSet({
      ground("A", Rect(0, 0, 5, 5)),
      ground("B", Rect(5, 0, 10, 5)),                 // shares an edge with A
      ground("C", Rect(10.03, 0, 15, 5)),             // 3 cm gap to B: within tolerance
      ground("D", Rect(20, 0, 25, 5)),                // alone
      MakeZone("E", Rect(0, 5, 5, 10), 1, 1.5, 4.5),  // beside A's edge, but upstairs
      ground("F", Rect(6, 1, 7, 2)),                  // inside B
      ground("G", Rect(5, 5, 6, 6)),                  // a corner of A, an edge of B
  });
  const ZoneGraph g = BuildAdjacency(set, {}, {});
  CHECK(g.zone_count() == 7);
  CHECK(g.Adjacent(ZoneId{0}, ZoneId{1}));
  CHECK(g.Adjacent(ZoneId{1}, ZoneId{0}));
  CHECK(g.Adjacent(ZoneId{1}, ZoneId{2}));
  CHECK_FALSE(g.Adjacent(ZoneId{0}, ZoneId{2}));
  CHECK(g.Neighbours(ZoneId{3}).empty());
  CHECK_FALSE(g.Adjacent(ZoneId{0}, ZoneId{4}));
  CHECK(g.Adjacent(ZoneId{1}, ZoneId{5}));
  CHECK(g.Adjacent(ZoneId{6}, ZoneId{0}));
  const auto nb = g.Neighbours(ZoneId{1});
  CHECK(std::vector<ZoneId>(nb.begin(), nb.end()) ==
        std::vector<ZoneId>{ZoneId{0}, ZoneId{2}, ZoneId{5}, ZoneId{6}});
  const ZoneGraph strict = BuildAdjacency(set, {}, {}, {.touch_tolerance_m = 0.01});
  CHECK_FALSE(strict.Adjacent(ZoneId{1}, ZoneId{2}));
  for (const ZoneEdge& e : g.edges()) {
    CHECK(e.a < e.b);
    CHECK(e.touching);
  }
}

TEST_CASE("links across zones and shared keyframes join zones that do not touch") {
  const ZoneSet set = MakeSet({MakeZone("A", Rect(0, 0, 5, 5)), MakeZone("B", Rect(20, 0, 25, 5)),
                               MakeZone("C", Rect(40, 0, 45, 5)), MakeZone("D", Rect(60, 0, 65, 5))});
  const std::vector<ZoneMember> members = {{ZoneId{0}, KeyframeId{1}}, {ZoneId{1}, KeyframeId{2}},
                                           {ZoneId{2}, KeyframeId{3}}, {ZoneId{3}, KeyframeId{3}},
                                           {ZoneId{0}, KeyframeId{4}}};
  const std::vector<LinkRecord> links = {Link(1, 2), Link(1, 4), Link(2, 99)};
  const ZoneGraph g = BuildAdjacency(set, members, links);
  CHECK(g.Adjacent(ZoneId{0}, ZoneId{1}));   // link 1-2
  CHECK(g.Adjacent(ZoneId{2}, ZoneId{3}));   // keyframe 3 in both
  CHECK_FALSE(g.Adjacent(ZoneId{0}, ZoneId{2}));
  REQUIRE(g.edges().size() == 2);
  CHECK(g.edges()[0].links == 1);
  CHECK_FALSE(g.edges()[0].touching);
  CHECK(g.edges()[1].shared_keyframes == 1);
  CHECK(g.Neighbours(ZoneId{42}).empty());
}

}  // namespace
}  // namespace zm
