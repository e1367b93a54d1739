// SQLite out of memory (issue 11): with MapDbOptions::sqlite_heap_limit_bytes (SQLite's
// sqlite3_hard_heap_limit64) set low, MapDb::Open and zone loads fail with one clean error
// instead of crashing, and every byte SQLite allocated is given back (sqlite3_memory_used()
// returns to its value before the open; LeakSanitizer checks the rest of the process in the ASan
// build). The hard limit is process-wide, so each case restores "no limit" before it ends.
#include <doctest/doctest.h>
#include <sqlite3.h>

#include <string>
#include <vector>

#include "mapdb/map_db.h"
#include "mapdb/mapdb_test_util.h"

namespace zm {
namespace {

using test::BuildMap;
using test::MakeArena;
using test::RecordingSink;
using test::TempDir;

// Restores "no limit" when the scope ends, whatever the test did.
struct HeapLimitReset {
  ~HeapLimitReset() { sqlite3_hard_heap_limit64(0); }
};

struct Attempt {
  Status status = Status::Ok();
  bool opened = false;
};

// Opens with the limit and loads every zone; everything is closed before returning.
Attempt OpenAndLoad(const std::string& path, std::int64_t limit, std::size_t zones) {
  Attempt a;
  MapDbOptions options;
  options.sqlite_heap_limit_bytes = limit;
  auto db = MapDb::Open(path, options);
  if (!db.ok()) {
    a.status = db.status();
    return a;
  }
  a.opened = true;
  Arena arena = MakeArena(64, (*db)->metadata().largest_payload_bytes);
  RecordingSink sink;
  for (std::size_t z = 0; z < zones && a.status.ok(); ++z) {
    auto st = (*db)->LoadZone(ZoneId{static_cast<std::int32_t>(z)}, arena, sink);
    if (!st.ok()) a.status = st.status();
    for (const auto& e : sink.loaded()) arena.Release(e.slot);
    sink.Clear();
  }
  if (a.status.ok()) {
    auto kfs = (*db)->Keyframes();
    if (!kfs.ok()) a.status = kfs.status();
  }
  CHECK(arena.in_use() == 0);
  return a;
}

TEST_CASE("reliability: SQLite out of memory at open or load gives a clean error and no leak") {
  HeapLimitReset reset;
  TempDir dir;
  const std::string path = dir.File("map.db");
  test::MapSpec spec;
  spec.count = 40;
  spec.dense_bytes = 6000;  // payloads span overflow pages: loads need page-cache memory
  spec.members = {{}, {}, {}, {}};
  for (int i = 1; i <= spec.count; ++i) spec.members[static_cast<std::size_t>(i % 4)].push_back(i);
  BuildMap(path, spec);

  const std::int64_t base = sqlite3_memory_used();
  int failures = 0;
  int clean_successes = 0;
  // From far too little to plenty: each step either works or fails cleanly.
  for (std::int64_t extra = 1024; extra <= (std::int64_t{8} << 20); extra *= 2) {
    CAPTURE(extra);
    const Attempt a = OpenAndLoad(path, base + extra, spec.members.size());
    sqlite3_hard_heap_limit64(0);
    CHECK(sqlite3_memory_used() == base);  // SQLite gave back everything it took
    if (a.status.ok()) {
      ++clean_successes;
      continue;
    }
    ++failures;
    INFO(a.status.ToString());
    // Out of memory is reported as such, never as a corrupt file.
    CHECK(a.status.code() == StatusCode::kResourceExhausted);
    CHECK(a.status.message().find("out of memory") != std::string::npos);
  }
  MESSAGE(failures << " limits failed cleanly, " << clean_successes << " worked");
  CHECK(failures > 0);
  CHECK(clean_successes > 0);
  // The last (largest) limit must have worked: the failures were the limit, not the file.
  CHECK(OpenAndLoad(path, base + (std::int64_t{8} << 20), spec.members.size()).status.ok());
}

TEST_CASE("reliability: every allocation failing in turn during open and load never crashes") {
  // SQLite's own fault-injection style: lower the limit byte by byte-ish through the range
  // where the first failure moves from open to load.
  HeapLimitReset reset;
  TempDir dir;
  const std::string path = dir.File("map.db");
  BuildMap(path);
  const std::int64_t base = sqlite3_memory_used();
  std::int64_t first_ok = -1;
  for (std::int64_t extra = 0; extra <= 400 * 1024; extra += 4096) {
    const Attempt a = OpenAndLoad(path, base + std::max<std::int64_t>(extra, 1), 3);
    sqlite3_hard_heap_limit64(0);
    CHECK(sqlite3_memory_used() == base);
    if (a.status.ok()) {
      if (first_ok < 0) first_ok = extra;
    } else {
      INFO(extra << ": " << a.status.ToString());
      CHECK(a.status.code() == StatusCode::kResourceExhausted);
    }
  }
  MESSAGE("first limit that worked: " << first_ok << " bytes above SQLite's baseline");
  CHECK(first_ok > 0);
}

}  // namespace
}  // namespace zm
