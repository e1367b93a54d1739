// SqliteHeap: SQLite's memory from one fixed reservation, so a warm tick of zonemapd never calls
// malloc, not even inside SQLite.
//
// Why: Debian's libsqlite3 is built with SQLITE_SYSTEM_MALLOC and SQLITE_OMIT_LOOKASIDE (and
// without SQLITE_ENABLE_MEMSYS5), so every zone load mallocs and frees inside SQLite (a blob
// handle per keyframe: a VDBE, a copy of the table name; cursor memory per transaction). The
// heap returns to its baseline after each load (tests/mapdb checks sqlite3_memory_used), but
// a daemon meant to run for months should not go through malloc per tick at all: after a
// month of churn a general-purpose heap is what fragments.
//
// How (the arena's rule, and SQLite's own memsys5 idea): SQLITE_CONFIG_MALLOC with a segregated
// free-list allocator over one reservation of `capacity_bytes` (mmap, touched on use): sizes are
// rounded up to a power of two (16 B .. capacity / 4); a class's freed blocks are reused by that
// class only; a new block is cut from the reservation's unused end. When the reservation is used
// up the allocator refuses (SQLite then reports SQLITE_NOMEM, which MapDb maps to
// ResourceExhausted): it never falls back to malloc. In steady state the same classes are reused,
// so the reservation's high-water mark stops moving (tested), and that is the process's SQLite
// memory for as long as it runs.
//
// It is process-wide (SQLite's configuration is): Install() before any database is opened, or
// with none open (it shuts SQLite down and initialises it again). The handle's destructor puts the
// previous allocator back (again with no database open). Thread-safe (one mutex; zonemapd calls
// SQLite from its loop thread only).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "common/status.h"

namespace zm {

struct SqliteHeapStats {
  std::uint64_t capacity_bytes = 0;  // the reservation
  std::uint64_t carved_bytes = 0;    // cut from it so far (its high-water mark, class-rounded)
  std::uint64_t in_use_bytes = 0;    // blocks handed to SQLite now (class-rounded)
  std::uint64_t allocations = 0;     // xMalloc / xRealloc calls served
  std::uint64_t refused = 0;         // requests refused (reservation used up, or too large)
};

class SqliteHeap {
 public:
  // Reserves `capacity_bytes` (at least 1 MiB) and makes it SQLite's allocator.
  [[nodiscard]] static Result<std::unique_ptr<SqliteHeap>> Install(std::uint64_t capacity_bytes);
  ~SqliteHeap();
  SqliteHeap(const SqliteHeap&) = delete;
  SqliteHeap& operator=(const SqliteHeap&) = delete;

  [[nodiscard]] SqliteHeapStats stats() const;

  // The allocator itself, exposed for its own test (SQLite reaches it through SQLITE_CONFIG_MALLOC).
  void* Allocate(std::size_t bytes);
  void Free(void* p);
  void* Reallocate(void* p, std::size_t bytes);
  [[nodiscard]] std::size_t UsableSize(const void* p) const;
  [[nodiscard]] static std::size_t RoundUp(std::size_t bytes);

  struct Impl;

 private:
  SqliteHeap() = default;
  std::unique_ptr<Impl> impl_;
};

}  // namespace zm
