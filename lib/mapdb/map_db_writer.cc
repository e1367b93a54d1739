// The map database's writer (MapDbWriter): creates the schema of a new map (its page size chosen
// from the first payloads), or opens an existing one for annotation, bringing a version 1 map to
// version 2; bulk inserts in transactions; Finish() leaves one self-contained file.
#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "mapdb/map_db.h"
#include "mapdb/map_db_internal.h"

namespace zm {

std::uint32_t PageBytesForPayload(std::uint64_t mean_payload_bytes) {
  constexpr std::uint64_t kMin = 4096;
  constexpr std::uint64_t kMax = 65536;
  return static_cast<std::uint32_t>(std::clamp<std::uint64_t>(std::bit_floor(mean_payload_bytes / 16),
                                                               kMin, kMax));
}

struct MapDbWriter::Impl {
  std::string path;
  MapDbWriterOptions options;
  bool schema_ready = false;  // false: a new database whose schema waits for the page size
  std::optional<CameraIntrinsics> pending_camera;  // SetCamera/SetSource before the schema
  std::optional<std::string> pending_source;
  sqlite::Db db;
  sqlite::Stmt begin, commit, rollback;
  sqlite::Stmt ins_keyframe, ins_payload, ins_link, ins_zone, ins_member, del_zones, del_members;
  sqlite::Stmt put_meta, keyframe_exists, keyframes, links;
  WriteProgressFn progress;

  Status Prepare() {
    sqlite3* d = db.get();
    ZM_ASSIGN_OR_RETURN(begin, sqlite::Prepare(d, "BEGIN IMMEDIATE"));
    ZM_ASSIGN_OR_RETURN(commit, sqlite::Prepare(d, "COMMIT"));
    ZM_ASSIGN_OR_RETURN(rollback, sqlite::Prepare(d, "ROLLBACK"));
    ZM_ASSIGN_OR_RETURN(ins_keyframe,
                        PrepareOn(d, path, "keyframe",
                                  "INSERT INTO keyframe(id, stamp, pose, weight, payload_bytes) "
                                  "VALUES(?1, ?2, ?3, ?4, ?5)"));
    ZM_ASSIGN_OR_RETURN(ins_payload, PrepareOn(d, path, "payload",
                                               "INSERT INTO payload(keyframe_id, blob) VALUES(?1, ?2)"));
    ZM_ASSIGN_OR_RETURN(ins_link,
                        PrepareOn(d, path, "link",
                                  "INSERT INTO link(from_id, to_id, type, transform, information) "
                                  "VALUES(?1, ?2, ?3, ?4, ?5)"));
    ZM_ASSIGN_OR_RETURN(ins_zone,
                        PrepareOn(d, path, "zone",
                                  "INSERT INTO zone(id, name, kind, floor, z_min, z_max, polygon) "
                                  "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7)"));
    ZM_ASSIGN_OR_RETURN(ins_member, PrepareOn(d, path, "zone_member",
                                              "INSERT INTO zone_member(zone_id, keyframe_id) "
                                              "VALUES(?1, ?2)"));
    ZM_ASSIGN_OR_RETURN(del_zones, PrepareOn(d, path, "zone", "DELETE FROM zone"));
    ZM_ASSIGN_OR_RETURN(del_members, PrepareOn(d, path, "zone_member", "DELETE FROM zone_member"));
    ZM_ASSIGN_OR_RETURN(put_meta, PrepareOn(d, path, "meta",
                                            "INSERT OR REPLACE INTO meta(key, value) VALUES(?1, ?2)"));
    ZM_ASSIGN_OR_RETURN(keyframe_exists,
                        PrepareOn(d, path, "keyframe", "SELECT 1 FROM keyframe WHERE id=?1"));
    ZM_ASSIGN_OR_RETURN(keyframes, PrepareOn(d, path, "keyframe",
                                             "SELECT id, stamp, pose, weight, payload_bytes "
                                             "FROM keyframe ORDER BY id"));
    ZM_ASSIGN_OR_RETURN(links, PrepareOn(d, path, "link",
                                         "SELECT from_id, to_id, type, transform, information "
                                         "FROM link ORDER BY rowid"));
    return Status::Ok();
  }

