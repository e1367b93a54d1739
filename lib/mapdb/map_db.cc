// The map database over SQLite (see map_db.h and docs/mapdb.md for the schema).
//
// Schema version 1:
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
//     before; readers that predate it ignore them. So the schema version stays 1.
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
//     and the sink is told the keyframe's resident bytes (what the slot then holds);
//   - once warm, the load paths make no allocation through operator new (errors aside).
#include "mapdb/map_db.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <chrono>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string_view>

#include "mapdb/dense_codec.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/sqlite_util.h"

namespace zm {
namespace {

using sqlite::FromSqlite;
using sqlite::Prepare;
using sqlite::StmtReset;

constexpr const char* kTables[] = {"keyframe", "payload", "link", "zone", "zone_member", "meta"};

constexpr const char* kSchemaSql = R"sql(
CREATE TABLE keyframe(
  id INTEGER PRIMARY KEY,
  stamp REAL NOT NULL,
  pose BLOB NOT NULL,
  weight INTEGER NOT NULL,
  payload_bytes INTEGER NOT NULL);
CREATE TABLE payload(
  keyframe_id INTEGER PRIMARY KEY,
  blob BLOB NOT NULL);
CREATE TABLE link(
  from_id INTEGER NOT NULL,
  to_id INTEGER NOT NULL,
  type INTEGER NOT NULL,
  transform BLOB NOT NULL,
  information BLOB NOT NULL);
CREATE INDEX link_from ON link(from_id);
CREATE INDEX link_to ON link(to_id);
CREATE TABLE zone(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  kind TEXT NOT NULL,
  floor INTEGER NOT NULL,
  z_min REAL NOT NULL,
  z_max REAL NOT NULL,
  polygon BLOB NOT NULL);
CREATE TABLE zone_member(
  zone_id INTEGER NOT NULL,
  keyframe_id INTEGER NOT NULL,
  PRIMARY KEY(zone_id, keyframe_id)) WITHOUT ROWID;
CREATE TABLE meta(
  key TEXT PRIMARY KEY,
  value) WITHOUT ROWID;
CREATE TABLE last_wm(
  keyframe_id INTEGER PRIMARY KEY) WITHOUT ROWID;
)sql";

constexpr int kPoseBlobBytes = 12 * 8;
constexpr int kInformationBlobBytes = 36 * 8;

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

double Ms(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Payload bytes are copied into a slot in pieces of this size and each piece's share of the
// body checksum is computed right after it lands, while it is still in the L2 cache: the body is
// then read once from memory instead of twice (copy, then checksum). Issue 14's profile.
constexpr std::size_t kCopyChunkBytes = 256 * 1024;

// The body checksum of a payload computed piece by piece as its bytes land in a slot. Knows the
// payload's version (so the checksum) from the header, the first piece; a header of an unknown
// version computes nothing (DecodePayload refuses the version anyway).
class StreamedChecksum {
 public:
  explicit StreamedChecksum(bool enabled) : enabled_(enabled) {}
  // `landed` = the slot's bytes so far, [0, done); the new piece is [from, done).
  void Feed(std::span<const std::byte> landed, std::size_t from) {
    if (!enabled_) return;
    if (from < kPayloadHeaderBytes) {
      if (landed.size() < kPayloadHeaderBytes) return;  // header incomplete (then: too short)
      std::uint16_t version = 0;
      std::memcpy(&version, landed.data() + offsetof(PayloadHeader, version), sizeof version);
      known_ = version == kPayloadVersion || version == kPayloadVersionZlibCrc;
      version_ = version;
      from = kPayloadHeaderBytes;
    }
    if (known_ && landed.size() > from) {
      crc_ = PayloadBodyChecksum(version_, landed.subspan(from), crc_);
    }
  }
  // The checksum to hand DecodePayload, or nullptr (it then computes one itself, if asked).
  [[nodiscard]] const std::uint32_t* value() const { return known_ ? &crc_ : nullptr; }

 private:
  bool enabled_;
  bool known_ = false;
  std::uint16_t version_ = 0;
  std::uint32_t crc_ = 0;
};

// Checks the schema version and that every table exists; shared by the reader and
// MapDbWriter::OpenExisting. Errors name the file, the version or the table.
Status CheckSchema(sqlite3* db, const std::string& path) {
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
  if (version != kMapDbSchemaVersion) {
    ZM_ASSIGN_OR_RETURN(const bool has_keyframe, sqlite::TableExists(db, "keyframe"));
    if (version == 0 && !has_keyframe) {
      return FailedPrecondition(path + " is not a zonemap map database (schema version 0, no table "
                                "keyframe)");
    }
    return FailedPrecondition(path + " has map schema version " + std::to_string(version) +
                              "; this build reads version " + std::to_string(kMapDbSchemaVersion));
  }
  for (const char* t : kTables) {
    ZM_ASSIGN_OR_RETURN(const bool exists, sqlite::TableExists(db, t));
    if (!exists) {
      return Corrupt(path + ": missing table " + t + " (schema version " +
                     std::to_string(kMapDbSchemaVersion) +
                     " needs keyframe, payload, link, zone, zone_member, meta)");
    }
  }
  return Status::Ok();
}

// Prepares `sql`, turning failure into an error that names the file and the table.
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
  StmtReset reset(s);
  std::vector<KeyframeMeta> out;
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
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
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, "reading table keyframe");
  return out;
}

