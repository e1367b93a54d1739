// The map database over SQLite, read side (see map_db.h and docs/mapdb.md for the schema).
// The zone loads are in map_db_zone_load.cc, the writer in map_db_writer.cc, what they share in
// map_db_internal.h.
//
// Schema version 2 (version 1 is the same without the vocabulary table, read as a map without a
// vocabulary; MapDbWriter::OpenExisting upgrades it):
//   keyframe(id INTEGER PRIMARY KEY, stamp REAL, pose BLOB = 12 float64 row-major [R|t],
//            weight INTEGER, payload_bytes INTEGER)
//   payload(keyframe_id INTEGER PRIMARY KEY, blob BLOB)   -- separate, so metadata reads no
//                                                          -- payload pages
//   link(from_id, to_id, type, transform BLOB = 12 float64, information BLOB = 36 float64)
//     indexes link_from(from_id) and (maps written since issue 14) link_to(to_id), so the links
//     of a node are two index lookups
//   zone(id INTEGER PRIMARY KEY, name UNIQUE, kind, floor, z_min, z_max, polygon BLOB = n x 2 f64)
//   zone_member(zone_id, keyframe_id, PRIMARY KEY(zone_id, keyframe_id)) WITHOUT ROWID
//   meta(key TEXT PRIMARY KEY, value) WITHOUT ROWID
//   last_wm(keyframe_id INTEGER PRIMARY KEY) WITHOUT ROWID   -- the last working memory, when
//     meta last_wm_rule is set and last_wm_every_node is not 1 (import-rtabmap records one or
//     the other). Optional: maps written before it lack the table and the keys and are read as
//     before; readers that predate it ignore them. So the schema version stayed 1.
//   vocabulary(id INTEGER PRIMARY KEY CHECK(id = 1), blob BLOB)  -- version 2: at most one row,
//     the map's visual vocabulary (lib/localization's Vocabulary::ToBlob bytes)
// The page size is the writer's choice (PageBytesForPayload): 64 KiB for megabyte payloads.
//
// Invariants of the read path:
//   - the database is opened SQLITE_OPEN_READONLY; every statement is prepared in Open();
//   - a zone load is one BEGIN..COMMIT and one statement stepping over zone_member's primary
//     key; payload bytes go straight into the arena slot through an incremental blob handle
//     (sqlite3_blob_read; SQLite reads each overflow page with one pread into the slot), never
//     through a buffer of ours; time-sliced, the transaction, the statement and the blob handle
//     stay open between steps, and nothing else (no slot);
//   - a blob's size is checked against the slot BEFORE any byte is copied, and a slot whose
//     payload fails validation is released before the error is returned, so nothing is written
//     outside a slot and nothing half-valid is reported as loaded;
//   - every error of a zone load ends it (statement reset, blob closed, transaction rolled back);
//   - a validated dense payload is decoded in its slot right away (Impl::Land, dense_codec.h),
#include "mapdb/map_db.h"

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string_view>

#include "mapdb/dense_codec.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db_internal.h"
#include "mapdb/sqlite_util.h"

