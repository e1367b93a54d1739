// The map database: keyframes, their payloads, the pose graph and the semantic zones, in one
// SQLite file. Writers (simulator, importer, zone annotation) use MapDbWriter; the run-time reads
// through MapDb, opened read-only with every statement prepared once at open.
//
// The hot path is the zone load: one read transaction, one prepared statement stepping over the
// zone-member index, each member's payload read by SQLite's incremental blob I/O straight into an
// arena slot (no buffer of ours; with the large pages MapDbWriter picks for large payloads,
// SQLite reads each overflow page with one pread straight into the slot), checked with the
// hardware CRC-32C, stopping with a clear error, never writing outside a slot, if a blob does not
// fit. It runs in one call (LoadZone) or time-sliced (BeginZoneLoad / StepZoneLoad /
// AbortZoneLoad: the same transaction held open across steps, keyframes delivered one at a
// time, each complete and validated before the sink hears of it).
//
// LoadKeyframes() is the per-node retrieval of the "basic" baseline and ReadGraphNodes() its
// graph-search point queries, both as real statements, each its own transaction, as RTAB-Map
// does them (basic-baseline.md §3.1, §5, §11). Every path counts its work in LoadStats the same
// way, so the I/O patterns can be compared.
//
// This module knows nothing of memory policies (docs/design.md): callers say which keyframes
// they want through a LoadSink and get told which slot each one landed in.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "arena/arena.h"
#include "common/ids.h"
#include "common/status.h"
#include "geometry/pose.h"

namespace zm {

// Bumped whenever the schema changes so that a reader of one version cannot read the other; a
// database of another version is refused at open. Not bumped by changes both ways can read: the
// page size (any is read), the link_to index (used when present), the payload version (carried
// by each payload, keyframe_payload.h).
//
// Version 2 (issue 26) adds the vocabulary table: a map's keyframes are scored through the
// vocabulary trained on them, and a build that predates it would localize such a map without
// it, so older builds refuse version 2 with their "has map schema version 2" line. This build
// reads version 1 as a map without a vocabulary; MapDbWriter::OpenExisting brings a version 1
// map to version 2 (adds the empty table) before writing to it; new maps are version 2.
inline constexpr int kMapDbSchemaVersion = 2;
inline constexpr int kMapDbSchemaVersionNoVocabulary = 1;

// RTAB-Map's Link.type values (basic-baseline.md §5), kept as-is on import: the one LinkKind
// (common/ids.h). The map database's code still says LinkType.
using LinkType = LinkKind;

struct KeyframeMeta {
  KeyframeId id;
  double stamp_s = 0.0;
  Pose3 pose = Pose3::Identity();  // map frame
  std::int32_t weight = 0;         // RTAB-Map weight (basic's transfer order); -1 intermediate
  std::uint32_t payload_bytes = 0;  // resident in a slot: the blob + what decoding adds
};

struct LinkRecord {
  KeyframeId from;
  KeyframeId to;
  LinkType type = LinkType::kNeighbor;
  Pose3 transform = Pose3::Identity();  // pose_to = pose_from * transform
  std::array<double, 36> information{};  // 6x6 row-major, (x y z roll pitch yaw)
};

struct ZoneRecord {
  ZoneId id;
  std::string name;   // unique
  std::string kind;   // room, corridor, lobby, ward, ...
  std::int32_t floor = 0;
  double z_min_m = -1e9;
  double z_max_m = 1e9;
  std::vector<std::array<double, 2>> polygon;  // outer ring, map frame metres, not repeated-closed
};

struct ZoneMember {
  ZoneId zone;
  KeyframeId keyframe;
};

struct CameraIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::uint32_t width = 0, height = 0;
};

struct MapMetadata {
  std::uint64_t keyframe_count = 0;
  std::uint64_t link_count = 0;
  std::uint64_t zone_count = 0;
  std::uint32_t largest_payload_bytes = 0;  // largest resident keyframe: slot_bytes >= this
  std::uint64_t total_payload_bytes = 0;
  std::uint32_t page_bytes = 0;  // SQLite page size of the file (PRAGMA page_size)
  CameraIntrinsics camera;
  std::string source;  // "sim hospital seed=1", "rtabmap:/path/file.db", ...
};