// One link row (from_id, to_id, type, transform, information) into `l`; builds a message only
// on error, so reading a row allocates nothing.
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
  StmtReset reset(s);
  std::vector<LinkRecord> out;
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
    LinkRecord l;
    ZM_RETURN_IF_ERROR(LinkFromRow(s, l));
    out.push_back(l);
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, "reading table link");
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Reader
// ---------------------------------------------------------------------------------------------

struct MapDb::Impl {
  std::string path;
  MapDbOptions options;
  sqlite::Db db;  // declared first: destroyed last, after every statement and blob handle
  sqlite::Stmt begin, commit, rollback;
  sqlite::Stmt zone_members;   // keyframe ids of one zone, stepping over zone_member's PK
  sqlite::Stmt payload_point;  // one payload by keyframe id (the per-keyframe path)
  sqlite::Stmt node_point;     // one keyframe row by id (RTAB-Map's Node)
  sqlite::Stmt weight_point;   // one keyframe's weight by id (the graph search's getWeight)
  sqlite::Stmt links_of;       // every link of one keyframe, both directions (loadLinks)
  sqlite::Stmt calibration;    // the camera rows of meta (RTAB-Map's Data.calibration)
  sqlite::Stmt keyframes, links, zones, all_members, zone_sizes;
  MapMetadata meta;
  std::unique_ptr<DenseDecoder> dense;  // decodes dense payloads into their slots
  std::uint64_t total_queries = 0;
  std::uint64_t total_blob_reads = 0;
  std::uint64_t total_transactions = 0;
  std::uint64_t total_bytes = 0;

  // The zone load in flight (zone == kNoZone: none). Between steps it holds the transaction,
  // zone_members positioned on the next member to handle (row_ready) and the blob handle.
  struct Cursor {
    ZoneId zone = kNoZone;
    Arena* arena = nullptr;
    LoadSink* sink = nullptr;
    bool row_ready = false;
    std::uint32_t delivered = 0;  // keyframes of this load so far (for messages)
  } cursor;
  sqlite::Blob blob;  // after db: closed before the connection

