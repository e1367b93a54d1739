// MapDbWriter: refuses bad records with an error naming them, rolls the whole batch back, reports
// progress, and leaves a finished map as one self-contained file.
#include <doctest/doctest.h>

#include <cstring>
#include <filesystem>
#include <map>

#include "mapdb/map_db.h"
#include "mapdb/mapdb_test_util.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::Contains;

using test::MakePayload;
using test::TempDir;

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

TEST_CASE("the page size follows the payloads: 1/16 of the mean, from 4 KiB to 64 KiB") {
  CHECK(PageBytesForPayload(0) == 4096);
  CHECK(PageBytesForPayload(2000) == 4096);
  CHECK(PageBytesForPayload(100'000) == 4096);  // the default hospital's ~100 KB keyframes
  CHECK(PageBytesForPayload(16 * 8192) == 8192);
  CHECK(PageBytesForPayload(300'000) == 16384);
  CHECK(PageBytesForPayload(1'600'000) == 65536);  // dense keyframes
  CHECK(PageBytesForPayload(std::uint64_t{1} << 40) == 65536);
}

// Writes `count` keyframes of about `payload_bytes` (opaque dense bytes) in one zone; returns
// the payloads by id.
std::map<std::int64_t, std::vector<std::byte>> WriteDense(const std::string& path, int count,
                                                          std::uint32_t payload_bytes,
                                                          MapDbWriterOptions options = {}) {
  auto w = MapDbWriter::Create(path, false, options);
  REQUIRE(w.ok());
  // Camera and source before the first keyframe: kept until the schema exists.
  REQUIRE((*w)->SetCamera({.fx = 1, .fy = 2, .cx = 3, .cy = 4, .width = 5, .height = 6}).ok());
  REQUIRE((*w)->SetSource("dense test").ok());
  std::map<std::int64_t, std::vector<std::byte>> payloads;
  std::vector<KeyframeRecord> recs;
  for (int i = 1; i <= count; ++i) {
    payloads[i] = MakePayload(i, 10, payload_bytes + static_cast<std::uint32_t>(i) * 4099);
  }
  for (auto& [id, p] : payloads) recs.push_back({Meta(id), p});
  REQUIRE((*w)->InsertKeyframes(recs).ok());
  std::vector<ZoneRecord> zones = {Zone(0, "all")};
  std::vector<ZoneMember> members;
  for (int i = 1; i <= count; ++i) members.push_back({ZoneId{0}, KeyframeId{i}});
  REQUIRE((*w)->ReplaceZones(zones, members).ok());
  REQUIRE((*w)->Finish().ok());
  return payloads;
}

TEST_CASE("large payloads get large pages and load byte-exact through both read paths") {
  TempDir dir;
  struct Case {
    std::uint32_t payload_bytes;
    MapDbWriterOptions options;
    std::uint32_t page;
  };
  for (const Case c : {Case{1'200'000, {}, 65536}, Case{300'000, {}, 16384},
                       Case{300'000, {.page_bytes = 4096}, 4096}}) {
    CAPTURE(c.payload_bytes);
    CAPTURE(c.page);
    const std::string path = dir.File("dense" + std::to_string(c.page) + ".db");
    const auto payloads = WriteDense(path, 6, c.payload_bytes, c.options);
    auto db = MapDb::Open(path);
    REQUIRE(db.ok());
    CHECK((*db)->metadata().page_bytes == c.page);
    CHECK((*db)->metadata().camera.height == 6);
    CHECK((*db)->metadata().source == "dense test");
    Arena arena = test::MakeArena(6, (*db)->metadata().largest_payload_bytes);
    test::RecordingSink sink;
    auto st = (*db)->LoadZone(ZoneId{0}, arena, sink);
    REQUIRE_MESSAGE(st.ok(), st.status().ToString());
    CHECK(st->keyframes == 6);
    for (const auto& e : sink.loaded()) {
      const auto& want = payloads.at(e.id.value);
      CHECK(std::memcmp(arena.Slot(e.slot).data(), want.data(), want.size()) == 0);
    }
    sink.ReleaseAll(arena);
    const KeyframeId ids[] = {KeyframeId{6}, KeyframeId{2}};
    REQUIRE((*db)->LoadKeyframes(ids, arena, sink).ok());
    for (const auto& e : sink.loaded()) {
      const auto& want = payloads.at(e.id.value);
      CHECK(std::memcmp(arena.Slot(e.slot).data(), want.data(), want.size()) == 0);
    }
  }
}

TEST_CASE("a page size that SQLite cannot use is refused before anything is created") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  auto w = MapDbWriter::Create(path, false, MapDbWriterOptions{.page_bytes = 3000});
  REQUIRE_FALSE(w.ok());
  CHECK(w.status().code() == StatusCode::kInvalidArgument);
  CHECK(Contains(w.status(), "page size 3000 bytes: must be a power of two from 512 to 65536"));
  CHECK_FALSE(std::filesystem::exists(path));
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