namespace zm {

Status MapDb::Impl::Validate(KeyframeId id, std::span<const std::byte> blob_bytes,
                const StreamedChecksum& checksum) const {
  auto view = DecodePayload(blob_bytes, DecodeOptions{.verify_crc = options.verify_checksums,
                                                      .body_checksum = checksum.value()});
  if (!view.ok()) return view.status().Annotate(Kf(id) + " in " + path);
  if (view->id != id) {
    return Corrupt(Kf(id) + " in " + path + ": payload row holds keyframe " +
                   std::to_string(view->id.value));
  }
  return Status::Ok();
}

Result<std::uint32_t> MapDb::Impl::Land(KeyframeId id, std::span<std::byte> slot, std::size_t bytes,
                           const StreamedChecksum& checksum) const {
  ZM_RETURN_IF_ERROR(Validate(id, slot.first(bytes), checksum));
  auto resident = dense->DecodeInSlot(slot, bytes);
  if (!resident.ok()) return resident.status().Annotate(Kf(id) + " in " + path);
  return resident;
}

Status MapDb::Impl::ReadNodeRow(KeyframeId id) {
  sqlite3_stmt* s = node_point.get();
  StmtReset reset(s);
  sqlite3_bind_int64(s, 1, id.value);
  const int rc = sqlite3_step(s);
  if (rc == SQLITE_DONE) return NotFound(Kf(id) + " is not in " + path);
  if (rc != SQLITE_ROW) return FromSqlite(rc, db.get(), "reading the row of " + Kf(id));
  Pose3 pose;
  if (!PoseFromColumn(s, 2, pose)) {
    return Corrupt(Kf(id) + ": pose blob is " + std::to_string(sqlite3_column_bytes(s, 2)) +
                   " bytes, expected " + std::to_string(kPoseBlobBytes) + " (12 float64)");
  }
  return Status::Ok();
}

Status MapDb::Impl::ReadLinksOf(KeyframeId id, GraphNodeSink* sink) {
  sqlite3_stmt* s = links_of.get();
  StmtReset reset(s);
  sqlite3_bind_int64(s, 1, id.value);
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
    LinkRecord link;
    ZM_RETURN_IF_ERROR(LinkFromRow(s, link));
    if (sink != nullptr) sink->Link(link);
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, db.get(), "reading the links of " + Kf(id));
  return Status::Ok();
}

Status MapDb::Impl::ReadCalibration(KeyframeId id) {
  sqlite3_stmt* s = calibration.get();
  StmtReset reset(s);
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) (void)sqlite3_column_double(s, 1);
  if (rc != SQLITE_DONE) {
    return FromSqlite(rc, db.get(), "reading the calibration for " + Kf(id));
  }
  return Status::Ok();
}