// What a load did, counted the same way on every path so I/O patterns compare (issue 17 §5).
// Times are wall-clock on a monotonic clock.
//   queries       SQL statements executed (each SELECT stepped from its start; BEGIN, COMMIT
//                 and ROLLBACK are not counted here, they are the transaction);
//   blob_reads    payloads read through an incremental blob handle (the zone load's way);
//   transactions  read transactions: each BEGIN..COMMIT, plus each statement executed outside
//                 one (SQLite's autocommit: one statement, one transaction).
// A zone load: 1 query, 1 blob read per keyframe read, 1 transaction. LoadKeyframes: 4 queries
// and 4 transactions per keyframe read. ReadGraphNodes: 2 queries, 2 transactions per node.
struct LoadStats {
  std::uint32_t keyframes = 0;     // payloads copied into slots
  std::uint32_t skipped = 0;       // members the sink did not want (already resident)
  std::uint64_t bytes = 0;         // payload bytes copied
  std::uint32_t queries = 0;       // SQL statements executed (see above)
  std::uint32_t blob_reads = 0;    // incremental blob reads
  std::uint32_t transactions = 0;  // read transactions, autocommit statements included
  double ms = 0.0;

  LoadStats& operator+=(const LoadStats& o) {
    keyframes += o.keyframes;
    skipped += o.skipped;
    bytes += o.bytes;
    queries += o.queries;
    blob_reads += o.blob_reads;
    transactions += o.transactions;
    ms += o.ms;
    return *this;
  }
};

// Receives loaded keyframes. Wants() is asked before a payload is read (so resident keyframes
// of overlapping zones are not read twice); Loaded() after it sits in `slot`, complete and
// validated (the slot then belongs to the sink). A time-sliced load may ask Wants() again for a
// member it stopped before (the answer must not change while the load is in flight).
class LoadSink {
 public:
  virtual ~LoadSink() = default;
  virtual bool Wants(KeyframeId id) = 0;
  virtual void Loaded(KeyframeId id, SlotIndex slot, std::uint32_t payload_bytes) = 0;
};

// Receives what ReadGraphNodes() read: each node's weight, then each of its links (both
// directions: `link.from` or `link.to` is the node).
class GraphNodeSink {
 public:
  virtual ~GraphNodeSink() = default;
  virtual void Node(KeyframeId id, std::int32_t weight) = 0;
  virtual void Link(const LinkRecord& link) = 0;
};

// How much one step of a time-sliced zone load may do. A step always loads at least one
// keyframe when one is left (so every load finishes), then stops before the first keyframe
// that would take it past max_keyframes or past max_bytes of payload, or that would start after
// the deadline. Skipped members (not wanted) cost nothing against the budget.
struct LoadBudget {
  std::uint32_t max_keyframes = std::numeric_limits<std::uint32_t>::max();
  std::uint64_t max_bytes = std::numeric_limits<std::uint64_t>::max();
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
};

// The outcome of one StepZoneLoad().
struct ZoneLoadStep {
  bool done = false;  // every member handled and the transaction ended: no load in flight now
  LoadStats stats;    // what this step did
};