  // Validates the payload that now sits in `slot` (exactly `bytes` long) for keyframe `id`,
  // with its body checksum as computed while it landed.
  Status Validate(KeyframeId id, std::span<const std::byte> blob_bytes,
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

  // Validates the payload that now sits at the start of `slot` (`bytes` long) and decodes its
  // dense part into the slot; returns the keyframe's resident bytes.
  Result<std::uint32_t> Land(KeyframeId id, std::span<std::byte> slot, std::size_t bytes,
                             const StreamedChecksum& checksum) const {
    ZM_RETURN_IF_ERROR(Validate(id, slot.first(bytes), checksum));
    auto resident = dense->DecodeInSlot(slot, bytes);
    if (!resident.ok()) return resident.status().Annotate(Kf(id) + " in " + path);
    return resident;
  }

  void Count(LoadStats& st, std::uint32_t queries, std::uint32_t blob_reads,
             std::uint32_t transactions) {
    st.queries += queries;
    st.blob_reads += blob_reads;
    st.transactions += transactions;
    total_queries += queries;
    total_blob_reads += blob_reads;
    total_transactions += transactions;
  }
  void CountBytes(LoadStats& st, std::uint32_t bytes) {
    ++st.keyframes;
    st.bytes += bytes;
    total_bytes += bytes;
  }

  // A metadata statement run outside any transaction: one query, one transaction.
  void CountMetadataRead() {
    ++total_queries;
    ++total_transactions;
  }

  Status RefuseWhileZoneLoad(std::string_view what) const {
    if (cursor.zone == kNoZone) return Status::Ok();
    return FailedPrecondition(std::string(what) + " refused: the load of zone " +
                              std::to_string(cursor.zone.value) + " from " + path +
                              " is in flight (one load at a time; step it to the end or abort it)");
  }

  // Ends the zone load in flight: statement reset, blob closed, transaction ended (COMMIT when
  // `commit`, else ROLLBACK; a read transaction changes nothing either way). Returns the
  // COMMIT's error, if any.
  Status EndZoneLoad(bool commit_it) {
    sqlite3_stmt* members = zone_members.get();
    sqlite3_reset(members);
    sqlite3_clear_bindings(members);
    blob.reset();
    cursor = Cursor{};
    sqlite3_stmt* end = commit_it ? commit.get() : rollback.get();
    const int rc = sqlite3_step(end);
    sqlite3_reset(end);
    if (commit_it && rc != SQLITE_DONE) {
      // A failed COMMIT leaves the transaction open: roll it back so the next load can begin.
      const Status st = FromSqlite(rc, db.get(), "COMMIT");
      sqlite3_step(rollback.get());
      sqlite3_reset(rollback.get());
      return st;
    }
    return Status::Ok();
  }

  // Steps zone_members to the next member: row_ready says whether there is one.
  Status Advance() {
    const int rc = sqlite3_step(zone_members.get());
    cursor.row_ready = rc == SQLITE_ROW;
    if (rc == SQLITE_ROW || rc == SQLITE_DONE) return Status::Ok();
    return FromSqlite(rc, db.get(), "stepping the members of zone " + std::to_string(cursor.zone.value));
  }

  Status MissingPayload(int brc, KeyframeId id) const {
    const std::string zone = std::to_string(cursor.zone.value);
    if ((brc & 0xff) == SQLITE_NOMEM) {  // SQLite's heap limit, not a missing row
      return ResourceExhausted(Kf(id) + " of zone " + zone + " in " + path +
                               ": SQLite out of memory opening its payload (" + sqlite3_errstr(brc) + ")");
    }
    return Corrupt(Kf(id) + " of zone " + zone + " in " + path + ": no readable payload row (" +
                   sqlite3_errstr(brc) + ": " + sqlite3_errmsg(db.get()) + ")");
  }

  // Positions the blob handle on `id`'s payload (opened once per load, then moved along the
  // payload table: no statement compile, no buffer).
  Status PositionBlob(KeyframeId id) {
    if (!blob) {
      sqlite3_blob* raw = nullptr;
      const int brc = sqlite3_blob_open(db.get(), "main", "payload", "blob", id.value, 0, &raw);
      blob.reset(raw);
      if (brc != SQLITE_OK) return MissingPayload(brc, id);
      return Status::Ok();
    }
    const int brc = sqlite3_blob_reopen(blob.get(), id.value);
    return brc == SQLITE_OK ? Status::Ok() : MissingPayload(brc, id);
  }

  // The body of one step (see StepZoneLoad); on error the caller ends the load.
  Status Step(const LoadBudget& budget, LoadStats& st) {
    Arena& arena = *cursor.arena;
    LoadSink& sink = *cursor.sink;
    const bool timed = budget.deadline != std::chrono::steady_clock::time_point::max();
    std::uint32_t loaded = 0;
    std::uint64_t bytes_loaded = 0;
    while (cursor.row_ready) {
      // Count and time are checked before Wants(), so a member is asked once unless the byte
      // budget (which needs the blob's size) stops the step.
      if (loaded > 0 && (loaded >= budget.max_keyframes ||
                         (timed && std::chrono::steady_clock::now() >= budget.deadline))) {
        return Status::Ok();
      }
      const KeyframeId id{sqlite3_column_int64(zone_members.get(), 0)};
      if (!sink.Wants(id)) {
        ++st.skipped;
        ZM_RETURN_IF_ERROR(Advance());
        continue;
      }
      ZM_RETURN_IF_ERROR(PositionBlob(id));
      const int bytes = sqlite3_blob_bytes(blob.get());
      if (bytes < 0 || static_cast<std::uint64_t>(bytes) > arena.slot_bytes()) {
        return OutOfRange(Kf(id) + " in " + path + ": payload blob of " + std::to_string(bytes) +
                          " bytes is larger than the arena slot of " +
                          std::to_string(arena.slot_bytes()) + " bytes");
      }
      if (loaded > 0 && bytes_loaded + static_cast<std::uint64_t>(bytes) > budget.max_bytes) {
        return Status::Ok();  // the row stays ready: the next step starts with this member
      }
      const auto slot = arena.TryAcquire();
      if (!slot) {
        return ResourceExhausted("arena full (" + std::to_string(arena.capacity()) +
                                 " slots) loading " + Kf(id) + " of zone " +
                                 std::to_string(cursor.zone.value) + " after " +
                                 std::to_string(cursor.delivered) + " keyframes of this zone");
      }
      std::span<std::byte> dst = arena.Slot(*slot).first(static_cast<std::size_t>(bytes));
      Count(st, 0, 1, 0);
      StreamedChecksum checksum(options.verify_checksums);
      int rrc = SQLITE_OK;
      // The header first (it says which checksum), then the body piece by piece.
      for (std::size_t done = 0; done < dst.size() && rrc == SQLITE_OK;) {
        const std::size_t n = std::min(done == 0 ? kPayloadHeaderBytes : kCopyChunkBytes, dst.size() - done);
        rrc = sqlite3_blob_read(blob.get(), dst.data() + done, static_cast<int>(n), static_cast<int>(done));
        checksum.Feed(dst.first(done + n), done);
        done += n;
      }
      auto landed = rrc == SQLITE_OK
                        ? Land(id, arena.Slot(*slot), static_cast<std::size_t>(bytes), checksum)
                        : Result<std::uint32_t>(FromSqlite(rrc, db.get(), "reading the payload of " + Kf(id)));
      if (!landed.ok()) {
        arena.Release(*slot);
        return landed.status();
      }
      sink.Loaded(id, *slot, *landed);
      CountBytes(st, static_cast<std::uint32_t>(bytes));
      ++loaded;
      ++cursor.delivered;
      bytes_loaded += static_cast<std::uint64_t>(bytes);
      ZM_RETURN_IF_ERROR(Advance());
    }
    return Status::Ok();
  }

  // RTAB-Map's Node row of `id`: read and checked like Keyframes() does, then dropped.
  Status ReadNodeRow(KeyframeId id) {
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

  // Every link of `id` (both directions), each checked and handed to `sink` when there is one.
  Status ReadLinksOf(KeyframeId id, GraphNodeSink* sink) {
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

  // The camera rows of meta (a zonemap map has one calibration for every keyframe).
  Status ReadCalibration(KeyframeId id) {
    sqlite3_stmt* s = calibration.get();
    StmtReset reset(s);
    int rc;
    while ((rc = sqlite3_step(s)) == SQLITE_ROW) (void)sqlite3_column_double(s, 1);
    if (rc != SQLITE_DONE) {
      return FromSqlite(rc, db.get(), "reading the calibration for " + Kf(id));
    }
    return Status::Ok();
  }
};

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
  ZM_RETURN_IF_ERROR(CheckSchema(db, path));
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
  sqlite3_stmt* s = impl_->zones.get();
  StmtReset reset(s);
  std::vector<ZoneRecord> out;
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
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
    if (bytes > 0) std::memcpy(z.polygon.data(), sqlite3_column_blob(s, 6), static_cast<std::size_t>(bytes));
    if (z.id.value != static_cast<std::int32_t>(out.size())) {
      return Corrupt(impl_->path + ": zone ids are not dense: found zone " +
                     std::to_string(z.id.value) + " at position " + std::to_string(out.size()));
    }
    out.push_back(std::move(z));
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, impl_->db.get(), "reading table zone");
  return out;
}

Result<std::vector<ZoneMember>> MapDb::ZoneMembers() const {
  impl_->CountMetadataRead();
  sqlite3_stmt* s = impl_->all_members.get();
  StmtReset reset(s);
  std::vector<ZoneMember> out;
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
    out.push_back(ZoneMember{ZoneId{sqlite3_column_int(s, 0)}, KeyframeId{sqlite3_column_int64(s, 1)}});
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, impl_->db.get(), "reading table zone_member");
  return out;
}