MapDb::MapDb(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
MapDb::~MapDb() = default;

Result<std::unique_ptr<MapDb>> MapDb::Open(const std::string& path, MapDbOptions options) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return NotFound("map database " + path + " does not exist");
  if (std::filesystem::is_directory(path, ec)) {
    return InvalidArgument("map database " + path + " is a directory, not a file");
  }
  if (std::filesystem::file_size(path, ec) == 0 && !ec) {
    return InvalidArgument(path + " is empty (0 bytes): not a zonemap map database");
  }
  if (options.sqlite_heap_limit_bytes > 0) sqlite3_hard_heap_limit64(options.sqlite_heap_limit_bytes);

  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->options = options;
  ZM_ASSIGN_OR_RETURN(impl->db, sqlite::Open(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX));
  sqlite3* db = impl->db.get();
  ZM_RETURN_IF_ERROR(CheckSchema(db, path, &impl->schema_version));
  if (options.mmap_bytes > 0) {
    ZM_RETURN_IF_ERROR(sqlite::Exec(db, "PRAGMA mmap_size=" + std::to_string(options.mmap_bytes),
                                    "setting mmap_size on " + path));
  }

  ZM_ASSIGN_OR_RETURN(impl->begin, Prepare(db, "BEGIN"));
  ZM_ASSIGN_OR_RETURN(impl->commit, Prepare(db, "COMMIT"));
  ZM_ASSIGN_OR_RETURN(impl->rollback, Prepare(db, "ROLLBACK"));
  ZM_ASSIGN_OR_RETURN(impl->zone_members,
                      PrepareOn(db, path, "zone_member",
                                "SELECT keyframe_id FROM zone_member WHERE zone_id=?1 "
                                "ORDER BY keyframe_id"));
  ZM_ASSIGN_OR_RETURN(impl->payload_point,
                      PrepareOn(db, path, "payload", "SELECT blob FROM payload WHERE keyframe_id=?1"));
  ZM_ASSIGN_OR_RETURN(impl->node_point,
                      PrepareOn(db, path, "keyframe",
                                "SELECT id, stamp, pose, weight, payload_bytes FROM keyframe "
                                "WHERE id=?1"));
  ZM_ASSIGN_OR_RETURN(impl->weight_point,
                      PrepareOn(db, path, "keyframe", "SELECT weight FROM keyframe WHERE id=?1"));
  // Each edge is stored once, so a node's links are those it starts and those it ends: two
  // index lookups (link_from, link_to; a map written before link_to existed scans for the
  // second half, correct but slower: regenerate it or run `zonemap zones annotate` on it).
  ZM_ASSIGN_OR_RETURN(impl->links_of,
                      PrepareOn(db, path, "link",
                                "SELECT from_id, to_id, type, transform, information FROM link "
                                "WHERE from_id=?1 UNION ALL "
                                "SELECT from_id, to_id, type, transform, information FROM link "
                                "WHERE to_id=?1 AND from_id<>?1"));
  ZM_ASSIGN_OR_RETURN(impl->calibration,
                      PrepareOn(db, path, "meta",
                                "SELECT key, value FROM meta WHERE key GLOB 'camera_*'"));
  ZM_ASSIGN_OR_RETURN(impl->keyframes,
                      PrepareOn(db, path, "keyframe",
                                "SELECT id, stamp, pose, weight, payload_bytes FROM keyframe "
                                "ORDER BY id"));
  ZM_ASSIGN_OR_RETURN(impl->links, PrepareOn(db, path, "link",
                                             "SELECT from_id, to_id, type, transform, information "
                                             "FROM link ORDER BY rowid"));
  ZM_ASSIGN_OR_RETURN(impl->zones,
                      PrepareOn(db, path, "zone",
                                "SELECT id, name, kind, floor, z_min, z_max, polygon FROM zone "
                                "ORDER BY id"));
  ZM_ASSIGN_OR_RETURN(impl->all_members,
                      PrepareOn(db, path, "zone_member",
                                "SELECT zone_id, keyframe_id FROM zone_member "
                                "ORDER BY zone_id, keyframe_id"));
  ZM_ASSIGN_OR_RETURN(impl->zone_sizes,
                      PrepareOn(db, path, "zone_member",
                                "SELECT zone_id, count(*) FROM zone_member GROUP BY zone_id"));

  // Metadata, then a cross-check against the keyframe table (which holds no payload pages), so
  // a lying meta table cannot make callers size slots too small.
  ZM_ASSIGN_OR_RETURN(sqlite::Stmt meta_stmt, PrepareOn(db, path, "meta", "SELECT key, value FROM meta"));
  MapMetadata& m = impl->meta;
  bool finished = false;
  int rc;
  while ((rc = sqlite3_step(meta_stmt.get())) == SQLITE_ROW) {
    const char* key_text = reinterpret_cast<const char*>(sqlite3_column_text(meta_stmt.get(), 0));
    const std::string_view key = key_text != nullptr ? key_text : "";
    sqlite3_stmt* s = meta_stmt.get();
    const auto u64 = [&] { return static_cast<std::uint64_t>(sqlite3_column_int64(s, 1)); };
    if (key == "keyframe_count") {
      m.keyframe_count = u64();
      finished = true;
    } else if (key == "link_count") {
      m.link_count = u64();
    } else if (key == "zone_count") {
      m.zone_count = u64();
    } else if (key == "largest_payload_bytes") {
      if (!sqlite::ColumnU32(s, 1, m.largest_payload_bytes)) {
        return Corrupt(path + ": meta largest_payload_bytes out of range");
      }
    } else if (key == "total_payload_bytes") {
      m.total_payload_bytes = u64();
    } else if (key == "camera_fx") {
      m.camera.fx = sqlite3_column_double(s, 1);
    } else if (key == "camera_fy") {
      m.camera.fy = sqlite3_column_double(s, 1);
    } else if (key == "camera_cx") {
      m.camera.cx = sqlite3_column_double(s, 1);
    } else if (key == "camera_cy") {
      m.camera.cy = sqlite3_column_double(s, 1);
    } else if (key == "camera_width") {
      (void)sqlite::ColumnU32(s, 1, m.camera.width);
    } else if (key == "camera_height") {
      (void)sqlite::ColumnU32(s, 1, m.camera.height);
    } else if (key == "source") {
      const auto* t = reinterpret_cast<const char*>(sqlite3_column_text(s, 1));
      m.source = t != nullptr ? t : "";
    }
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, path + ": reading table meta");
  {
    ZM_ASSIGN_OR_RETURN(sqlite::Stmt page, Prepare(db, "PRAGMA page_size"));
    if (sqlite3_step(page.get()) == SQLITE_ROW) {
      m.page_bytes = static_cast<std::uint32_t>(sqlite3_column_int(page.get(), 0));
    }
  }
  if (!finished) {
    return FailedPrecondition(path + " was not finished by its writer (meta has no keyframe_count; "
                              "MapDbWriter::Finish() was not called)");
  }
  ZM_ASSIGN_OR_RETURN(sqlite::Stmt check,
                      PrepareOn(db, path, "keyframe",
                                "SELECT count(*), coalesce(max(payload_bytes), 0), "
                                "(SELECT count(*) FROM zone) FROM keyframe"));
  rc = sqlite3_step(check.get());
  if (rc != SQLITE_ROW) return FromSqlite(rc, db, path + ": counting keyframes");
  const auto kf_count = static_cast<std::uint64_t>(sqlite3_column_int64(check.get(), 0));
  const auto largest = static_cast<std::uint64_t>(sqlite3_column_int64(check.get(), 1));
  const auto zone_count = static_cast<std::uint64_t>(sqlite3_column_int64(check.get(), 2));
  if (kf_count != m.keyframe_count || largest != m.largest_payload_bytes ||
      zone_count != m.zone_count) {
    return Corrupt(path + ": meta says " + std::to_string(m.keyframe_count) + " keyframes, " +
                   std::to_string(m.zone_count) + " zones, largest payload " +
                   std::to_string(m.largest_payload_bytes) + " bytes, but the tables hold " +
                   std::to_string(kf_count) + ", " + std::to_string(zone_count) + " and " +
                   std::to_string(largest) + " bytes");
  }
  ZM_ASSIGN_OR_RETURN(impl->dense, DenseDecoder::Create(m.camera));
  return std::unique_ptr<MapDb>(new MapDb(std::move(impl)));
}

