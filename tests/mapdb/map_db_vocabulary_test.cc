// The vocabulary table of schema version 2 (issue 26): the writer stores the bytes it is given,
// the reader returns them unchanged or "none" as a value; a version 1 map reads as one without a
// vocabulary and is upgraded by the first writer that opens it; a version 2 map without the
// table, or with a non-blob value in it, is refused with one clear error. (That the bytes are a
// valid vocabulary is lib/localization's check: tests/localization/map_vocabulary_test.cc.)
#include <doctest/doctest.h>
#include <sqlite3.h>

#include <string>
#include <vector>

#include "mapdb/map_db.h"
#include "mapdb/mapdb_test_util.h"
#include "support/test_util.h"

namespace zm {
namespace {

using test::Sql;

using test::BuildMap;
using test::Snapshot;
using test::TempDir;

std::vector<std::byte> Bytes(std::size_t n, unsigned seed) {
  std::vector<std::byte> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<std::byte>((i * 131 + seed) & 0xFF);
  return out;
}

TEST_CASE("map db: a new map is schema version 2 and has no vocabulary until one is stored") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  BuildMap(path);
  auto db = MapDb::Open(path);
  REQUIRE(db.ok());
  CHECK((*db)->schema_version() == kMapDbSchemaVersion);
  auto blob = (*db)->VocabularyBlob();
  REQUIRE(blob.ok());
  CHECK_FALSE(blob->has_value());
}

TEST_CASE("map db: the vocabulary blob round-trips bit-exactly and a second one replaces it") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  BuildMap(path);
  const std::vector<std::byte> first = Bytes(700'001, 3);  // several 4 KiB pages of overflow
  const std::vector<std::byte> second = Bytes(1'234, 9);
  for (const auto* want : {&first, &second}) {
    {
      auto w = MapDbWriter::OpenExisting(path);
      REQUIRE(w.ok());
      REQUIRE((*w)->SetVocabulary(*want).ok());
      REQUIRE((*w)->Finish().ok());
    }
    auto db = MapDb::Open(path);
    REQUIRE(db.ok());
    auto got = (*db)->VocabularyBlob();
    REQUIRE(got.ok());
    REQUIRE(got->has_value());
    CHECK(**got == *want);
  }
}

TEST_CASE("map db: an empty vocabulary blob is refused by the writer") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  BuildMap(path);
  auto w = MapDbWriter::OpenExisting(path);
  REQUIRE(w.ok());
  const Status st = (*w)->SetVocabulary({});
  CHECK(st.code() == StatusCode::kInvalidArgument);
  CHECK(st.message().find("empty blob") != std::string::npos);
}

TEST_CASE("map db: a version 1 map reads as one without a vocabulary and a writer upgrades it") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  BuildMap(path);
  Sql(path, "DROP TABLE vocabulary; PRAGMA user_version=1");  // what builds before issue 26 wrote
  {
    const auto before = Snapshot(path);
    auto db = MapDb::Open(path);
    REQUIRE(db.ok());
    CHECK((*db)->schema_version() == kMapDbSchemaVersionNoVocabulary);
    auto blob = (*db)->VocabularyBlob();
    REQUIRE(blob.ok());
    CHECK_FALSE(blob->has_value());
    CHECK(Snapshot(path) == before);  // reading never upgrades
  }
  {
    auto w = MapDbWriter::OpenExisting(path);
    REQUIRE(w.ok());
    REQUIRE((*w)->SetVocabulary(Bytes(100, 1)).ok());
    REQUIRE((*w)->Finish().ok());
  }
  auto db = MapDb::Open(path);
  REQUIRE(db.ok());
  CHECK((*db)->schema_version() == kMapDbSchemaVersion);
  auto blob = (*db)->VocabularyBlob();
  REQUIRE(blob.ok());
  REQUIRE(blob->has_value());
  CHECK(**blob == Bytes(100, 1));
}

TEST_CASE("map db: a damaged vocabulary table is one clear error") {
  TempDir dir;
  const std::string path = dir.File("map.db");
  BuildMap(path);
  SUBCASE("version 2 without the table is refused at open") {
    Sql(path, "DROP TABLE vocabulary");
    auto db = MapDb::Open(path);
    REQUIRE_FALSE(db.ok());
    CHECK(db.status().code() == StatusCode::kCorrupt);
    CHECK(db.status().message().find("missing table vocabulary") != std::string::npos);
  }
  SUBCASE("a text value instead of a blob") {
    // The CHECK and NOT NULL constraints allow it: SQLite columns are not typed.
    Sql(path, "INSERT INTO vocabulary(id, blob) VALUES(1, 'not a blob')");
    auto db = MapDb::Open(path);
    REQUIRE(db.ok());
    auto blob = (*db)->VocabularyBlob();
    REQUIRE_FALSE(blob.ok());
    CHECK(blob.status().code() == StatusCode::kCorrupt);
    CHECK(blob.status().message().find("table vocabulary holds a non-blob value") !=
          std::string::npos);
  }
}

}  // namespace
}  // namespace zm
