// The map database's happy paths: write/read round trip, zone loads landing exact bytes in
// slots, overlapping zones with Wants() skipping, per-keyframe loads counting their queries,
// and no heap allocation once warm.
#include "mapdb/map_db.h"

#include <doctest/doctest.h>
#include <sqlite3.h>

#include <cstring>

#include "mapdb/mapdb_test_util.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

using test::BuildMap;
using test::LoadFixture;
using test::MakeArena;
using test::RecordingSink;
using test::TempDir;

TEST_CASE("map database round trip keeps metadata, poses, links and zones") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  auto built = BuildMap(path);
  {
    auto w = MapDbWriter::OpenExisting(path);
    REQUIRE(w.ok());
    LinkRecord l;
    l.from = KeyframeId{1};
    l.to = KeyframeId{2};
    l.type = LinkType::kGlobalClosure;
    l.transform = PoseFromXYYaw(1.0, 2.0, 0.3);
    for (std::size_t i = 0; i < 36; ++i) l.information[i] = static_cast<double>(i);
    REQUIRE((*w)->InsertLinks(std::span(&l, 1)).ok());
    REQUIRE((*w)->SetCamera({.fx = 500, .fy = 501, .cx = 320, .cy = 240, .width = 640, .height = 480}).ok());
    REQUIRE((*w)->SetSource("test map").ok());
    REQUIRE((*w)->Finish().ok());
  }
  auto db = MapDb::Open(path);
  REQUIRE_MESSAGE(db.ok(), db.status().ToString());
  const MapMetadata& m = (*db)->metadata();
  CHECK(m.keyframe_count == 12);
  CHECK(m.link_count == 1);
  CHECK(m.zone_count == 3);
  CHECK(m.largest_payload_bytes == built.payloads.at(12).size());
  CHECK(m.camera.fx == 500);
  CHECK(m.camera.height == 480);
  CHECK(m.source == "test map");

  auto kfs = (*db)->Keyframes();
  REQUIRE(kfs.ok());
  REQUIRE(kfs->size() == 12);
  for (std::size_t i = 0; i < kfs->size(); ++i) {
    const KeyframeMeta& got = (*kfs)[i];
    const KeyframeMeta& want = built.metas[i];
    CHECK(got.id == want.id);
    CHECK(got.stamp_s == want.stamp_s);
    CHECK(got.weight == want.weight);
    CHECK(got.payload_bytes == want.payload_bytes);
    CHECK(got.pose.isApprox(want.pose, 1e-15));
  }
  auto links = (*db)->Links();
  REQUIRE(links.ok());
  REQUIRE(links->size() == 1);
  CHECK((*links)[0].type == LinkType::kGlobalClosure);
  CHECK((*links)[0].transform.isApprox(PoseFromXYYaw(1.0, 2.0, 0.3)));
  CHECK((*links)[0].information[35] == 35.0);

  auto zones = (*db)->Zones();
  REQUIRE(zones.ok());
  REQUIRE(zones->size() == 3);
  CHECK((*zones)[1].name == "zone1");
  CHECK((*zones)[1].polygon.size() == 3);
  CHECK((*zones)[1].polygon[1][0] == 2.0);
  auto sizes = (*db)->ZoneSizes();
  REQUIRE(sizes.ok());
  CHECK(*sizes == std::vector<std::uint32_t>{5, 4, 4});
  auto members = (*db)->ZoneMembers();
  REQUIRE(members.ok());
  CHECK(members->size() == 13);
  CHECK((*members)[5].zone == ZoneId{1});
  CHECK((*members)[5].keyframe == KeyframeId{5});
}

