// Every bad input of issue 3 gives one clear error naming the keyframe or table and the sizes,
// never writes outside a slot (every slot that was not reported loaded keeps its bytes), leaves
// the reader usable, and never changes the file on disk.
#include <doctest/doctest.h>
#include <sqlite3.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>

#include "mapdb/map_db.h"
#include "mapdb/mapdb_test_util.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::Contains;
using test::Sql;

using test::BuildMap;
using test::EditPayload;
using test::MakeArena;
using test::RecordingSink;
using test::Snapshot;
using test::TempDir;

// Fills every slot with a pattern (holding them all), then frees `free_slots` of them, so a
// load can only use those; returns a copy of the whole arena to compare against afterwards.
std::vector<std::byte> Prepare(Arena& arena, std::uint32_t free_slots) {
  for (std::uint32_t i = 0; i < arena.capacity(); ++i) {
    const auto s = arena.TryAcquire();
    REQUIRE(s.has_value());
    std::memset(arena.Slot(*s).data(), 0x5A + static_cast<int>(i), arena.slot_bytes());
  }
  for (std::uint32_t i = 0; i < free_slots; ++i) arena.Release(SlotIndex{i});
  std::vector<std::byte> copy;
  for (std::uint32_t i = 0; i < arena.capacity(); ++i) {
    auto s = arena.Slot(SlotIndex{i});
    copy.insert(copy.end(), s.begin(), s.end());
  }
  return copy;
}

// Every slot not reported loaded has exactly its bytes from before the load, except that the
// one slot a rejected payload was read into (then released) may differ in its first
// `rejected_bytes` bytes: the rejected blob stayed inside its slot. Without arena poisoning
// (release builds) those bytes are visible; with it they were overwritten by the release pattern.
void CheckUntouched(const Arena& arena, const std::vector<std::byte>& before,
                    const RecordingSink& sink, std::size_t rejected_bytes = 0) {
  int changed = 0;
  for (std::uint32_t i = 0; i < arena.capacity(); ++i) {
    bool loaded = false;
    for (const auto& e : sink.loaded()) loaded |= e.slot == SlotIndex{i};
    if (loaded) continue;
    const auto s = arena.Slot(SlotIndex{i});
    const std::byte* was = before.data() + std::size_t{i} * arena.slot_bytes();
    INFO("slot " << i);
    if (std::memcmp(s.data(), was, s.size()) == 0) continue;
    ++changed;
    CHECK_FALSE(arena.InUse(SlotIndex{i}));
    CHECK(std::memcmp(s.data() + rejected_bytes, was + rejected_bytes, s.size() - rejected_bytes) ==
          0);
  }
  CHECK(changed <= (rejected_bytes > 0 ? 1 : 0));
}

struct Fixture {
  TempDir dir;
  std::string path = dir.File("map.db");
  test::BuiltMap built = BuildMap(path);
};

TEST_CASE("a blob larger than slot_bytes is refused before any byte is copied") {
  Fixture f;
  const std::uint64_t small = f.built.payloads.at(10).size();  // rounded up, still < 11's size
  auto db = MapDb::Open(f.path);
  REQUIRE(db.ok());
  Arena arena = MakeArena(8, small);
  REQUIRE(arena.slot_bytes() < f.built.payloads.at(11).size());
  const auto before = Prepare(arena, 4);
  const auto file_before = Snapshot(f.path);
  RecordingSink sink;
  auto st = (*db)->LoadZone(ZoneId{2}, arena, sink);  // 9, 10 fit; 11 does not
  REQUIRE_FALSE(st.ok());
  CHECK(st.status().code() == StatusCode::kOutOfRange);
  CHECK(Contains(st.status(), "keyframe 11"));
  CHECK(Contains(st.status(), std::to_string(f.built.payloads.at(11).size()) + " bytes"));
  CHECK(Contains(st.status(), "slot of " + std::to_string(arena.slot_bytes()) + " bytes"));
  CHECK(sink.loaded().size() == 2);  // already reported: they stay loaded
  CHECK(arena.in_use() == 4 + 2);
  CheckUntouched(arena, before, sink);

  RecordingSink sink2;
  const std::vector<KeyframeId> ids = {KeyframeId{12}};
  auto st2 = (*db)->LoadKeyframes(ids, arena, sink2);
  REQUIRE_FALSE(st2.ok());
  CHECK(st2.status().code() == StatusCode::kOutOfRange);
  CHECK(arena.in_use() == 6);
  CHECK(Snapshot(f.path) == file_before);
}

