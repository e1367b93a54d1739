// SQLite plumbing: see sqlite_util.h. FromSqlite() is the only function that turns SQLite result
// codes into Status codes; everything else in lib/mapdb goes through it.
#include "mapdb/sqlite_util.h"

#include <array>
#include <filesystem>
#include <fstream>

namespace zm::sqlite {

Status FromSqlite(int rc, sqlite3* db, std::string_view context) {
  if (rc == SQLITE_OK || rc == SQLITE_DONE || rc == SQLITE_ROW) return Status::Ok();
  std::string msg(context);
  msg += ": ";
  msg += (db != nullptr && sqlite3_errcode(db) == rc) ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  msg += " (SQLite code " + std::to_string(rc) + ")";
  switch (rc & 0xff) {
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
    case SQLITE_FORMAT:
      return Corrupt(std::move(msg));
    case SQLITE_NOMEM:
    case SQLITE_FULL:
      return ResourceExhausted(std::move(msg));
    case SQLITE_CONSTRAINT:
    case SQLITE_MISMATCH:
    case SQLITE_TOOBIG:
    case SQLITE_RANGE:
    case SQLITE_ERROR:
      return InvalidArgument(std::move(msg));
    case SQLITE_NOTFOUND:
      return NotFound(std::move(msg));
    case SQLITE_MISUSE:
    case SQLITE_INTERNAL:
      return Internal(std::move(msg));
    default:  // IOERR, CANTOPEN, READONLY, BUSY, LOCKED, PERM, AUTH, ...
      return IoError(std::move(msg));
  }
}

Result<Db> Open(const std::string& path, int flags) {
  sqlite3* raw = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &raw, flags, nullptr);
  Db db(raw);  // owns the handle even when open failed (sqlite3 allocates one for the message)
  if (rc != SQLITE_OK) return FromSqlite(rc, raw, "opening " + path);
  sqlite3_extended_result_codes(raw, 1);
  return db;
}

Result<Stmt> Prepare(sqlite3* db, std::string_view sql) {
  sqlite3_stmt* raw = nullptr;
  const int rc = sqlite3_prepare_v3(db, sql.data(), static_cast<int>(sql.size()),
                                    SQLITE_PREPARE_PERSISTENT, &raw, nullptr);
  Stmt s(raw);
  if (rc != SQLITE_OK) return FromSqlite(rc, db, "preparing \"" + std::string(sql) + "\"");
  return s;
}

Status Exec(sqlite3* db, const std::string& sql, std::string_view context) {
  char* err = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err);
  sqlite3_free(err);  // the connection keeps the message for FromSqlite
  return FromSqlite(rc, db, context);
}

Status StepDone(sqlite3* db, sqlite3_stmt* s, std::string_view context) {
  StmtReset reset(s);
  int rc = sqlite3_step(s);
  while (rc == SQLITE_ROW) rc = sqlite3_step(s);
  return FromSqlite(rc, db, context);
}

Result<bool> TableExists(sqlite3* db, const std::string& table) {
  ZM_ASSIGN_OR_RETURN(Stmt s, Prepare(db, "SELECT 1 FROM sqlite_master WHERE type='table' AND name=?1"));
  sqlite3_bind_text(s.get(), 1, table.c_str(), -1, SQLITE_TRANSIENT);
  const int rc = sqlite3_step(s.get());
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  return FromSqlite(rc, db, "looking for table " + table);
}

Result<std::vector<std::string>> TableColumns(sqlite3* db, const std::string& table) {
  ZM_ASSIGN_OR_RETURN(Stmt s, Prepare(db, "SELECT name FROM pragma_table_info(?1)"));
  sqlite3_bind_text(s.get(), 1, table.c_str(), -1, SQLITE_TRANSIENT);
  std::vector<std::string> cols;
  int rc;
  while ((rc = sqlite3_step(s.get())) == SQLITE_ROW) {
    cols.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(s.get(), 0)));
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, "reading the columns of table " + table);
  return cols;
}

bool ColumnU32(sqlite3_stmt* s, int col, std::uint32_t& out) {
  const sqlite3_int64 v = sqlite3_column_int64(s, col);
  if (v < 0 || v > 0xffffffffLL) return false;
  out = static_cast<std::uint32_t>(v);
  return true;
}

std::string DescribeFileVsHeader(const std::string& path) {
  std::error_code ec;
  const auto file_bytes = std::filesystem::file_size(path, ec);
  if (ec) return {};
  std::string out = "file is " + std::to_string(file_bytes) + " bytes";
  std::ifstream in(path, std::ios::binary);
  std::array<unsigned char, 100> h{};
  if (!in.read(reinterpret_cast<char*>(h.data()), static_cast<std::streamsize>(h.size()))) {
    return out + ", shorter than the 100-byte SQLite header";
  }
  if (std::string_view(reinterpret_cast<const char*>(h.data()), 16) !=
      std::string_view("SQLite format 3\0", 16)) {
    return out + ", no SQLite header";
  }
  // Page size at offset 16 (big-endian, 1 means 65536), page count at offset 28.
  std::uint64_t page = (std::uint64_t{h[16]} << 8) | h[17];
  if (page == 1) page = 65536;
  const std::uint64_t pages = (std::uint64_t{h[28]} << 24) | (std::uint64_t{h[29]} << 16) |
                              (std::uint64_t{h[30]} << 8) | h[31];
  out += "; header says " + std::to_string(pages) + " pages x " + std::to_string(page) +
         " bytes = " + std::to_string(pages * page) + " bytes";
  if (pages * page > file_bytes) out += " (truncated)";
  return out;
}

}  // namespace zm::sqlite