  // Runs `fn` inside BEGIN IMMEDIATE..COMMIT, rolling back if it fails.
  template <class Fn>
  Status InTransaction(std::string_view what, Fn&& fn) {
    sqlite3* d = db.get();
    ZM_RETURN_IF_ERROR(sqlite::StepDone(d, begin.get(), std::string("BEGIN for ") + std::string(what)));
    Status st = fn();
    if (st.ok()) st = sqlite::StepDone(d, commit.get(), std::string("COMMIT of ") + std::string(what));
    if (!st.ok()) (void)sqlite::StepDone(d, rollback.get(), "ROLLBACK");
    return st;
  }

  Result<bool> KeyframeExists(KeyframeId id) {
    sqlite3_stmt* s = keyframe_exists.get();
    StmtReset reset(s);
    sqlite3_bind_int64(s, 1, id.value);
    const int rc = sqlite3_step(s);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    return FromSqlite(rc, db.get(), "looking up " + Kf(id));
  }

  Status PutMeta(const char* key, const std::string& text) {
    sqlite3_stmt* s = put_meta.get();
    sqlite3_bind_text(s, 1, key, -1, SQLITE_STATIC);
    sqlite3_bind_text(s, 2, text.c_str(), static_cast<int>(text.size()), SQLITE_TRANSIENT);
    return sqlite::StepDone(db.get(), s, std::string("writing meta ") + key);
  }
  Status PutMeta(const char* key, sqlite3_int64 v) {
    sqlite3_stmt* s = put_meta.get();
    sqlite3_bind_text(s, 1, key, -1, SQLITE_STATIC);
    sqlite3_bind_int64(s, 2, v);
    return sqlite::StepDone(db.get(), s, std::string("writing meta ") + key);
  }
  Status PutMeta(const char* key, double v) {
    sqlite3_stmt* s = put_meta.get();
    sqlite3_bind_text(s, 1, key, -1, SQLITE_STATIC);
    sqlite3_bind_double(s, 2, v);
    return sqlite::StepDone(db.get(), s, std::string("writing meta ") + key);
  }

  void Report(std::string_view stage, std::uint64_t done, std::uint64_t total) const {
    if (progress && (done % 256 == 0 || done == total)) progress(stage, done, total);
  }

  Status WriteCamera(const CameraIntrinsics& c) {
    return InTransaction("camera", [&]() -> Status {
      ZM_RETURN_IF_ERROR(PutMeta("camera_fx", c.fx));
      ZM_RETURN_IF_ERROR(PutMeta("camera_fy", c.fy));
      ZM_RETURN_IF_ERROR(PutMeta("camera_cx", c.cx));
      ZM_RETURN_IF_ERROR(PutMeta("camera_cy", c.cy));
      ZM_RETURN_IF_ERROR(PutMeta("camera_width", sqlite3_int64{c.width}));
      return PutMeta("camera_height", sqlite3_int64{c.height});
    });
  }