TEST_CASE_FIXTURE(LoadFixture,
                  "zone load lands exact payload bytes in slots, one query and one transaction") {
  auto st = db->LoadZone(ZoneId{0}, arena, sink);
  REQUIRE_MESSAGE(st.ok(), st.status().ToString());
  CHECK(st->keyframes == 5);
  CHECK(st->skipped == 0);
  CHECK(st->queries == 1);
  CHECK(st->transactions == 1);
  CHECK(st->blob_reads == 5);
  std::uint64_t bytes = 0;
  REQUIRE(sink.loaded().size() == 5);
  for (const auto& e : sink.loaded()) {
    const auto& want = built.payloads.at(e.id.value);
    REQUIRE(e.bytes == want.size());
    CHECK(std::memcmp(arena.Slot(e.slot).data(), want.data(), want.size()) == 0);
    auto view = DecodePayload(arena.Slot(e.slot), {}, /*blob_is_slot=*/true);
    REQUIRE(view.ok());
    CHECK(view->id == e.id);
    bytes += want.size();
  }
  CHECK(st->bytes == bytes);
  CHECK(arena.in_use() == 5);
  CHECK(db->total_transactions() == 1);
  CHECK(db->total_bytes_read() == bytes);

  SUBCASE("an unknown zone is refused by id") {
    auto bad = db->LoadZone(ZoneId{3}, arena, sink);
    REQUIRE_FALSE(bad.ok());
    CHECK(bad.status().code() == StatusCode::kNotFound);
    CHECK(bad.status().message().find("zone 3") != std::string::npos);
  }
}

TEST_CASE("reads through SQLite's memory map (the default) and through read() land the same bytes") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  auto built = BuildMap(path);
  for (const std::int64_t mmap_bytes : {kMapDbMmapWholeFile, std::int64_t{0}, std::int64_t{8192}}) {
    CAPTURE(mmap_bytes);
    auto db = MapDb::Open(path, MapDbOptions{.verify_checksums = true, .sqlite_heap_limit_bytes = 0,
                                             .mmap_bytes = mmap_bytes});
    REQUIRE(db.ok());
    Arena arena = MakeArena(16, (*db)->metadata().largest_payload_bytes);
    RecordingSink sink;
    REQUIRE((*db)->LoadZone(ZoneId{2}, arena, sink).ok());
    REQUIRE(sink.loaded().size() == 4);
    for (const auto& e : sink.loaded()) {
      const auto& want = built.payloads.at(e.id.value);
      CHECK(std::memcmp(arena.Slot(e.slot).data(), want.data(), want.size()) == 0);
    }
  }
}