// The seam between the working set and the database: the memory module talks to this
// interface, tests use a fake (tests/support/fake_keyframe_source.h).
//
// Time-sliced zone loads: at most ONE is in flight per source. BeginZoneLoad opens the read
// transaction (the load sees one state of the map, whatever is written meanwhile), each
// StepZoneLoad delivers keyframes within its budget, the last one ends the transaction
// (done = true). Any error ends the load: the failing keyframe's slot is released, the
// transaction ended, and nothing is in flight any more; keyframes delivered before stay with the
// sink. AbortZoneLoad ends a load early the same way. Between steps the source holds no slot:
// only the transaction, its statement and blob handle. The arena and the sink must outlive the
// load. While a zone load is in flight, the other loads and ReadGraphNodes are refused
// (FailedPrecondition), so each counts its transactions truly.
class KeyframeSource {
 public:
  virtual ~KeyframeSource() = default;
  // Loads the members of `zone` that the sink wants, in one transaction (one call: Begin, then
  // Step with no budget).
  [[nodiscard]] virtual Result<LoadStats> LoadZone(ZoneId zone, Arena& arena, LoadSink& sink) = 0;
  // Loads the given keyframes the way RTAB-Map retrieves nodes: per wanted keyframe its row,
  // payload, links and calibration, each one statement in its own transaction.
  [[nodiscard]] virtual Result<LoadStats> LoadKeyframes(std::span<const KeyframeId> ids,
                                                        Arena& arena, LoadSink& sink) = 0;

  // Starts a time-sliced load of `zone` (see above); returns what starting cost (1 transaction,
  // 1 query). Refused while another load is in flight.
  [[nodiscard]] virtual Result<LoadStats> BeginZoneLoad(ZoneId zone, Arena& arena,
                                                        LoadSink& sink) = 0;
  // Delivers the next keyframes within `budget`. Refused when no load is in flight.
  [[nodiscard]] virtual Result<ZoneLoadStep> StepZoneLoad(const LoadBudget& budget) = 0;
  // Ends the load in flight, if any (no-op otherwise).
  virtual void AbortZoneLoad() = 0;
  // The zone being loaded, or kNoZone.
  [[nodiscard]] virtual ZoneId ZoneLoadInFlight() const = 0;

  // The basic baseline's graph-search point queries (basic-baseline.md §3.1): per id its weight
  // and its links, two statements, each its own transaction. `sink` may be null (read, counted,
  // discarded). An id that is not in the map is NotFound. No allocation once warm.
  [[nodiscard]] virtual Result<LoadStats> ReadGraphNodes(std::span<const KeyframeId> ids,
                                                         GraphNodeSink* sink) = 0;
};

// The working memory a map ended its last mapping session with: what RTAB-Map's start-up loads
// with Mem/InitWMWithAllNodes=false (Memory::loadDataFromDb -> loadLastNodes; basic-baseline.md
// §3.4). `zonemap import-rtabmap` records it; a map built without memory management (zonemap's
// simulator) records none, and its last working memory is then every node.
struct RecordedWorkingMemory {
  bool every_node = true;       // the whole map (no record, or a record saying so)
  std::string rule;             // how it was decided, for reports; empty when nothing recorded
  std::vector<KeyframeId> ids;  // when !every_node: ascending; may be empty (RTAB-Map then
                                // starts with none)
};

// What the tick loop needs of a map: its metadata (read once at start) and keyframe loads. MapDb
// is the implementation; tests may fake it.
class MapReader : public KeyframeSource {
 public:
  [[nodiscard]] virtual const MapMetadata& metadata() const = 0;
  // Metadata queries: read no payload.
  [[nodiscard]] virtual Result<std::vector<KeyframeMeta>> Keyframes() const = 0;  // by id
  [[nodiscard]] virtual Result<std::vector<LinkRecord>> Links() const = 0;        // each edge once
  [[nodiscard]] virtual Result<std::vector<ZoneRecord>> Zones() const = 0;        // by id
  [[nodiscard]] virtual Result<std::vector<ZoneMember>> ZoneMembers() const = 0;  // zone, keyframe
  // The map's last working memory (read once at start). The default: every node.
  [[nodiscard]] virtual Result<RecordedWorkingMemory> LastWorkingMemory() const {
    return RecordedWorkingMemory{};
  }
  // The map's visual vocabulary as stored (the bytes of lib/localization's Vocabulary::ToBlob,
  // which validates them: LoadMapVocabulary in localization/map_vocabulary.h), or nullopt when
  // the map has none. Read once at start. The default: none.
  [[nodiscard]] virtual Result<std::optional<std::vector<std::byte>>> VocabularyBlob() const {
    return std::optional<std::vector<std::byte>>{};
  }
};
// mmap_bytes that maps the whole file (SQLite caps it at its compile-time limit, 2 GiB on Debian;
// pages past the limit are read with read() calls).
inline constexpr std::int64_t kMapDbMmapWholeFile = std::int64_t{1} << 40;