TEST_CASE("truncated, corrupt, misplaced and missing payload blobs give clear errors") {
  Fixture f;
  std::string expect;
  std::int64_t bad_id = 7;  // zone 1 holds 5, 6, 7, 8
  std::size_t bad_bytes = f.built.payloads.at(7).size();
  SUBCASE("truncated") {
    EditPayload(f.path, bad_id, [](auto& b) { b.resize(b.size() - 100); });
    expect = "truncated";
    bad_bytes -= 100;
  }
  SUBCASE("corrupt body") {
    EditPayload(f.path, bad_id, [](auto& b) { b[200] ^= 0x40; });
    expect = "checksum mismatch";
  }
  SUBCASE("corrupt header") {
    EditPayload(f.path, bad_id, [](auto& b) { b[0] = 0; });
    expect = "bad magic";
  }
  SUBCASE("shorter than a header") {
    EditPayload(f.path, bad_id, [](auto& b) { b.resize(10); });
    expect = "shorter than";
    bad_bytes = 10;
  }
  SUBCASE("another keyframe's payload") {
    EditPayload(f.path, bad_id, [&](auto& b) {
      const auto& other = f.built.payloads.at(6);
      b.assign(reinterpret_cast<const unsigned char*>(other.data()),
               reinterpret_cast<const unsigned char*>(other.data()) + other.size());
    });
    expect = "holds keyframe 6";
    bad_bytes = f.built.payloads.at(6).size();
  }
  SUBCASE("missing payload row") {
    Sql(f.path, "DELETE FROM payload WHERE keyframe_id=7");
    expect = "no readable payload row";
    bad_bytes = 0;
  }
  const auto file_before = Snapshot(f.path);
  auto db = MapDb::Open(f.path);
  REQUIRE(db.ok());
  Arena arena = MakeArena(8, (*db)->metadata().largest_payload_bytes);
  const auto before = Prepare(arena, 8);
  RecordingSink sink;
  auto st = (*db)->LoadZone(ZoneId{1}, arena, sink);
  REQUIRE_FALSE(st.ok());
  INFO(st.status().ToString());
  CHECK(st.status().code() == StatusCode::kCorrupt);
  CHECK(Contains(st.status(), "keyframe 7"));
  CHECK(Contains(st.status(), expect));
  CHECK(sink.loaded().size() == 2);  // 5 and 6 came before 7
  CHECK(arena.in_use() == 2);        // 7's slot was released
  CheckUntouched(arena, before, sink, bad_bytes);
  // The reader is still usable: the failed load ended its transaction.
  auto ok = (*db)->LoadZone(ZoneId{2}, arena, sink);
  CHECK(ok.ok());
  CHECK(Snapshot(f.path) == file_before);
}

TEST_CASE("a corrupt body loads when checksums are off (option honoured)") {
  Fixture f;
  EditPayload(f.path, 3, [](auto& b) { b[200] ^= 0x40; });
  auto db = MapDb::Open(f.path, MapDbOptions{.verify_checksums = false});
  REQUIRE(db.ok());
  Arena arena = MakeArena(8, (*db)->metadata().largest_payload_bytes);
  RecordingSink sink;
  CHECK((*db)->LoadZone(ZoneId{0}, arena, sink).ok());
}

TEST_CASE("a full arena stops the load with ResourceExhausted") {
  Fixture f;
  auto db = MapDb::Open(f.path);
  REQUIRE(db.ok());
  Arena arena = MakeArena(3, (*db)->metadata().largest_payload_bytes);
  RecordingSink sink;
  auto st = (*db)->LoadZone(ZoneId{0}, arena, sink);
  REQUIRE_FALSE(st.ok());
  CHECK(st.status().code() == StatusCode::kResourceExhausted);
  CHECK(Contains(st.status(), "keyframe 4"));
  CHECK(Contains(st.status(), "3 slots"));
  CHECK(sink.loaded().size() == 3);
}

// Open must fail with `code` and `expect` in the message, without creating or changing the file.
void ExpectOpenFails(const std::string& path, StatusCode code, const std::string& expect) {
  const bool existed = std::filesystem::exists(path);
  const auto file_before = existed ? Snapshot(path) : std::vector<char>{};
  auto db = MapDb::Open(path);
  REQUIRE_FALSE(db.ok());
  INFO(db.status().ToString());
  CHECK(db.status().code() == code);
  CHECK(Contains(db.status(), expect));
  CHECK(std::filesystem::exists(path) == existed);
  if (existed) CHECK(Snapshot(path) == file_before);
}

TEST_CASE("a map with a bad schema or metadata is refused at open with one clear error") {
  Fixture f;
  SUBCASE("wrong schema version") {
    Sql(f.path, "PRAGMA user_version=7");
    ExpectOpenFails(f.path, StatusCode::kFailedPrecondition,
                    "schema version 7; this build reads versions 1 and 2");
  }
  SUBCASE("missing table") {
    Sql(f.path, "DROP TABLE zone_member");
    ExpectOpenFails(f.path, StatusCode::kCorrupt, "missing table zone_member");
  }
  SUBCASE("missing column") {
    Sql(f.path, "ALTER TABLE keyframe DROP COLUMN weight");
    ExpectOpenFails(f.path, StatusCode::kCorrupt,
                    "table keyframe does not have the expected columns");
  }
  SUBCASE("meta disagrees with the tables") {
    Sql(f.path, "UPDATE meta SET value=10 WHERE key='largest_payload_bytes'");
    ExpectOpenFails(f.path, StatusCode::kCorrupt, "largest payload 10 bytes");
  }
  SUBCASE("writer never finished") {
    Sql(f.path, "DELETE FROM meta WHERE key='keyframe_count'");
    ExpectOpenFails(f.path, StatusCode::kFailedPrecondition, "not finished");
  }
}

TEST_CASE("files that are not a whole zonemap map are refused at open with one clear error") {
  TempDir dir;
  SUBCASE("not a database") {
    const std::string path = dir.File("text.db");
    std::ofstream(path) << std::string(4096, 'x');
    ExpectOpenFails(path, StatusCode::kCorrupt, "not a valid SQLite database");
  }
  SUBCASE("some other SQLite database") {
    const std::string path = dir.File("other.db");
    Sql(path, "CREATE TABLE t(x)");
    ExpectOpenFails(path, StatusCode::kFailedPrecondition, "not a zonemap map database");
  }
  SUBCASE("empty file") {
    const std::string path = dir.File("empty.db");
    std::ofstream(path).flush();
    ExpectOpenFails(path, StatusCode::kInvalidArgument, "empty (0 bytes)");
  }
  SUBCASE("no such file") {
    ExpectOpenFails(dir.File("nope.db"), StatusCode::kNotFound, "does not exist");
  }
  SUBCASE("truncated database") {
    const std::string path = dir.File("map.db");
    BuildMap(path);
    std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
    ExpectOpenFails(path, StatusCode::kCorrupt, "truncated");
  }
}

}  // namespace
}  // namespace zm
