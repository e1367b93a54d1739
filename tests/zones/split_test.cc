// Oversize zones: every resulting zone fits the budget, every keyframe stays in exactly one
// part, parts are compact (split along the long axis) and the split is reported.
#include <doctest/doctest.h>

#include <map>
#include <random>

#include "zones/polygon.h"
#include "zones/split.h"
#include "zones_test_util.h"

namespace zm {
namespace {

using test::KeyframeAt;
using test::MakeSet;
using test::MakeZone;
using test::Rect;

TEST_CASE("an oversize zone is split into parts that each fit, along its long axis") {
  const ZoneSet set = MakeSet({MakeZone("Hall", Rect(0, 0, 10, 10)), MakeZone("Ward3", Rect(10, 0, 70, 6))});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(10.1, 69.9), uy(0.1, 5.9);
  std::vector<KeyframeMeta> kfs;
  std::vector<ZoneMember> members;
  for (int i = 0; i < 5; ++i) {
    kfs.push_back(KeyframeAt(i + 1, 5, 5));
    members.push_back({ZoneId{0}, KeyframeId{i + 1}});
  }
  for (int i = 0; i < 230; ++i) {
    kfs.push_back(KeyframeAt(100 + i, ux(rng), uy(rng)));
    members.push_back({ZoneId{1}, KeyframeId{100 + i}});
  }
  auto r = SplitOversizeZones(set, members, kfs, 50);
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  REQUIRE(r->report.entries.size() == 1);
  const SplitEntry& e = r->report.entries[0];
  CHECK(e.original == "Ward3");
  CHECK(e.keyframes == 230);
  CHECK(e.parts.size() == 5);  // ceil(230 / 50)
  CHECK(e.parts[0] == "Ward3/1");
  CHECK_FALSE(e.polygon_shared);
  REQUIRE(r->zones.size() == 6);
  CHECK(r->zones.zone(ZoneId{0}).name == "Hall");

  std::map<ZoneId, std::uint32_t> counts;
  std::map<KeyframeId, int> times;
  for (const ZoneMember& m : r->members) {
    ++counts[m.zone];
    ++times[m.keyframe];
  }
  for (const auto& [z, c] : counts) CHECK(c <= 50);
  CHECK(times.size() == 235);
  for (const auto& [k, t] : times) CHECK(t == 1);
  // Parts tile the parent: areas add up, each keyframe lies in its own part's polygon.
  double area = 0.0;
  std::map<KeyframeId, Eigen::Vector2d> pos;
  for (const auto& k : kfs) pos[k.id] = k.pose.translation().head<2>();
  for (std::size_t i = 1; i < r->zones.size(); ++i) {
    const Zone& part = r->zones.zone(ZoneId{static_cast<std::int32_t>(i)});
    area += part.AreaM2();
    const Box2 box = BoundingBox(part.polygon);
    CHECK(box.max.y() - box.min.y() == doctest::Approx(6.0));  // cut across the long axis
  }
  CHECK(area == doctest::Approx(360.0));
  for (const ZoneMember& m : r->members) {
    CHECK(PointInPolygon(r->zones.zone(m.zone).polygon, pos[m.keyframe]));
  }
}

TEST_CASE("keyframe-list zones split their lists, zones that fit are untouched") {
  auto set = ParseZoneJson(R"({"initial_zone":"L1","zones":{"L1":[1,2,3,4,5],"H1":[6]}})", "p.json");
  REQUIRE(set.ok());
  std::vector<KeyframeMeta> kfs;
  std::vector<ZoneMember> members;
  for (int i = 1; i <= 6; ++i) {
    kfs.push_back(KeyframeAt(i, i, 0));
    members.push_back({ZoneId{i <= 5 ? 0 : 1}, KeyframeId{i}});
  }
  auto r = SplitOversizeZones(*set, members, kfs, 2);
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  REQUIRE(r->zones.size() == 4);  // L1/1, L1/2, L1/3, H1
  CHECK(r->zones.has_keyframe_lists());
  CHECK(r->zones.zone(ZoneId{0}).name == "L1/1");
  CHECK(r->zones.keyframes(ZoneId{0}) == std::vector<KeyframeId>{KeyframeId{1}, KeyframeId{2}});
  CHECK(r->zones.keyframes(ZoneId{3}) == std::vector<KeyframeId>{KeyframeId{6}});
  CHECK(r->zones.initial_zone() == ZoneId{0});
  CHECK(r->report.entries[0].part_keyframes == std::vector<std::uint32_t>{2, 2, 1});
}

TEST_CASE("split errors: zero budget, members without poses") {
  const ZoneSet set = MakeSet({MakeZone("A", Rect(0, 0, 1, 1))});
  const std::vector<ZoneMember> members = {{ZoneId{0}, KeyframeId{1}}, {ZoneId{0}, KeyframeId{2}}};
  const std::vector<KeyframeMeta> kfs = {KeyframeAt(1, 0.5, 0.5)};
  CHECK_FALSE(SplitOversizeZones(set, members, kfs, 0).ok());
  auto r = SplitOversizeZones(set, members, kfs, 1);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().message().find("keyframe 2") != std::string::npos);
}

}  // namespace
}  // namespace zm