Result<std::vector<std::uint32_t>> MapDb::ZoneSizes() const {
  impl_->CountMetadataRead();
  sqlite3_stmt* s = impl_->zone_sizes.get();
  StmtReset reset(s);
  std::vector<std::uint32_t> out(impl_->meta.zone_count, 0);
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
    const auto zone = sqlite3_column_int64(s, 0);
    if (zone < 0 || static_cast<std::uint64_t>(zone) >= out.size()) {
      return Corrupt(impl_->path + ": zone_member lists zone " + std::to_string(zone) +
                     ", but the map has " + std::to_string(out.size()) + " zones");
    }
    out[static_cast<std::size_t>(zone)] = static_cast<std::uint32_t>(sqlite3_column_int64(s, 1));
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, impl_->db.get(), "reading table zone_member");
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
  while ((rc = sqlite3_step(ids.get())) == SQLITE_ROW) {
    const KeyframeId id{sqlite3_column_int64(ids.get(), 0)};
    if (sqlite3_column_type(ids.get(), 1) == SQLITE_NULL) {
      return Corrupt(path + ": table last_wm names keyframe " + std::to_string(id.value) +
                     ", which is not in the map");
    }
    out.ids.push_back(id);
  }
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, path + ": reading table last_wm");
  return out;
}

