// Small helpers many test files wrote for themselves, one copy each: text searches in strings and
// Status messages, splitting output into lines, reaping a child, running SQL on a map file to
// damage it on purpose. One definition also lets a test folder compile as one unity source.
#pragma once

#include <doctest/doctest.h>
#include <sqlite3.h>
#include <sys/types.h>
#include <sys/wait.h>

#include <cerrno>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "common/status.h"

namespace zm::test {

inline constexpr std::uint64_t kMiB = 1ULL << 20;

[[nodiscard]] inline bool Contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}
[[nodiscard]] inline bool Contains(const Status& s, const std::string& text) {
  return s.message().find(text) != std::string::npos;
}

// The lines of `text`, without their '\n'.
[[nodiscard]] inline std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string l;
  while (std::getline(in, l)) out.push_back(l);
  return out;
}

// waitpid's status of `pid`, retried over EINTR.
inline int Reap(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return status;
}

// Runs SQL on the file with a plain read-write connection (to damage it on purpose), leaving it
// in rollback-journal mode so the file alone is the whole database.
inline void Sql(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
  char* err = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err);
  INFO(sql << ": " << (err ? err : ""));
  sqlite3_free(err);
  sqlite3_close(db);
  REQUIRE(rc == SQLITE_OK);
}

}  // namespace zm::test
