// The map database's shared pieces (map_db_internal.h): schema check, row helpers.
#include <string>

#include "mapdb/map_db_internal.h"

namespace zm::mapdb_detail {

using sqlite::ForEachRow;
using sqlite::FromSqlite;
using sqlite::Prepare;

std::string Kf(KeyframeId id) { return "keyframe " + std::to_string(id.value); }

void PoseToDoubles(const Pose3& p, double out[12]) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out[r * 4 + c] = p.linear()(r, c);
    out[r * 4 + 3] = p.translation()(r);
  }
}

bool PoseFromColumn(sqlite3_stmt* s, int col, Pose3& out) {
  if (sqlite3_column_bytes(s, col) != kPoseBlobBytes) return false;
  double v[12];
  std::memcpy(v, sqlite3_column_blob(s, col), sizeof v);
  out = Pose3::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.linear()(r, c) = v[r * 4 + c];
    out.translation()(r) = v[r * 4 + 3];
  }
  return true;
}

Status CheckSchema(sqlite3* db, const std::string& path, int* version_out) {
  ZM_ASSIGN_OR_RETURN(sqlite::Stmt s, Prepare(db, "PRAGMA user_version"));
  const int rc = sqlite3_step(s.get());
  if (rc != SQLITE_ROW) {
    const Status st = FromSqlite(rc, db, path);
    if ((rc & 0xff) == SQLITE_NOTADB || (rc & 0xff) == SQLITE_CORRUPT) {
      return Corrupt(path + " is not a valid SQLite database or is truncated (" +
                     sqlite::DescribeFileVsHeader(path) + "): " + st.message());
    }
    return st;
  }
  const int version = sqlite3_column_int(s.get(), 0);
  if (version != kMapDbSchemaVersion && version != kMapDbSchemaVersionNoVocabulary) {
    ZM_ASSIGN_OR_RETURN(const bool has_keyframe, sqlite::TableExists(db, "keyframe"));
    if (version == 0 && !has_keyframe) {
      return FailedPrecondition(path + " is not a zonemap map database (schema version 0, no table "
                                "keyframe)");
    }
    return FailedPrecondition(path + " has map schema version " + std::to_string(version) +
                              "; this build reads versions " +
                              std::to_string(kMapDbSchemaVersionNoVocabulary) + " and " +
                              std::to_string(kMapDbSchemaVersion));
  }
  for (const char* t : kTables) {
    ZM_ASSIGN_OR_RETURN(const bool exists, sqlite::TableExists(db, t));
    if (!exists) {
      return Corrupt(path + ": missing table " + t + " (schema version " +
                     std::to_string(version) +
                     " needs keyframe, payload, link, zone, zone_member, meta" +
                     (version >= kMapDbSchemaVersion ? ", vocabulary)" : ")"));
    }
  }
  if (version >= kMapDbSchemaVersion) {
    ZM_ASSIGN_OR_RETURN(const bool exists, sqlite::TableExists(db, "vocabulary"));
    if (!exists) {
      return Corrupt(path + ": missing table vocabulary (schema version " +
                     std::to_string(version) +
                     " needs keyframe, payload, link, zone, zone_member, meta, vocabulary)");
    }
  }
  *version_out = version;
  return Status::Ok();
}

Result<sqlite::Stmt> PrepareOn(sqlite3* db, const std::string& path, std::string_view table,
                               std::string_view sql) {
  auto s = Prepare(db, sql);
  // Out of memory is not a schema problem (tests/reliability/sqlite_oom_test.cc).
  if (!s.ok() && s.status().code() == StatusCode::kResourceExhausted) return s.status();
  if (!s.ok()) {
    return Corrupt(path + ": table " + std::string(table) +
                   " does not have the expected columns: " + s.status().message());
  }
  return s;
}

Result<std::vector<KeyframeMeta>> ReadKeyframes(sqlite3* db, sqlite3_stmt* s) {
  std::vector<KeyframeMeta> out;
  ZM_RETURN_IF_ERROR(ForEachRow(db, s, "reading table keyframe", [&](sqlite3_stmt*) -> Status {
    KeyframeMeta m;
    m.id = KeyframeId{sqlite3_column_int64(s, 0)};
    m.stamp_s = sqlite3_column_double(s, 1);
    if (!PoseFromColumn(s, 2, m.pose)) {
      return Corrupt(Kf(m.id) + ": pose blob is " + std::to_string(sqlite3_column_bytes(s, 2)) +
                     " bytes, expected " + std::to_string(kPoseBlobBytes) + " (12 float64)");
    }
    m.weight = sqlite3_column_int(s, 3);
    if (!sqlite::ColumnU32(s, 4, m.payload_bytes)) {
      return Corrupt(Kf(m.id) + ": payload_bytes " + std::to_string(sqlite3_column_int64(s, 4)) +
                     " out of range");
    }
    out.push_back(m);
    return Status::Ok();
  }));
  return out;
}

Status LinkFromRow(sqlite3_stmt* s, LinkRecord& l) {
  l.from = KeyframeId{sqlite3_column_int64(s, 0)};
  l.to = KeyframeId{sqlite3_column_int64(s, 1)};
  l.type = static_cast<LinkType>(sqlite3_column_int(s, 2));
  const auto what = [&] {
    return "link " + std::to_string(l.from.value) + "->" + std::to_string(l.to.value);
  };
  if (!PoseFromColumn(s, 3, l.transform)) {
    return Corrupt(what() + ": transform blob is " + std::to_string(sqlite3_column_bytes(s, 3)) +
                   " bytes, expected " + std::to_string(kPoseBlobBytes));
  }
  if (sqlite3_column_bytes(s, 4) != kInformationBlobBytes) {
    return Corrupt(what() + ": information blob is " + std::to_string(sqlite3_column_bytes(s, 4)) +
                   " bytes, expected " + std::to_string(kInformationBlobBytes) + " (36 float64)");
  }
  std::memcpy(l.information.data(), sqlite3_column_blob(s, 4), kInformationBlobBytes);
  return Status::Ok();
}

Result<std::vector<LinkRecord>> ReadLinks(sqlite3* db, sqlite3_stmt* s) {
  std::vector<LinkRecord> out;
  const auto row = [&](sqlite3_stmt*) {
    LinkRecord l;
    ZM_RETURN_IF_ERROR(LinkFromRow(s, l));
    out.push_back(l);
    return Status::Ok();
  };
  ZM_RETURN_IF_ERROR(ForEachRow(db, s, "reading table link", row));
  return out;
}

}  // namespace zm::mapdb_detail