Result<LoadStats> MapDb::BeginZoneLoad(ZoneId zone, Arena& arena, LoadSink& sink) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& im = *impl_;
  ZM_RETURN_IF_ERROR(im.RefuseWhileZoneLoad("loading zone " + std::to_string(zone.value)));
  if (zone.value < 0 || static_cast<std::uint64_t>(zone.value) >= im.meta.zone_count) {
    return NotFound("zone " + std::to_string(zone.value) + " is not in " + im.path + " (" +
                    std::to_string(im.meta.zone_count) + " zones)");
  }
  sqlite3* db = im.db.get();
  LoadStats st;
  const int rc = sqlite3_step(im.begin.get());
  sqlite3_reset(im.begin.get());
  if (rc != SQLITE_DONE) return FromSqlite(rc, db, "BEGIN for zone " + std::to_string(zone.value));
  im.cursor.zone = zone;
  im.cursor.arena = &arena;
  im.cursor.sink = &sink;
  im.Count(st, 1, 0, 1);
  // The first step of the member statement takes the read lock: from here on the load sees
  // one state of the map, however many steps it takes.
  sqlite3_bind_int(im.zone_members.get(), 1, zone.value);
  Status status = im.Advance();
  if (!status.ok()) {
    (void)im.EndZoneLoad(/*commit_it=*/false);
    return status;
  }
  st.ms = Ms(t0);
  return st;
}

Result<ZoneLoadStep> MapDb::StepZoneLoad(const LoadBudget& budget) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& im = *impl_;
  if (im.cursor.zone == kNoZone) {
    return FailedPrecondition("no zone load in flight on " + im.path + " (BeginZoneLoad first)");
  }
  ZoneLoadStep step;
  Status status = im.Step(budget, step.stats);
  if (status.ok() && !im.cursor.row_ready) {
    status = im.EndZoneLoad(/*commit_it=*/true);
    step.done = true;
  }
  if (!status.ok()) {
    if (im.cursor.zone != kNoZone) (void)im.EndZoneLoad(/*commit_it=*/false);
    return status;
  }
  step.stats.ms = Ms(t0);
  return step;
}

void MapDb::AbortZoneLoad() {
  if (impl_->cursor.zone != kNoZone) (void)impl_->EndZoneLoad(/*commit_it=*/false);
}

ZoneId MapDb::ZoneLoadInFlight() const { return impl_->cursor.zone; }

Result<LoadStats> MapDb::LoadZone(ZoneId zone, Arena& arena, LoadSink& sink) {
  const auto t0 = std::chrono::steady_clock::now();
  ZM_ASSIGN_OR_RETURN(LoadStats st, BeginZoneLoad(zone, arena, sink));
  ZM_ASSIGN_OR_RETURN(const ZoneLoadStep step, StepZoneLoad(LoadBudget{}));
  assert(step.done && "an unlimited step finishes the load");
  st += step.stats;
  st.ms = Ms(t0);
  return st;
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
  st.ms = Ms(t0);
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
  st.ms = Ms(t0);
  return st;
}

std::uint64_t MapDb::total_queries() const { return impl_->total_queries; }
std::uint64_t MapDb::total_blob_reads() const { return impl_->total_blob_reads; }
std::uint64_t MapDb::total_transactions() const { return impl_->total_transactions; }
std::uint64_t MapDb::total_bytes_read() const { return impl_->total_bytes; }

// ---------------------------------------------------------------------------------------------
// Writer
// ---------------------------------------------------------------------------------------------

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
        d, std::string("BEGIN;") + kSchemaSql + "PRAGMA user_version=" +
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
  ZM_RETURN_IF_ERROR(CheckSchema(db, path));
  ZM_RETURN_IF_ERROR(sqlite::Exec(db, "PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;",
                                  "configuring " + path));
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