  // Creates the schema of a new database with `page_bytes` pages (the options' size wins when
  // set), then writes what SetCamera/SetSource kept. A no-op once done.
  Status EnsureSchema(std::uint32_t page_bytes) {
    if (schema_ready) return Status::Ok();
    if (options.page_bytes != 0) page_bytes = options.page_bytes;
    sqlite3* d = db.get();
    // page_size first: it only takes effect on a database with nothing in it yet, and WAL mode
    // would fix it (WAL cannot change the page size).
    ZM_RETURN_IF_ERROR(sqlite::Exec(d,
                                    "PRAGMA page_size=" + std::to_string(page_bytes) +
                                        "; PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;",
                                    "configuring " + path));
    ZM_RETURN_IF_ERROR(sqlite::Exec(
        d, std::string("BEGIN;") + kSchemaSql + kVocabularyTableSql + "PRAGMA user_version=" +
               std::to_string(kMapDbSchemaVersion) + "; COMMIT;",
        "creating the schema in " + path));
    ZM_RETURN_IF_ERROR(Prepare());
    schema_ready = true;
    if (pending_camera) ZM_RETURN_IF_ERROR(WriteCamera(*pending_camera));
    if (pending_source) {
      ZM_RETURN_IF_ERROR(InTransaction("source", [&] { return PutMeta("source", *pending_source); }));
    }
    pending_camera.reset();
    pending_source.reset();
    return Status::Ok();
  }
  Status EnsureSchema() { return EnsureSchema(4096); }
};

MapDbWriter::MapDbWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapDbWriter::~MapDbWriter() = default;

Result<std::unique_ptr<MapDbWriter>> MapDbWriter::Create(const std::string& path, bool overwrite,
                                                         MapDbWriterOptions options) {
  const std::uint32_t page = options.page_bytes;
  if (page != 0 && (page < 512 || page > 65536 || !std::has_single_bit(page))) {
    return InvalidArgument("map database page size " + std::to_string(page) +
                           " bytes: must be a power of two from 512 to 65536 (or 0 = automatic)");
  }
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) {
    if (!overwrite) return FailedPrecondition(path + " already exists (pass overwrite to replace it)");
    for (const char* suffix : {"", "-wal", "-shm", "-journal"}) {
      std::filesystem::remove(path + suffix, ec);
      if (ec) return IoError("cannot remove " + path + suffix + ": " + ec.message());
    }
  }
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->options = options;
  ZM_ASSIGN_OR_RETURN(impl->db, sqlite::Open(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE |
                                                       SQLITE_OPEN_NOMUTEX));
  // The schema waits for the first call that needs it (EnsureSchema), so that the page size
  // can follow the first batch of payloads.
  return std::unique_ptr<MapDbWriter>(new MapDbWriter(std::move(impl)));
}

Result<std::unique_ptr<MapDbWriter>> MapDbWriter::OpenExisting(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return NotFound("map database " + path + " does not exist");
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->schema_ready = true;
  ZM_ASSIGN_OR_RETURN(impl->db, sqlite::Open(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX));
  sqlite3* db = impl->db.get();
  int version = 0;
  ZM_RETURN_IF_ERROR(CheckSchema(db, path, &version));
  ZM_RETURN_IF_ERROR(sqlite::Exec(db, "PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;",
                                  "configuring " + path));
  if (version == kMapDbSchemaVersionNoVocabulary) {
    // Version 1 -> 2: the vocabulary table, empty (map_db.h, kMapDbSchemaVersion), and the
    // version, in one transaction, so the file is one version or the other.
    ZM_RETURN_IF_ERROR(sqlite::Exec(db,
                                    std::string("BEGIN IMMEDIATE;") + kVocabularyTableSql +
                                        "PRAGMA user_version=" +
                                        std::to_string(kMapDbSchemaVersion) + "; COMMIT;",
                                    "upgrading " + path + " to map schema version " +
                                        std::to_string(kMapDbSchemaVersion)));
  }
  // Maps written before the link_to index existed get it here (same schema version: readers
  // work with or without it, only faster with it).
  ZM_RETURN_IF_ERROR(sqlite::Exec(db, "CREATE INDEX IF NOT EXISTS link_to ON link(to_id)",
                                  "indexing table link of " + path));
  ZM_RETURN_IF_ERROR(impl->Prepare());
  return std::unique_ptr<MapDbWriter>(new MapDbWriter(std::move(impl)));
}

void MapDbWriter::SetProgress(WriteProgressFn progress) { impl_->progress = std::move(progress); }

