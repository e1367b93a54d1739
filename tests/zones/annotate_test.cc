// Annotation without a database: containment, the doorway band (a doorway keyframe belongs to
// both rooms), nearest-zone fallback, keyframe-list files, budget warnings and splitting.
#include <doctest/doctest.h>

#include <algorithm>

#include "zones/annotate.h"
#include "zones_test_util.h"

namespace zm {
namespace {

using test::KeyframeAt;
using test::MakeSet;
using test::MakeZone;
using test::Rect;

std::vector<ZoneId> ZonesOf(const AnnotationReport& r, std::int64_t kf) {
  std::vector<ZoneId> out;
  for (const ZoneMember& m : r.members) {
    if (m.keyframe == KeyframeId{kf}) out.push_back(m.zone);
  }
  return out;
}

TEST_CASE("containment, doorway band and nearest-zone fallback") {
  const ZoneSet set = MakeSet({MakeZone("A", Rect(0, 0, 5, 5), 0, -1.5, 1.5),
                               MakeZone("B", Rect(5, 0, 10, 5), 0, -1.5, 1.5),
                               MakeZone("Up", Rect(0, 0, 10, 5), 1, 1.5, 4.5)});
  const std::vector<KeyframeMeta> kfs = {
      KeyframeAt(1, 2, 2),        // deep in A
      KeyframeAt(2, 4.8, 2.5),    // doorway: 0.2 m from B
      KeyframeAt(3, 5.3, 2.5),    // doorway from the other side
      KeyframeAt(4, 30, 2),       // far east of everything: nearest is B
      KeyframeAt(5, -0.3, 2),     // just outside A, within the band
      KeyframeAt(6, 2, 2, 3.0),   // upstairs: only "Up"
      KeyframeAt(7, 2, 2, 20.0),  // a floor with no zones: nearest of any floor
  };
  auto r = AnnotateKeyframes(set, kfs, {.band_m = 0.5});
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  CHECK(ZonesOf(*r, 1) == std::vector<ZoneId>{ZoneId{0}});
  CHECK(ZonesOf(*r, 2) == std::vector<ZoneId>{ZoneId{0}, ZoneId{1}});
  CHECK(ZonesOf(*r, 3) == std::vector<ZoneId>{ZoneId{0}, ZoneId{1}});
  CHECK(ZonesOf(*r, 4) == std::vector<ZoneId>{ZoneId{1}});
  CHECK(ZonesOf(*r, 5) == std::vector<ZoneId>{ZoneId{0}});
  CHECK(ZonesOf(*r, 6) == std::vector<ZoneId>{ZoneId{2}});
  CHECK(ZonesOf(*r, 7).size() == 1);
  CHECK(r->keyframes == 7);
  CHECK(r->inside == 4);
  CHECK(r->band_memberships == 3);
  CHECK(r->nearest == 2);
  CHECK(r->counts == std::vector<std::uint32_t>{5, 3, 1});  // keyframe 7 ties A and Up: lower id
  CHECK(std::is_sorted(r->members.begin(), r->members.end(), [](const ZoneMember& x, const ZoneMember& y) {
    return x.zone != y.zone ? x.zone < y.zone : x.keyframe < y.keyframe;
  }));

  auto narrow = AnnotateKeyframes(set, kfs, {.band_m = 0.0});
  REQUIRE(narrow.ok());
  CHECK(ZonesOf(*narrow, 2) == std::vector<ZoneId>{ZoneId{0}});
  CHECK(ZonesOf(*narrow, 5) == std::vector<ZoneId>{ZoneId{0}});  // now by nearest
  CHECK(narrow->nearest == 3);
}

TEST_CASE("budget warning and splitting during annotation") {
  const ZoneSet set = MakeSet({MakeZone("Ward", Rect(0, 0, 40, 4)), MakeZone("Bath", Rect(40, 0, 42, 4))});
  std::vector<KeyframeMeta> kfs;
  for (int i = 0; i < 50; ++i) kfs.push_back(KeyframeAt(i + 1, 0.5 + 0.75 * i, 2.0));
  kfs.push_back(KeyframeAt(100, 41, 2));
  auto warned = AnnotateKeyframes(set, kfs, {.band_m = 0.1, .warn_zone_keyframes = 20});
  REQUIRE(warned.ok());
  CHECK(warned->over_budget == std::vector<ZoneId>{ZoneId{0}});

  auto split = AnnotateKeyframes(set, kfs, {.band_m = 0.1, .warn_zone_keyframes = 20,
                                             .max_zone_keyframes = 20});
  REQUIRE_MESSAGE(split.ok(), split.status().ToString());
  CHECK(split->over_budget.empty());
  REQUIRE(split->split.entries.size() == 1);
  CHECK(split->split.entries[0].original == "Ward");
  CHECK(split->zones.Find("Ward/1") != kNoZone);
  CHECK(split->zones.Find("Bath") != kNoZone);
  for (std::uint32_t c : split->counts) CHECK(c <= 20);
}

TEST_CASE("keyframe-list zones use their lists, unknown ids are an error naming file and zone") {
  auto set = ParseZoneJson(R"({"initial_zone":"L1","zones":{"L1":[1,2,3],"H1":[3,4]}})",
                           "paper.json");
  REQUIRE(set.ok());
  std::vector<KeyframeMeta> kfs;
  for (int i = 1; i <= 5; ++i) kfs.push_back(KeyframeAt(i, i, 0));
  auto r = AnnotateKeyframes(*set, kfs, {});
  REQUIRE_MESSAGE(r.ok(), r.status().ToString());
  CHECK(r->members.size() == 5);
  CHECK(r->counts == std::vector<std::uint32_t>{3, 2});
  CHECK(r->unassigned == 1);  // keyframe 5
  CHECK(r->zones.initial_zone() == ZoneId{0});

  kfs.pop_back();
  kfs.erase(kfs.begin() + 3);  // drop keyframe 4, listed by H1
  auto bad = AnnotateKeyframes(*set, kfs, {});
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message() ==
        "paper.json: feature 1 (\"H1\"): keyframe id 4 does not exist in the map (3 keyframes)");
}

TEST_CASE("annotation refuses an empty zone set and a bad band") {
  const std::vector<KeyframeMeta> kfs = {KeyframeAt(1, 0, 0)};
  CHECK_FALSE(AnnotateKeyframes(ZoneSet{}, kfs, {}).ok());
  const ZoneSet set = MakeSet({MakeZone("A", Rect(0, 0, 1, 1))});
  CHECK_FALSE(AnnotateKeyframes(set, kfs, {.band_m = -1.0}).ok());
}

}  // namespace
}  // namespace zm
