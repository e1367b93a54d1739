// SQLite plumbing shared by the map database and the RTAB-Map importer (internal to lib/mapdb):
// RAII owners for connections, statements and blob handles, the ONE function that maps SQLite
// result codes to zm::Status, and small helpers for preparing and stepping statements.
//
// Invariants: every sqlite3*, sqlite3_stmt* and sqlite3_blob* is owned by exactly one
// unique_ptr below; a statement stepped in a scope is reset when the scope ends (StmtReset), so
// no statement ever holds a read transaction open by accident.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"

namespace zm::sqlite {

struct DbCloser {
  void operator()(sqlite3* db) const noexcept { sqlite3_close_v2(db); }
};
struct StmtFinalizer {
  void operator()(sqlite3_stmt* s) const noexcept { sqlite3_finalize(s); }
};
struct BlobCloser {
  void operator()(sqlite3_blob* b) const noexcept { sqlite3_blob_close(b); }
};
using Db = std::unique_ptr<sqlite3, DbCloser>;
using Stmt = std::unique_ptr<sqlite3_stmt, StmtFinalizer>;
using Blob = std::unique_ptr<sqlite3_blob, BlobCloser>;

// The one place SQLite result codes become Status codes. `context` names what was being done
// ("reading table keyframe"); the message ends with SQLite's own text for the connection.
[[nodiscard]] Status FromSqlite(int rc, sqlite3* db, std::string_view context);

// Resets (and clears bindings of) a statement when the scope ends.
class StmtReset {
 public:
  explicit StmtReset(sqlite3_stmt* s) noexcept : s_(s) {}
  ~StmtReset() {
    sqlite3_reset(s_);
    sqlite3_clear_bindings(s_);
  }
  StmtReset(const StmtReset&) = delete;
  StmtReset& operator=(const StmtReset&) = delete;

 private:
  sqlite3_stmt* s_;
};

// Opens `path` with `flags` (SQLITE_OPEN_*); extended result codes on.
[[nodiscard]] Result<Db> Open(const std::string& path, int flags);
[[nodiscard]] Result<Stmt> Prepare(sqlite3* db, std::string_view sql);
// Runs one or more statements that return no rows we need.
[[nodiscard]] Status Exec(sqlite3* db, const std::string& sql, std::string_view context);
// Steps a statement to completion (SQLITE_DONE) and resets it.
[[nodiscard]] Status StepDone(sqlite3* db, sqlite3_stmt* s, std::string_view context);

// Steps `s` over every row, calling `row(s)` (returning Status) on each, and resets it when done.
// The first error of a row, or SQLite's (named by `context`: "reading table zone"), ends it.
template <typename RowFn>
[[nodiscard]] Status ForEachRow(sqlite3* db, sqlite3_stmt* s, std::string_view context,
                                RowFn&& row) {
  StmtReset reset(s);
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
    ZM_RETURN_IF_ERROR(row(s));
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, context);
  return Status::Ok();
}

// Whether `table` exists in the main schema.
[[nodiscard]] Result<bool> TableExists(sqlite3* db, const std::string& table);
// Column names of `table` (PRAGMA table_info), empty when the table does not exist.
[[nodiscard]] Result<std::vector<std::string>> TableColumns(sqlite3* db, const std::string& table);

// A 64-bit column value as uint32 when it fits; false otherwise.
[[nodiscard]] bool ColumnU32(sqlite3_stmt* s, int col, std::uint32_t& out);

// What the first 100 bytes of an SQLite file say about its size, for truncation messages:
// "header says 12 pages x 4096 bytes = 49152 bytes, file has 20000 bytes". Empty if unreadable.
[[nodiscard]] std::string DescribeFileVsHeader(const std::string& path);

}  // namespace zm::sqlite