TEST_CASE("a flipped byte deep in a payload larger than a copy chunk is caught on both read paths") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  test::MapSpec spec;
  spec.count = 4;
  spec.dense_bytes = 700'000;  // the checksum is computed in 256 KiB pieces as the bytes land
  spec.members = {{1, 2, 3, 4}};
  auto built = BuildMap(path, spec);
  test::EditPayload(path, 3, [](std::vector<unsigned char>& b) { b[650'000] ^= 0x10; });
  for (const std::int64_t mmap_bytes : {kMapDbMmapWholeFile, std::int64_t{0}}) {
    CAPTURE(mmap_bytes);
    auto db = MapDb::Open(path, MapDbOptions{.verify_checksums = true, .sqlite_heap_limit_bytes = 0,
                                             .mmap_bytes = mmap_bytes});
    REQUIRE(db.ok());
    Arena arena = MakeArena(4, (*db)->metadata().largest_payload_bytes);
    RecordingSink sink;
    auto st = (*db)->LoadZone(ZoneId{0}, arena, sink);
    REQUIRE_FALSE(st.ok());
    CHECK(st.status().message().find("keyframe 3") != std::string::npos);
    CHECK(st.status().message().find("checksum mismatch") != std::string::npos);
    CHECK(sink.loaded().size() == 2);
    CHECK(arena.in_use() == 2);
    sink.ReleaseAll(arena);
    const KeyframeId three[] = {KeyframeId{3}};
    auto kf = (*db)->LoadKeyframes(three, arena, sink);
    CHECK(kf.status().message().find("checksum mismatch") != std::string::npos);
    CHECK(arena.in_use() == 0);
    const KeyframeId four[] = {KeyframeId{4}};
    REQUIRE((*db)->LoadKeyframes(four, arena, sink).ok());
    const auto& want = built.payloads.at(4);
    CHECK(std::memcmp(arena.Slot(sink.loaded()[0].slot).data(), want.data(), want.size()) == 0);
  }
}

TEST_CASE("payloads of version 1 (zlib CRC-32) in an older map still load and are checked") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  auto built = BuildMap(path);
  for (std::int64_t id : {9, 10, 11, 12}) {
    test::EditPayload(path, id, [](std::vector<unsigned char>& b) {
      PayloadHeader h;
      std::memcpy(&h, b.data(), sizeof h);
      h.version = kPayloadVersionZlibCrc;
      h.body_crc32 = Crc32(std::as_bytes(std::span(b)).subspan(kPayloadHeaderBytes));
      std::memcpy(b.data(), &h, sizeof h);
    });
  }
  test::EditPayload(path, 11, [](std::vector<unsigned char>& b) { b[300] ^= 1; });
  auto db = MapDb::Open(path);
  REQUIRE(db.ok());
  Arena arena = MakeArena(16, (*db)->metadata().largest_payload_bytes);
  RecordingSink sink;
  auto st = (*db)->LoadZone(ZoneId{2}, arena, sink);  // 9, 10, then 11 is corrupt
  REQUIRE_FALSE(st.ok());
  CHECK(st.status().message().find("keyframe 11") != std::string::npos);
  CHECK(st.status().message().find("checksum mismatch") != std::string::npos);
  REQUIRE(sink.loaded().size() == 2);
  for (const auto& e : sink.loaded()) {
    auto view = DecodePayload(arena.Slot(e.slot), {}, /*blob_is_slot=*/true);
    CHECK(view.ok());
  }
}

TEST_CASE_FIXTURE(LoadFixture, "overlapping zones: resident members are skipped, not read twice") {
  REQUIRE(db->LoadZone(ZoneId{0}, arena, sink).ok());  // 1..5
  auto st = db->LoadZone(ZoneId{1}, arena, sink);      // 5..8, 5 already resident
  REQUIRE(st.ok());
  CHECK(st->keyframes == 3);
  CHECK(st->skipped == 1);
  CHECK(arena.in_use() == 8);
  CHECK(db->total_transactions() == 2);
}

TEST_CASE_FIXTURE(LoadFixture,
                  "per-keyframe loads land exact bytes and count four statements per keyframe") {
  const std::vector<KeyframeId> ids = {KeyframeId{9}, KeyframeId{3}, KeyframeId{12}, KeyframeId{3}};
  auto st = db->LoadKeyframes(ids, arena, sink);
  REQUIRE_MESSAGE(st.ok(), st.status().ToString());
  CHECK(st->keyframes == 3);
  CHECK(st->skipped == 1);  // the second 3 is already resident
  CHECK(st->queries == 4 * 3);  // row, payload, links, calibration (map_db_basic_io_test.cc)
  for (const auto& e : sink.loaded()) {
    const auto& want = built.payloads.at(e.id.value);
    CHECK(std::memcmp(arena.Slot(e.slot).data(), want.data(), want.size()) == 0);
  }
  const std::vector<KeyframeId> missing = {KeyframeId{99}};
  auto bad = db->LoadKeyframes(missing, arena, sink);
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().code() == StatusCode::kNotFound);
  CHECK(bad.status().message().find("keyframe 99") != std::string::npos);
  CHECK(arena.in_use() == 3);
}

TEST_CASE_FIXTURE(LoadFixture, "warm zone and per-keyframe loads make no heap allocation") {
  const std::vector<KeyframeId> ids = {KeyframeId{2}, KeyframeId{7}, KeyframeId{11}};
  const auto cycle = [&] {
    for (std::int32_t z = 0; z < 3; ++z) {
      auto st = db->LoadZone(ZoneId{z}, arena, sink);
      REQUIRE(st.ok());
    }
    for (const auto& e : sink.loaded()) arena.Release(e.slot);
    sink.Clear();
    auto st = db->LoadKeyframes(ids, arena, sink);
    REQUIRE(st.ok());
    for (const auto& e : sink.loaded()) arena.Release(e.slot);
    sink.Clear();
  };
  cycle();  // warm-up: SQLite's page cache, lookaside and statement state
  const std::int64_t sqlite_before = sqlite3_memory_used();
  test::AllocationCounter counter;
  for (int i = 0; i < 20; ++i) cycle();
  CHECK(counter.allocations() == 0);
  // SQLite's own heap (sqlite3_malloc, not operator new) must not grow either.
  CHECK(sqlite3_memory_used() == sqlite_before);
  CHECK(arena.in_use() == 0);
}

}  // namespace
}  // namespace zm
