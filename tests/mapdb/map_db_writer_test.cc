// MapDbWriter: refuses bad records with an error naming them, rolls the whole batch back, reports
// progress, and leaves a finished map as one self-contained file.
#include <doctest/doctest.h>

#include <filesystem>

#include "mapdb/map_db.h"
#include "mapdb/mapdb_test_util.h"

namespace zm {
namespace {

using test::MakePayload;
using test::TempDir;

bool Contains(const Status& s, const std::string& text) {
  return s.message().find(text) != std::string::npos;
}

KeyframeMeta Meta(std::int64_t id) {
  KeyframeMeta m;
  m.id = KeyframeId{id};
  return m;
}

ZoneRecord Zone(std::int32_t id, std::string name) {
  ZoneRecord z;
  z.id = ZoneId{id};
  z.name = std::move(name);
  return z;
}

TEST_CASE("writer refuses to overwrite unless asked, and finishes into one file") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  test::BuildMap(path);
  auto again = MapDbWriter::Create(path);
  REQUIRE_FALSE(again.ok());
  CHECK(Contains(again.status(), "already exists"));
  CHECK_FALSE(std::filesystem::exists(path + "-wal"));
  auto w = MapDbWriter::Create(path, /*overwrite=*/true);
  REQUIRE(w.ok());
  REQUIRE((*w)->Finish().ok());
  w->reset();
  auto db = MapDb::Open(path);
  REQUIRE(db.ok());
  CHECK((*db)->metadata().keyframe_count == 0);
}

TEST_CASE("a bad keyframe rolls back its whole batch, with an error naming it") {
  TempDir dir;
  auto w = MapDbWriter::Create(dir.File("map.db"));
  REQUIRE(w.ok());
  const auto p1 = MakePayload(1, 3, 10);
  auto p2 = MakePayload(2, 3, 10);
  const auto p3 = MakePayload(3, 3, 10);
  std::vector<std::uint64_t> progress;
  (*w)->SetProgress([&](std::string_view, std::uint64_t done, std::uint64_t total) {
    if (done == total) progress.push_back(total);
  });

  SUBCASE("corrupt payload") {
    p2[100] ^= std::byte{1};
    const std::vector<KeyframeRecord> recs = {{Meta(1), p1}, {Meta(2), p2}};
    const Status st = (*w)->InsertKeyframes(recs);
    CHECK(st.code() == StatusCode::kCorrupt);
    CHECK(Contains(st, "keyframe 2"));
  }
  SUBCASE("payload of another keyframe") {
    const std::vector<KeyframeRecord> recs = {{Meta(1), p1}, {Meta(2), p3}};
    const Status st = (*w)->InsertKeyframes(recs);
    CHECK(Contains(st, "keyframe 2: its payload is for keyframe 3"));
  }
  SUBCASE("duplicate id") {
    const std::vector<KeyframeRecord> recs = {{Meta(1), p1}, {Meta(1), p1}};
    const Status st = (*w)->InsertKeyframes(recs);
    CHECK(Contains(st, "keyframe 1: already in"));
  }
  auto kfs = (*w)->Keyframes();
  REQUIRE(kfs.ok());
  CHECK(kfs->empty());  // rolled back
  CHECK(progress.empty());

  const std::vector<KeyframeRecord> good = {{Meta(1), p1}, {Meta(3), p3}};
  REQUIRE((*w)->InsertKeyframes(good).ok());
  CHECK(progress == std::vector<std::uint64_t>{2});
}

TEST_CASE("links and zones must reference keyframes and zones that exist") {
  TempDir dir;
  auto w = MapDbWriter::Create(dir.File("map.db"));
  REQUIRE(w.ok());
  const auto p1 = MakePayload(1, 3, 10);
  const auto p2 = MakePayload(2, 3, 10);
  const std::vector<KeyframeRecord> recs = {{Meta(1), p1}, {Meta(2), p2}};
  REQUIRE((*w)->InsertKeyframes(recs).ok());

  LinkRecord l;
  l.from = KeyframeId{1};
  l.to = KeyframeId{9};
  const Status link = (*w)->InsertLinks(std::span(&l, 1));
  CHECK(Contains(link, "link 1->9"));
  CHECK(Contains(link, "keyframe 9 is not in the map"));

  // Built by moving whole strings: GCC 12 at -O3 warns falsely (-Wrestrict, bug 105329) on
  // assigning a literal to a std::string member here.
  std::vector<ZoneRecord> zones = {Zone(0, "a"), Zone(1, "b")};
  std::vector<ZoneMember> members = {{ZoneId{0}, KeyframeId{1}}};
  SUBCASE("ids not dense") {
    zones[1].id = ZoneId{5};
    CHECK(Contains((*w)->ReplaceZones(zones, members), "dense"));
  }
  SUBCASE("duplicate name") {
    zones[1] = Zone(1, "a");
    CHECK(Contains((*w)->ReplaceZones(zones, members), "unique"));
  }
  SUBCASE("unknown zone") {
    members.push_back({ZoneId{2}, KeyframeId{1}});
    CHECK(Contains((*w)->ReplaceZones(zones, members), "zone 2 is not among the 2 zones"));
  }
  SUBCASE("unknown keyframe") {
    members.push_back({ZoneId{1}, KeyframeId{7}});
    CHECK(Contains((*w)->ReplaceZones(zones, members), "keyframe 7 is not in the map"));
  }
  SUBCASE("member listed twice") {
    members.push_back({ZoneId{0}, KeyframeId{1}});
    CHECK(Contains((*w)->ReplaceZones(zones, members), "listed twice"));
  }
  REQUIRE((*w)->Finish().ok());
}

}  // namespace
}  // namespace zm