const MapMetadata& MapDb::metadata() const { return impl_->meta; }

Result<std::vector<KeyframeMeta>> MapDb::Keyframes() const {
  impl_->CountMetadataRead();
  return ReadKeyframes(impl_->db.get(), impl_->keyframes.get());
}

Result<std::vector<LinkRecord>> MapDb::Links() const {
  impl_->CountMetadataRead();
  return ReadLinks(impl_->db.get(), impl_->links.get());
}

Result<std::vector<ZoneRecord>> MapDb::Zones() const {
  impl_->CountMetadataRead();
  std::vector<ZoneRecord> out;
  const auto row = [&](sqlite3_stmt* s) -> Status {
    ZoneRecord z;
    z.id = ZoneId{sqlite3_column_int(s, 0)};
    const auto* name = reinterpret_cast<const char*>(sqlite3_column_text(s, 1));
    const auto* kind = reinterpret_cast<const char*>(sqlite3_column_text(s, 2));
    z.name = name != nullptr ? name : "";
    z.kind = kind != nullptr ? kind : "";
    z.floor = sqlite3_column_int(s, 3);
    z.z_min_m = sqlite3_column_double(s, 4);
    z.z_max_m = sqlite3_column_double(s, 5);
    const int bytes = sqlite3_column_bytes(s, 6);
    if (bytes % 16 != 0) {
      return Corrupt("zone " + std::to_string(z.id.value) + " (" + z.name + "): polygon blob of " +
                     std::to_string(bytes) + " bytes is not a whole number of (x, y) float64 pairs");
    }
    z.polygon.resize(static_cast<std::size_t>(bytes / 16));
    if (bytes > 0)
      std::memcpy(z.polygon.data(), sqlite3_column_blob(s, 6), static_cast<std::size_t>(bytes));
    if (z.id.value != static_cast<std::int32_t>(out.size())) {
      return Corrupt(impl_->path + ": zone ids are not dense: found zone " +
                     std::to_string(z.id.value) + " at position " + std::to_string(out.size()));
    }
    out.push_back(std::move(z));
    return Status::Ok();
  };
  ZM_RETURN_IF_ERROR(ForEachRow(impl_->db.get(), impl_->zones.get(), "reading table zone", row));
  return out;
}

