// The map database: keyframes, their payloads, the pose graph and the semantic zones, in one
// SQLite file. Writers (simulator, importer, zone annotation) use MapDbWriter; the run-time reads
// through MapDb, opened read-only with every statement prepared once at open.
//
// The hot path is LoadZone(): one transaction, one prepared statement stepping over the
// zone-member index, each member's payload copied straight into an arena slot (no intermediate
// heap buffer), stopping with a clear error, never writing outside a slot, if a blob does not
// fit. LoadKeyframes() is the per-keyframe path of the "basic" baseline; it counts its queries
// so the two I/O patterns can be compared.
//
// This module knows nothing of memory policies (docs/design.md): callers say which keyframes
// they want through a LoadSink and get told which slot each one landed in.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "arena/arena.h"
#include "common/ids.h"
#include "common/status.h"
#include "geometry/pose.h"

namespace zm {

// Bumped whenever the schema changes; a database of another version is refused at open.
inline constexpr int kMapDbSchemaVersion = 1;

// RTAB-Map's Link.type values (basic-baseline.md §5), kept as-is on import.
enum class LinkType : std::int32_t {
  kNeighbor = 0,
  kGlobalClosure = 1,
  kLocalSpaceClosure = 2,
  kLocalTimeClosure = 3,
  kUserClosure = 4,
  kVirtualClosure = 5,
  kNeighborMerged = 6,
  kPosePrior = 7,
  kLandmark = 8,
  kGravity = 9,
};

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
  CameraIntrinsics camera;
  std::string source;  // "sim hospital seed=1", "rtabmap:/path/file.db", ...
};

// What a load did. Times are wall-clock on a monotonic clock.
struct LoadStats {
  std::uint32_t keyframes = 0;     // payloads copied into slots
  std::uint32_t skipped = 0;       // members the sink did not want (already resident)
  std::uint64_t bytes = 0;         // payload bytes copied
  std::uint32_t queries = 0;       // statements stepped (a zone load is 1)
  std::uint32_t transactions = 0;  // BEGIN..COMMIT pairs (a zone load is 1)
  double ms = 0.0;
};

// Receives loaded keyframes. Wants() is asked before a payload is read (so resident keyframes
// of overlapping zones are not read twice); Loaded() after it sits in `slot`.
class LoadSink {
 public:
  virtual ~LoadSink() = default;
  virtual bool Wants(KeyframeId id) = 0;
  virtual void Loaded(KeyframeId id, SlotIndex slot, std::uint32_t payload_bytes) = 0;
};

// The seam between the working set and the database: the memory module talks to this
// interface, tests use a fake (tests/support/fake_keyframe_source.h).
class KeyframeSource {
 public:
  virtual ~KeyframeSource() = default;
  // Loads the members of `zone` that the sink wants, in one transaction.
  [[nodiscard]] virtual Result<LoadStats> LoadZone(ZoneId zone, Arena& arena, LoadSink& sink) = 0;
  // Loads the given keyframes one point query each (RTAB-Map's pattern), in one call.
  [[nodiscard]] virtual Result<LoadStats> LoadKeyframes(std::span<const KeyframeId> ids,
                                                        Arena& arena, LoadSink& sink) = 0;
};

struct MapDbOptions {
  bool verify_checksums = true;  // CRC-check each payload as it lands in its slot
  std::int64_t sqlite_heap_limit_bytes = 0;  // sqlite3_hard_heap_limit64; 0 = none
  // PRAGMA mmap_size: read pages through a memory map instead of read() calls; 0 = off. Faster
  // loads, but a file truncated by another process while mapped raises SIGBUS, so off by default.
  std::int64_t mmap_bytes = 0;
};

// Read-only access for the run-time. Move-only; closing is RAII.
class MapDb final : public KeyframeSource {
 public:
  // Opens read-only, checks the schema version and every table, prepares every statement.
  [[nodiscard]] static Result<std::unique_ptr<MapDb>> Open(const std::string& path,
                                                           MapDbOptions options = {});
  ~MapDb() override;

  [[nodiscard]] const MapMetadata& metadata() const;

  // Metadata queries: read no payload.
  [[nodiscard]] Result<std::vector<KeyframeMeta>> Keyframes() const;  // ordered by id
  [[nodiscard]] Result<std::vector<LinkRecord>> Links() const;        // each edge once
  [[nodiscard]] Result<std::vector<ZoneRecord>> Zones() const;        // ordered by id
  [[nodiscard]] Result<std::vector<ZoneMember>> ZoneMembers() const;  // by zone, then keyframe
  [[nodiscard]] Result<std::vector<std::uint32_t>> ZoneSizes() const;  // index = ZoneId

  Result<LoadStats> LoadZone(ZoneId zone, Arena& arena, LoadSink& sink) override;
  Result<LoadStats> LoadKeyframes(std::span<const KeyframeId> ids, Arena& arena,
                                  LoadSink& sink) override;

  // Totals since open, for telemetry.
  [[nodiscard]] std::uint64_t total_queries() const;
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

// Creates or modifies a map database. WAL journal; bulk inserts in transactions.
class MapDbWriter {
 public:
  // Creates a new database (refuses to overwrite an existing file unless `overwrite`).
  [[nodiscard]] static Result<std::unique_ptr<MapDbWriter>> Create(const std::string& path,
                                                                   bool overwrite = false);
  // Opens an existing database for modification (zone annotation).
  [[nodiscard]] static Result<std::unique_ptr<MapDbWriter>> OpenExisting(const std::string& path);
  ~MapDbWriter();

  // Inserts keyframes (payloads validated first) in one transaction.
  Status InsertKeyframes(std::span<const KeyframeRecord> keyframes);
  Status InsertLinks(std::span<const LinkRecord> links);
  // Replaces every zone and membership in one transaction.
  Status ReplaceZones(std::span<const ZoneRecord> zones, std::span<const ZoneMember> members);
  Status SetCamera(const CameraIntrinsics& camera);
  Status SetSource(const std::string& source);
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