Status MapDbWriter::InsertKeyframes(std::span<const KeyframeRecord> keyframes) {
  Impl& im = *impl_;
  if (!im.schema_ready) {
    std::uint64_t sum = 0;
    for (const KeyframeRecord& k : keyframes) sum += k.payload.size();
    ZM_RETURN_IF_ERROR(im.EnsureSchema(
        PageBytesForPayload(keyframes.empty() ? 0 : sum / keyframes.size())));
  }
  sqlite3* db = im.db.get();
  return im.InTransaction("keyframes", [&]() -> Status {
    std::uint64_t done = 0;
    for (const KeyframeRecord& k : keyframes) {
      const KeyframeId id = k.meta.id;
      auto view = DecodePayload(k.payload);
      if (!view.ok()) return view.status().Annotate("inserting " + Kf(id));
      if (view->id != id) {
        return InvalidArgument("inserting " + Kf(id) + ": its payload is for keyframe " +
                               std::to_string(view->id.value));
      }
      double pose[12];
      PoseToDoubles(k.meta.pose, pose);
      sqlite3_stmt* s = im.ins_keyframe.get();
      sqlite3_bind_int64(s, 1, id.value);
      sqlite3_bind_double(s, 2, k.meta.stamp_s);
      sqlite3_bind_blob(s, 3, pose, sizeof pose, SQLITE_TRANSIENT);
      sqlite3_bind_int(s, 4, k.meta.weight);
      // payload_bytes is what the keyframe occupies in a slot once loaded (its blob, plus what
      // decoding adds for dense payloads): the largest one sizes the arena's slots.
      sqlite3_bind_int64(s, 5, static_cast<sqlite3_int64>(view->resident_bytes));
      Status st = sqlite::StepDone(db, s, "inserting " + Kf(id) + " into table keyframe");
      if (!st.ok()) {
        if (st.code() == StatusCode::kInvalidArgument) {
          return InvalidArgument("inserting " + Kf(id) + ": already in " + im.path + " (" +
                                 st.message() + ")");
        }
        return st;
      }
      s = im.ins_payload.get();
      sqlite3_bind_int64(s, 1, id.value);
      sqlite3_bind_blob64(s, 2, k.payload.data(), k.payload.size(), SQLITE_STATIC);
      ZM_RETURN_IF_ERROR(sqlite::StepDone(db, s, "inserting the payload of " + Kf(id)));
      im.Report("keyframes", ++done, keyframes.size());
    }
    return Status::Ok();
  });
}

Status MapDbWriter::InsertLinks(std::span<const LinkRecord> links) {
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.EnsureSchema());
  sqlite3* db = im.db.get();
  return im.InTransaction("links", [&]() -> Status {
    std::uint64_t done = 0;
    for (const LinkRecord& l : links) {
      const std::string what = "link " + std::to_string(l.from.value) + "->" +
                               std::to_string(l.to.value) + " (type " +
                               std::to_string(static_cast<int>(l.type)) + ")";
      for (const KeyframeId end : {l.from, l.to}) {
        ZM_ASSIGN_OR_RETURN(const bool exists, im.KeyframeExists(end));
        if (!exists) {
          return InvalidArgument(what + ": " + Kf(end) + " is not in the map (insert keyframes first)");
        }
      }
      double t[12];
      PoseToDoubles(l.transform, t);
      sqlite3_stmt* s = im.ins_link.get();
      sqlite3_bind_int64(s, 1, l.from.value);
      sqlite3_bind_int64(s, 2, l.to.value);
      sqlite3_bind_int(s, 3, static_cast<int>(l.type));
      sqlite3_bind_blob(s, 4, t, sizeof t, SQLITE_TRANSIENT);
      sqlite3_bind_blob(s, 5, l.information.data(), kInformationBlobBytes, SQLITE_STATIC);
      ZM_RETURN_IF_ERROR(sqlite::StepDone(db, s, "inserting " + what));
      im.Report("links", ++done, links.size());
    }
    return Status::Ok();
  });
}