Result<std::vector<ZoneMember>> MapDb::ZoneMembers() const {
  impl_->CountMetadataRead();
  std::vector<ZoneMember> out;
  ZM_RETURN_IF_ERROR(ForEachRow(
      impl_->db.get(), impl_->all_members.get(), "reading table zone_member", [&](sqlite3_stmt* s) {
        out.push_back(
            ZoneMember{ZoneId{sqlite3_column_int(s, 0)}, KeyframeId{sqlite3_column_int64(s, 1)}});
        return Status::Ok();
      }));
  return out;
}

Result<std::vector<std::uint32_t>> MapDb::ZoneSizes() const {
  impl_->CountMetadataRead();
  std::vector<std::uint32_t> out(impl_->meta.zone_count, 0);
  const auto row = [&](sqlite3_stmt* s) -> Status {
    const auto zone = sqlite3_column_int64(s, 0);
    if (zone < 0 || static_cast<std::uint64_t>(zone) >= out.size()) {
      return Corrupt(impl_->path + ": zone_member lists zone " + std::to_string(zone) +
                     ", but the map has " + std::to_string(out.size()) + " zones");
    }
    out[static_cast<std::size_t>(zone)] = static_cast<std::uint32_t>(sqlite3_column_int64(s, 1));
    return Status::Ok();
  };
  ZM_RETURN_IF_ERROR(
      ForEachRow(impl_->db.get(), impl_->zone_sizes.get(), "reading table zone_member", row));
  return out;
}

Result<RecordedWorkingMemory> MapDb::LastWorkingMemory() const {
  // Read once at start-up, so prepared here rather than at Open (the table is optional).
  sqlite3* db = impl_->db.get();
  const std::string& path = impl_->path;
  impl_->CountMetadataRead();
  ZM_ASSIGN_OR_RETURN(sqlite::Stmt rule_stmt,
                      PrepareOn(db, path, "meta", "SELECT value FROM meta WHERE key='last_wm_rule'"));
  ZM_ASSIGN_OR_RETURN(
      sqlite::Stmt all_stmt,
      PrepareOn(db, path, "meta", "SELECT value FROM meta WHERE key='last_wm_every_node'"));
  RecordedWorkingMemory out;
  bool recorded = false;
  int rc = sqlite3_step(rule_stmt.get());
  if (rc == SQLITE_ROW) {
    const auto* t = reinterpret_cast<const char*>(sqlite3_column_text(rule_stmt.get(), 0));
    recorded = true;
    out.rule = t != nullptr ? t : "";
  } else if (rc != SQLITE_DONE) {
    return FromSqlite(rc, db, path + ": reading meta last_wm_rule");
  }
  if (!recorded) {
    if (impl_->meta.source.rfind("rtabmap:", 0) == 0) {
      return FailedPrecondition(
          path + " was imported from RTAB-Map before zonemap recorded a map's last working "
                 "memory (Node.time_enter >= the last Info.time_enter); re-import it with "
                 "`zonemap import-rtabmap`, or set policy.basic.init_wm_with_all_nodes = true");
    }
    return out;  // built without memory management: every node
  }
  rc = sqlite3_step(all_stmt.get());
  if (rc == SQLITE_ROW && sqlite3_column_int(all_stmt.get(), 0) == 1) return out;  // every node
  if (rc != SQLITE_ROW && rc != SQLITE_DONE) {
    return FromSqlite(rc, db, path + ": reading meta last_wm_every_node");
  }
  out.every_node = false;
  ZM_ASSIGN_OR_RETURN(const bool has_table, sqlite::TableExists(db, "last_wm"));
  if (!has_table) return Corrupt(path + ": meta last_wm_rule is set but table last_wm is missing");
  impl_->CountMetadataRead();
  ZM_ASSIGN_OR_RETURN(sqlite::Stmt ids,
                      PrepareOn(db, path, "last_wm",
                                "SELECT l.keyframe_id, k.id FROM last_wm AS l LEFT JOIN keyframe "
                                "AS k ON k.id = l.keyframe_id ORDER BY l.keyframe_id"));
  ZM_RETURN_IF_ERROR(
      ForEachRow(db, ids.get(), path + ": reading table last_wm", [&](sqlite3_stmt* s) {
        const KeyframeId id{sqlite3_column_int64(s, 0)};
        if (sqlite3_column_type(s, 1) == SQLITE_NULL) {
          return Corrupt(path + ": table last_wm names keyframe " + std::to_string(id.value) +
                         ", which is not in the map");
        }
        out.ids.push_back(id);
        return Status::Ok();
      }));
  return out;
}