struct MapDbOptions {
  bool verify_checksums = true;  // CRC-check each payload as it lands in its slot
  std::int64_t sqlite_heap_limit_bytes = 0;  // sqlite3_hard_heap_limit64; 0 = none
  // PRAGMA mmap_size: SQLite reads pages through a memory map of the file. On by default since
  // issue 14: Debian's SQLite has no direct overflow read, so without the map every payload page
  // is pread into SQLite's page cache and then copied again into the slot (one copy with the
  // map: a warm zone load of dense keyframes at 60 % of a sequential read() instead of 37 %,
  // docs/mapdb.md). The price: a map file truncated in place by another process while mapped
  // raises SIGBUS (replace a map with rename, as every zonemap writer does; never cp over a
  // running robot's map), and the pages a load touched count in the process's RSS
  // (file-backed, reclaimable). 0 = off.
  std::int64_t mmap_bytes = kMapDbMmapWholeFile;
};

// Read-only access for the run-time. Move-only; closing is RAII.
class MapDb final : public MapReader {
 public:
  // Opens read-only, checks the schema version and every table, prepares every statement.
  [[nodiscard]] static Result<std::unique_ptr<MapDb>> Open(const std::string& path,
                                                           MapDbOptions options = {});
  ~MapDb() override;

  [[nodiscard]] const MapMetadata& metadata() const override;

  // Metadata queries: read no payload.
  [[nodiscard]] Result<std::vector<KeyframeMeta>> Keyframes() const override;  // ordered by id
  [[nodiscard]] Result<std::vector<LinkRecord>> Links() const override;        // each edge once
  [[nodiscard]] Result<std::vector<ZoneRecord>> Zones() const override;        // ordered by id
  [[nodiscard]] Result<std::vector<ZoneMember>> ZoneMembers() const override;  // by zone, then keyframe
  [[nodiscard]] Result<std::vector<std::uint32_t>> ZoneSizes() const;  // index = ZoneId
  // The recorded last working memory (meta last_wm_rule, last_wm_every_node; table last_wm), or
  // every node when the map records nothing (the simulator's maps). A map imported from RTAB-Map
  // before zonemap recorded it is refused (FailedPrecondition naming the file and the fix),
  // since "every node" could be wrong for it; a last_wm naming a keyframe the map does not hold
  // is Corrupt.
  [[nodiscard]] Result<RecordedWorkingMemory> LastWorkingMemory() const override;

  // The vocabulary table's blob (schema version 2), or nullopt: a version 1 map, or none stored
  // (`zonemap vocab` stores one). A non-blob value is Corrupt.
  [[nodiscard]] Result<std::optional<std::vector<std::byte>>> VocabularyBlob() const override;
  // The file's schema version: kMapDbSchemaVersion, or kMapDbSchemaVersionNoVocabulary.
  [[nodiscard]] int schema_version() const;

  Result<LoadStats> LoadZone(ZoneId zone, Arena& arena, LoadSink& sink) override;
  Result<LoadStats> LoadKeyframes(std::span<const KeyframeId> ids, Arena& arena,
                                  LoadSink& sink) override;
  Result<LoadStats> BeginZoneLoad(ZoneId zone, Arena& arena, LoadSink& sink) override;
  Result<ZoneLoadStep> StepZoneLoad(const LoadBudget& budget) override;
  void AbortZoneLoad() override;
  [[nodiscard]] ZoneId ZoneLoadInFlight() const override;
  Result<LoadStats> ReadGraphNodes(std::span<const KeyframeId> ids, GraphNodeSink* sink) override;

