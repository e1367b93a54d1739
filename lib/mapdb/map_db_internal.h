// Internal to lib/mapdb: what the map database's reader (map_db.cc), its zone loads
// (map_db_zone_load.cc) and its writer (map_db_writer.cc) share -- the schema, the row helpers,
// the streamed checksum and the reader's state. Not installed, not included outside lib/mapdb.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/elapsed.h"
#include "mapdb/dense_codec.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "mapdb/sqlite_util.h"

namespace zm::mapdb_detail {

inline constexpr const char* kTables[] = {"keyframe", "payload", "link", "zone", "zone_member", "meta"};

// The vocabulary table (schema version 2; a new map gets it with the rest of the schema, a
// version 1 map when a writer opens it): at most one row, the bytes of lib/localization's
// Vocabulary::ToBlob (this module stores them; lib/localization validates them).
inline constexpr const char* kVocabularyTableSql =
    "CREATE TABLE IF NOT EXISTS vocabulary(id INTEGER PRIMARY KEY CHECK(id = 1), "
    "blob BLOB NOT NULL);";

inline constexpr const char* kSchemaSql = R"sql(
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

inline constexpr int kPoseBlobBytes = 12 * 8;
inline constexpr int kInformationBlobBytes = 36 * 8;

[[nodiscard]] std::string Kf(KeyframeId id);
void PoseToDoubles(const Pose3& p, double out[12]);
// False when the column is not a 12-float64 blob.
[[nodiscard]] bool PoseFromColumn(sqlite3_stmt* s, int col, Pose3& out);

// Payload bytes are copied into a slot in pieces of this size and each piece's share of the
// body checksum is computed right after it lands, while it is still in the L2 cache: the body is
// then read once from memory instead of twice (copy, then checksum). Issue 14's profile.
inline constexpr std::size_t kCopyChunkBytes = 256 * 1024;

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
// MapDbWriter::OpenExisting. Errors name the file, the version or the table. Stores the file's
// version (kMapDbSchemaVersion or kMapDbSchemaVersionNoVocabulary) in *version.
[[nodiscard]] Status CheckSchema(sqlite3* db, const std::string& path, int* version);
// Prepares `sql`, turning failure into an error that names the file and the table.
[[nodiscard]] Result<sqlite::Stmt> PrepareOn(sqlite3* db, const std::string& path,
                                             std::string_view table, std::string_view sql);
[[nodiscard]] Result<std::vector<KeyframeMeta>> ReadKeyframes(sqlite3* db, sqlite3_stmt* s);
// One link row (from_id, to_id, type, transform, information) into `l`; builds a message only
// on error, so reading a row allocates nothing.
[[nodiscard]] Status LinkFromRow(sqlite3_stmt* s, LinkRecord& l);
[[nodiscard]] Result<std::vector<LinkRecord>> ReadLinks(sqlite3* db, sqlite3_stmt* s);

}  // namespace zm::mapdb_detail

namespace zm {

// The shared names the mapdb .cc files use unqualified, listed once here rather than in each
// file (this header is private to lib/mapdb, so nothing else sees them).
using mapdb_detail::CheckSchema;
using mapdb_detail::kCopyChunkBytes;
using mapdb_detail::Kf;
using mapdb_detail::kInformationBlobBytes;
using mapdb_detail::kPoseBlobBytes;
using mapdb_detail::kSchemaSql;
using mapdb_detail::kVocabularyTableSql;
using mapdb_detail::LinkFromRow;
using mapdb_detail::PoseFromColumn;
using mapdb_detail::PoseToDoubles;
using mapdb_detail::PrepareOn;
using mapdb_detail::ReadKeyframes;
using mapdb_detail::ReadLinks;
using mapdb_detail::StreamedChecksum;
using sqlite::ForEachRow;
using sqlite::FromSqlite;
using sqlite::Prepare;
using sqlite::StmtReset;

// The reader's state: the connection, every prepared statement, the counters and the zone load
// in flight. Its zone-load methods are in map_db_zone_load.cc, the rest in map_db.cc.
struct MapDb::Impl {
  int schema_version = 0;  // of the file: kMapDbSchemaVersion or ..NoVocabulary
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
                  const StreamedChecksum& checksum) const;

  // Validates the payload that now sits at the start of `slot` (`bytes` long) and decodes its
  // dense part into the slot; returns the keyframe's resident bytes.
  Result<std::uint32_t> Land(KeyframeId id, std::span<std::byte> slot, std::size_t bytes,
                             const StreamedChecksum& checksum) const;

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
  Status EndZoneLoad(bool commit_it);

  // Steps zone_members to the next member: row_ready says whether there is one.
  Status Advance();

  Status MissingPayload(int brc, KeyframeId id) const;

  // Positions the blob handle on `id`'s payload (opened once per load, then moved along the
  // payload table: no statement compile, no buffer).
  Status PositionBlob(KeyframeId id);

  // The body of one step (see StepZoneLoad); on error the caller ends the load.
  Status Step(const LoadBudget& budget, LoadStats& st);

  // RTAB-Map's Node row of `id`: read and checked like Keyframes() does, then dropped.
  Status ReadNodeRow(KeyframeId id);

  // Every link of `id` (both directions), each checked and handed to `sink` when there is one.
  Status ReadLinksOf(KeyframeId id, GraphNodeSink* sink);

  // The camera rows of meta (a zonemap map has one calibration for every keyframe).
  Status ReadCalibration(KeyframeId id);
};

}  // namespace zm