Result<LoadStats> MapDb::LoadKeyframes(std::span<const KeyframeId> ids, Arena& arena,
                                       LoadSink& sink) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.RefuseWhileZoneLoad("loading keyframes"));
  sqlite3* db = im.db.get();
  LoadStats st;
  // RTAB-Map's retrieval (basic-baseline.md §5, §11): per node its Node row, its features, its
  // links and its calibration, each one statement outside any transaction (autocommit: one
  // transaction each). Here: the keyframe row, the payload, the links of both directions and
  // the camera rows of meta (a zonemap map has no GlobalDescriptor table). Only the payload is
  // kept; the rest is read and counted, as the cost of retrieving a node the RTAB-Map way.
  for (const KeyframeId id : ids) {
    if (!sink.Wants(id)) {
      ++st.skipped;
      continue;
    }
    im.Count(st, 1, 0, 1);
    ZM_RETURN_IF_ERROR(im.ReadNodeRow(id));

    sqlite3_stmt* s = im.payload_point.get();
    std::optional<SlotIndex> slot;
    int bytes = 0;
    StreamedChecksum checksum(im.options.verify_checksums);
    {
      // Reset at the end of this scope, ending its transaction before the next statement.
      StmtReset reset(s);
      sqlite3_bind_int64(s, 1, id.value);
      im.Count(st, 1, 0, 1);
      const int rc = sqlite3_step(s);
      if (rc == SQLITE_DONE) return NotFound(Kf(id) + " has no payload row in " + im.path);
      if (rc != SQLITE_ROW) return FromSqlite(rc, db, "reading the payload of " + Kf(id));
      bytes = sqlite3_column_bytes(s, 0);
      if (bytes < 0 || static_cast<std::uint64_t>(bytes) > arena.slot_bytes()) {
        return OutOfRange(Kf(id) + " in " + im.path + ": payload blob of " + std::to_string(bytes) +
                          " bytes is larger than the arena slot of " +
                          std::to_string(arena.slot_bytes()) + " bytes");
      }
      const void* src = sqlite3_column_blob(s, 0);
      if (src == nullptr && bytes > 0) {
        return ResourceExhausted("SQLite could not materialise the payload of " + Kf(id) + " (" +
                                 std::to_string(bytes) + " bytes)");
      }
      slot = arena.TryAcquire();
      if (!slot) {
        return ResourceExhausted("arena full (" + std::to_string(arena.capacity()) +
                                 " slots) loading " + Kf(id) + " after " +
                                 std::to_string(st.keyframes) + " keyframes of this call");
      }
      std::span<std::byte> dst = arena.Slot(*slot).first(static_cast<std::size_t>(bytes));
      for (std::size_t done = 0; done < dst.size();) {
        const std::size_t n = std::min(done == 0 ? kPayloadHeaderBytes : kCopyChunkBytes, dst.size() - done);
        std::memcpy(dst.data() + done, static_cast<const std::byte*>(src) + done, n);
        checksum.Feed(dst.first(done + n), done);
        done += n;
      }
    }
    auto landed = im.Land(id, arena.Slot(*slot), static_cast<std::size_t>(bytes), checksum);
    Status valid = landed.ok() ? Status::Ok() : landed.status();
    if (valid.ok()) {
      im.Count(st, 1, 0, 1);
      valid = im.ReadLinksOf(id, nullptr);
    }
    if (valid.ok()) {
      im.Count(st, 1, 0, 1);
      valid = im.ReadCalibration(id);
    }
    if (!valid.ok()) {
      arena.Release(*slot);
      return valid;
    }
    sink.Loaded(id, *slot, *landed);
    im.CountBytes(st, static_cast<std::uint32_t>(bytes));
  }
  st.ms = MsSince(t0);
  return st;
}