  // Totals since open, for telemetry (metadata reads count as queries and transactions too).
  [[nodiscard]] std::uint64_t total_queries() const;
  [[nodiscard]] std::uint64_t total_blob_reads() const;
  [[nodiscard]] std::uint64_t total_transactions() const;
  [[nodiscard]] std::uint64_t total_bytes_read() const;

  struct Impl;

 private:
  explicit MapDb(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

struct KeyframeRecord {
  KeyframeMeta meta;              // payload_bytes is filled in from payload
  std::span<const std::byte> payload;  // an EncodePayload() blob
};

// Progress of a long write, for a progress bar: `stage` names it ("keyframes", "links"), `done`
// of `total` rows of the current call.
using WriteProgressFn =
    std::function<void(std::string_view stage, std::uint64_t done, std::uint64_t total)>;

// The SQLite page size for a new map whose payloads are `mean_payload_bytes` on average: the
// largest power of two in [4096, 65536] not above a sixteenth of it. A payload larger than a page
// is a chain of overflow pages that SQLite reads one pread each, so large pages make loads of
// large payloads cost few system calls (16x fewer at 64 KiB than at 4 KiB); the last page of a
// chain is half empty on average, so pages no larger than 1/16 of a payload waste <= ~3 %.
[[nodiscard]] std::uint32_t PageBytesForPayload(std::uint64_t mean_payload_bytes);

struct MapDbWriterOptions {
  // SQLite page size of a new database (a power of two in [512, 65536]); 0 = chosen from the
  // first InsertKeyframes batch with PageBytesForPayload() (4096 if the map gets no keyframe).
  std::uint32_t page_bytes = 0;
};

// Creates or modifies a map database. WAL journal while writing; bulk inserts in transactions.
// A new database's file is created at once, its schema at the first call that needs it (so
// the page size can follow the payloads; SetCamera/SetSource before that are kept until then).
class MapDbWriter {
 public:
  // Creates a new database (refuses to overwrite an existing file unless `overwrite`).
  [[nodiscard]] static Result<std::unique_ptr<MapDbWriter>> Create(const std::string& path,
                                                                   bool overwrite = false,
                                                                   MapDbWriterOptions options = {});
  // Opens an existing database for modification (zone annotation); adds the link_to index to
  // a map written before it existed.
  [[nodiscard]] static Result<std::unique_ptr<MapDbWriter>> OpenExisting(const std::string& path);
  ~MapDbWriter();

  // Inserts keyframes (payloads validated first) in one transaction.
  Status InsertKeyframes(std::span<const KeyframeRecord> keyframes);
  Status InsertLinks(std::span<const LinkRecord> links);
  // Replaces every zone and membership in one transaction.
  Status ReplaceZones(std::span<const ZoneRecord> zones, std::span<const ZoneMember> members);
  Status SetCamera(const CameraIntrinsics& camera);
  Status SetSource(const std::string& source);
  // Records the map's last working memory (see RecordedWorkingMemory), replacing any earlier
  // record, in one transaction: `ids` (every one a keyframe already inserted), or every node.
  // `rule` says how it was decided (reports print it).
  Status SetLastWorkingMemory(std::span<const KeyframeId> ids, const std::string& rule);
  Status SetLastWorkingMemoryEveryNode(const std::string& rule);
  // Stores the map's vocabulary (Vocabulary::ToBlob's bytes; this module does not look inside),
  // replacing any earlier one, in one transaction. An empty blob is refused.
  Status SetVocabulary(std::span<const std::byte> blob);
  // Called every 256 rows and at the end of each bulk insert; empty = no reports.
  void SetProgress(WriteProgressFn progress);
  // Reads back (for annotation: positions of the keyframes to assign).
  [[nodiscard]] Result<std::vector<KeyframeMeta>> Keyframes() const;
  [[nodiscard]] Result<std::vector<LinkRecord>> Links() const;
  // Recomputes the metadata (counts, largest payload) and commits everything.
  Status Finish();

  struct Impl;

 private:
  explicit MapDbWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace zm