Status MapDbWriter::ReplaceZones(std::span<const ZoneRecord> zones,
                                 std::span<const ZoneMember> members) {
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.EnsureSchema());
  sqlite3* db = im.db.get();
  return im.InTransaction("zones", [&]() -> Status {
    ZM_RETURN_IF_ERROR(sqlite::StepDone(db, im.del_members.get(), "clearing table zone_member"));
    ZM_RETURN_IF_ERROR(sqlite::StepDone(db, im.del_zones.get(), "clearing table zone"));
    for (std::size_t i = 0; i < zones.size(); ++i) {
      const ZoneRecord& z = zones[i];
      const std::string what = "zone " + std::to_string(z.id.value) + " (" + z.name + ")";
      if (z.id.value < 0 || static_cast<std::size_t>(z.id.value) != i) {
        return InvalidArgument(what + " at position " + std::to_string(i) +
                               ": zone ids must be dense 0..N-1 in order");
      }
      if (z.name.empty()) return InvalidArgument(what + ": empty name");
      sqlite3_stmt* s = im.ins_zone.get();
      sqlite3_bind_int(s, 1, z.id.value);
      sqlite3_bind_text(s, 2, z.name.c_str(), static_cast<int>(z.name.size()), SQLITE_STATIC);
      sqlite3_bind_text(s, 3, z.kind.c_str(), static_cast<int>(z.kind.size()), SQLITE_STATIC);
      sqlite3_bind_int(s, 4, z.floor);
      sqlite3_bind_double(s, 5, z.z_min_m);
      sqlite3_bind_double(s, 6, z.z_max_m);
      if (z.polygon.empty()) {
        sqlite3_bind_zeroblob(s, 7, 0);
      } else {
        sqlite3_bind_blob64(s, 7, z.polygon.data(), z.polygon.size() * sizeof(z.polygon[0]),
                            SQLITE_STATIC);
      }
      Status st = sqlite::StepDone(db, s, "inserting " + what);
      if (!st.ok()) {
        return st.code() == StatusCode::kInvalidArgument
                   ? InvalidArgument("inserting " + what + ": zone names must be unique (" +
                                     st.message() + ")")
                   : st;
      }
    }
    std::uint64_t done = 0;
    for (const ZoneMember& m : members) {
      const std::string what = "zone " + std::to_string(m.zone.value) + " member " + Kf(m.keyframe);
      if (m.zone.value < 0 || static_cast<std::size_t>(m.zone.value) >= zones.size()) {
        return InvalidArgument(what + ": zone " + std::to_string(m.zone.value) + " is not among the " +
                               std::to_string(zones.size()) + " zones given");
      }
      ZM_ASSIGN_OR_RETURN(const bool exists, im.KeyframeExists(m.keyframe));
      if (!exists) return InvalidArgument(what + ": " + Kf(m.keyframe) + " is not in the map");
      sqlite3_stmt* s = im.ins_member.get();
      sqlite3_bind_int(s, 1, m.zone.value);
      sqlite3_bind_int64(s, 2, m.keyframe.value);
      Status st = sqlite::StepDone(db, s, "inserting " + what);
      if (!st.ok()) {
        return st.code() == StatusCode::kInvalidArgument
                   ? InvalidArgument("inserting " + what + ": listed twice")
                   : st;
      }
      im.Report("zone members", ++done, members.size());
    }
    // The zone count in meta changes in the same transaction as the zones, so a crash before
    // Finish() cannot leave zones that disagree with meta (which Open refuses).
    return im.PutMeta("zone_count", static_cast<sqlite3_int64>(zones.size()));
  });
}

Status MapDbWriter::SetCamera(const CameraIntrinsics& c) {
  Impl& im = *impl_;
  if (!im.schema_ready) {
    im.pending_camera = c;
    return Status::Ok();
  }
  return im.WriteCamera(c);
}

Status MapDbWriter::SetSource(const std::string& source) {
  Impl& im = *impl_;
  if (!im.schema_ready) {
    im.pending_source = source;
    return Status::Ok();
  }
  return im.InTransaction("source", [&] { return im.PutMeta("source", source); });
}

Status MapDbWriter::SetLastWorkingMemory(std::span<const KeyframeId> ids, const std::string& rule) {
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.EnsureSchema());
  sqlite3* db = im.db.get();
  return im.InTransaction("the last working memory", [&]() -> Status {
    // A map written before last_wm existed gets the table here (OpenExisting).
    ZM_RETURN_IF_ERROR(sqlite::Exec(db,
                                    "CREATE TABLE IF NOT EXISTS last_wm(keyframe_id INTEGER "
                                    "PRIMARY KEY) WITHOUT ROWID; DELETE FROM last_wm;",
                                    "preparing table last_wm in " + im.path));
    ZM_ASSIGN_OR_RETURN(sqlite::Stmt ins,
                        Prepare(db, "INSERT OR IGNORE INTO last_wm(keyframe_id) VALUES(?1)"));
    for (const KeyframeId id : ids) {
      ZM_ASSIGN_OR_RETURN(const bool exists, im.KeyframeExists(id));
      if (!exists) {
        return InvalidArgument("the last working memory names " + Kf(id) + ", which is not in " +
                               im.path);
      }
      sqlite3_bind_int64(ins.get(), 1, id.value);
      ZM_RETURN_IF_ERROR(sqlite::StepDone(db, ins.get(), "writing the last working memory"));
    }
    ZM_RETURN_IF_ERROR(im.PutMeta("last_wm_every_node", sqlite3_int64{0}));
    return im.PutMeta("last_wm_rule", rule);
  });
}