Result<LoadStats> MapDb::ReadGraphNodes(std::span<const KeyframeId> ids, GraphNodeSink* sink) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.RefuseWhileZoneLoad("reading graph nodes"));
  sqlite3* db = im.db.get();
  LoadStats st;
  // Memory::getNeighborsId per admitted long-term-memory node: getWeight, then loadLinks
  // (basic-baseline.md §3.1), each its own autocommit statement.
  for (const KeyframeId id : ids) {
    sqlite3_stmt* w = im.weight_point.get();
    {
      StmtReset reset(w);
      sqlite3_bind_int64(w, 1, id.value);
      im.Count(st, 1, 0, 1);
      const int rc = sqlite3_step(w);
      if (rc == SQLITE_DONE) return NotFound(Kf(id) + " is not in " + im.path);
      if (rc != SQLITE_ROW) return FromSqlite(rc, db, "reading the weight of " + Kf(id));
      if (sink != nullptr) sink->Node(id, sqlite3_column_int(w, 0));
    }
    im.Count(st, 1, 0, 1);
    ZM_RETURN_IF_ERROR(im.ReadLinksOf(id, sink));
  }
  st.ms = MsSince(t0);
  return st;
}

Result<std::optional<std::vector<std::byte>>> MapDb::VocabularyBlob() const {
  // Read once at start-up (and by tools), so prepared here rather than at Open.
  if (impl_->schema_version < kMapDbSchemaVersion) return std::optional<std::vector<std::byte>>{};
  sqlite3* db = impl_->db.get();
  impl_->CountMetadataRead();
  ZM_ASSIGN_OR_RETURN(sqlite::Stmt s, PrepareOn(db, impl_->path, "vocabulary",
                                                "SELECT blob FROM vocabulary WHERE id=1"));
  const int rc = sqlite3_step(s.get());
  if (rc == SQLITE_DONE) return std::optional<std::vector<std::byte>>{};
  if (rc != SQLITE_ROW) return FromSqlite(rc, db, impl_->path + ": reading table vocabulary");
  if (sqlite3_column_type(s.get(), 0) != SQLITE_BLOB) {
    return Corrupt(impl_->path + ": table vocabulary holds a " +
                   (sqlite3_column_type(s.get(), 0) == SQLITE_NULL ? std::string("NULL")
                                                                   : std::string("non-blob")) +
                   " value, not a vocabulary blob");
  }
  const auto* bytes = static_cast<const std::byte*>(sqlite3_column_blob(s.get(), 0));
  const int n = sqlite3_column_bytes(s.get(), 0);
  if (bytes == nullptr && n > 0) {
    return ResourceExhausted("SQLite could not materialise the vocabulary of " + impl_->path +
                             " (" + std::to_string(n) + " bytes)");
  }
  return std::optional<std::vector<std::byte>>(std::vector<std::byte>(bytes, bytes + n));
}

int MapDb::schema_version() const { return impl_->schema_version; }

std::uint64_t MapDb::total_queries() const { return impl_->total_queries; }
std::uint64_t MapDb::total_blob_reads() const { return impl_->total_blob_reads; }
std::uint64_t MapDb::total_transactions() const { return impl_->total_transactions; }
std::uint64_t MapDb::total_bytes_read() const { return impl_->total_bytes; }

}  // namespace zm
