// SQLite's fixed heap: blocks by power-of-two class, reuse within a class, refusal (never a
// fallback) when the reservation is used up, realloc's contract; SQLite runs on it, and a warm
// query loop calls malloc zero times while the reservation's high-water mark stays put.
#include "runtime/sqlite_heap.h"

#include <doctest/doctest.h>
#include <sqlite3.h>

#include <cstring>
#include <vector>

#include "support/counting_allocator.h"

namespace zm {
namespace {

TEST_CASE("blocks are class-rounded, reused within their class, refused when the heap is full") {
  auto heap = SqliteHeap::Install(1 << 20);
  REQUIRE_MESSAGE(heap.ok(), heap.status().ToString());
  SqliteHeap& h = *heap.value();
  CHECK(SqliteHeap::RoundUp(1) == 16);
  CHECK(SqliteHeap::RoundUp(16) == 16);
  CHECK(SqliteHeap::RoundUp(17) == 48);
  CHECK(SqliteHeap::RoundUp(1000) == 1008);
  void* a = h.Allocate(100);
  REQUIRE(a != nullptr);
  CHECK(reinterpret_cast<std::uintptr_t>(a) % 16 == 0);
  CHECK(h.UsableSize(a) == 112);
  std::memset(a, 0x5A, 100);
  const std::uint64_t carved = h.stats().carved_bytes;
  h.Free(a);
  void* b = h.Allocate(90);  // same class: the freed block again, nothing new carved
  CHECK(b == a);
  CHECK(h.stats().carved_bytes == carved);
  // realloc: same class in place; a larger one moves and keeps the bytes; failure keeps the old.
  std::memset(b, 0x33, 90);
  CHECK(h.Reallocate(b, 110) == b);
  void* c = h.Reallocate(b, 5000);
  REQUIRE(c != nullptr);
  CHECK(static_cast<unsigned char*>(c)[89] == 0x33);
  CHECK(h.Reallocate(c, std::size_t{1} << 30) == nullptr);  // beyond a quarter of the heap
  CHECK(static_cast<unsigned char*>(c)[0] == 0x33);
  h.Free(c);
  // Fill the reservation with 64 KiB blocks: the next request is refused, never served elsewhere.
  std::vector<void*> blocks;
  for (;;) {
    void* p = h.Allocate(60000);
    if (p == nullptr) break;
    blocks.push_back(p);
    REQUIRE(blocks.size() < 64);
  }
  CHECK(h.stats().refused >= 2);
  CHECK(h.stats().carved_bytes <= h.stats().capacity_bytes);
  for (void* p : blocks) h.Free(p);
  CHECK(h.stats().in_use_bytes == 0);
}

TEST_CASE("SQLite runs on it, and a warm query loop never calls malloc") {
  auto heap = SqliteHeap::Install(16 << 20);
  REQUIRE(heap.ok());
  {
    sqlite3* db = nullptr;
    REQUIRE(sqlite3_open(":memory:", &db) == SQLITE_OK);
    REQUIRE(sqlite3_exec(db, "CREATE TABLE t(id INTEGER PRIMARY KEY, v BLOB);", nullptr, nullptr,
                         nullptr) == SQLITE_OK);
    sqlite3_stmt* ins = nullptr;
    REQUIRE(sqlite3_prepare_v2(db, "INSERT INTO t(v) VALUES(zeroblob(?))", -1, &ins, nullptr) ==
            SQLITE_OK);
    for (int i = 0; i < 200; ++i) {
      sqlite3_bind_int(ins, 1, 100 + i);
      REQUIRE(sqlite3_step(ins) == SQLITE_DONE);
      sqlite3_reset(ins);
    }
    sqlite3_finalize(ins);
    sqlite3_stmt* sel = nullptr;
    REQUIRE(sqlite3_prepare_v2(db, "SELECT length(v) FROM t WHERE id BETWEEN ? AND ?", -1, &sel,
                               nullptr) == SQLITE_OK);
    const auto query = [&] {
      std::int64_t sum = 0;
      for (int z = 0; z < 10; ++z) {
        sqlite3_bind_int(sel, 1, 20 * z + 1);
        sqlite3_bind_int(sel, 2, 20 * z + 20);
        while (sqlite3_step(sel) == SQLITE_ROW) sum += sqlite3_column_int(sel, 0);
        sqlite3_reset(sel);
        sqlite3_blob* blob = nullptr;  // what MapDb does per keyframe
        REQUIRE(sqlite3_blob_open(db, "main", "t", "v", 20 * z + 5, 0, &blob) == SQLITE_OK);
        sum += sqlite3_blob_bytes(blob);
        sqlite3_blob_close(blob);
      }
      return sum;
    };
    CHECK(query() > 0);  // warm-up
    const std::uint64_t carved = heap.value()->stats().carved_bytes;
    test::MallocCounter mallocs;
    for (int i = 0; i < 50; ++i) query();
    CHECK(mallocs.mallocs() == 0);
    CHECK(heap.value()->stats().carved_bytes == carved);  // the high-water mark stays put
    CHECK(heap.value()->stats().allocations > 0);         // SQLite did allocate: from the heap
    sqlite3_finalize(sel);
    sqlite3_close(db);
  }
  CHECK(heap.value()->stats().in_use_bytes == 0);
}

TEST_CASE("one heap per process") {
  auto a = SqliteHeap::Install(1 << 20);
  REQUIRE(a.ok());
  auto b = SqliteHeap::Install(1 << 20);
  CHECK_FALSE(b.ok());
  CHECK_FALSE(SqliteHeap::Install(1000).ok());
}

}  // namespace
}  // namespace zm