Status MapDbWriter::SetLastWorkingMemoryEveryNode(const std::string& rule) {
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.EnsureSchema());
  return im.InTransaction("the last working memory", [&]() -> Status {
    ZM_RETURN_IF_ERROR(sqlite::Exec(im.db.get(),
                                    "CREATE TABLE IF NOT EXISTS last_wm(keyframe_id INTEGER "
                                    "PRIMARY KEY) WITHOUT ROWID; DELETE FROM last_wm;",
                                    "preparing table last_wm in " + im.path));
    ZM_RETURN_IF_ERROR(im.PutMeta("last_wm_every_node", sqlite3_int64{1}));
    return im.PutMeta("last_wm_rule", rule);
  });
}

Status MapDbWriter::SetVocabulary(std::span<const std::byte> blob) {
  Impl& im = *impl_;
  if (blob.empty()) return InvalidArgument("storing a vocabulary in " + im.path + ": empty blob");
  ZM_RETURN_IF_ERROR(im.EnsureSchema());
  sqlite3* db = im.db.get();
  return im.InTransaction("the vocabulary", [&]() -> Status {
    ZM_ASSIGN_OR_RETURN(sqlite::Stmt put,
                        PrepareOn(db, im.path, "vocabulary",
                                  "INSERT OR REPLACE INTO vocabulary(id, blob) VALUES(1, ?1)"));
    sqlite3_bind_blob64(put.get(), 1, blob.data(), blob.size(), SQLITE_STATIC);
    return sqlite::StepDone(db, put.get(), "writing the vocabulary into " + im.path);
  });
}

Result<std::vector<KeyframeMeta>> MapDbWriter::Keyframes() const {
  if (!impl_->schema_ready) return std::vector<KeyframeMeta>{};
  return ReadKeyframes(impl_->db.get(), impl_->keyframes.get());
}

Result<std::vector<LinkRecord>> MapDbWriter::Links() const {
  if (!impl_->schema_ready) return std::vector<LinkRecord>{};
  return ReadLinks(impl_->db.get(), impl_->links.get());
}

Status MapDbWriter::Finish() {
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.EnsureSchema());
  sqlite3* db = im.db.get();
  const auto compute = [&]() -> Status {
    ZM_ASSIGN_OR_RETURN(sqlite::Stmt s,
                        Prepare(db,
                                "SELECT (SELECT count(*) FROM keyframe), "
                                "(SELECT coalesce(max(payload_bytes), 0) FROM keyframe), "
                                "(SELECT coalesce(sum(payload_bytes), 0) FROM keyframe), "
                                "(SELECT count(*) FROM link), (SELECT count(*) FROM zone)"));
    const int rc = sqlite3_step(s.get());
    if (rc != SQLITE_ROW) return FromSqlite(rc, db, "computing the metadata of " + im.path);
    ZM_RETURN_IF_ERROR(im.PutMeta("keyframe_count", sqlite3_column_int64(s.get(), 0)));
    ZM_RETURN_IF_ERROR(im.PutMeta("largest_payload_bytes", sqlite3_column_int64(s.get(), 1)));
    ZM_RETURN_IF_ERROR(im.PutMeta("total_payload_bytes", sqlite3_column_int64(s.get(), 2)));
    ZM_RETURN_IF_ERROR(im.PutMeta("link_count", sqlite3_column_int64(s.get(), 3)));
    return im.PutMeta("zone_count", sqlite3_column_int64(s.get(), 4));
  };
  ZM_RETURN_IF_ERROR(im.InTransaction("metadata", compute));
  // Fold the WAL back into the file and leave it in rollback-journal mode, so the finished map
  // is one self-contained file that a read-only process can open without creating -shm/-wal.
  return sqlite::Exec(db, "PRAGMA wal_checkpoint(TRUNCATE); PRAGMA journal_mode=DELETE;",
                      "checkpointing " + im.path);
}

}  // namespace zm
