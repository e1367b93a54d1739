// Helpers for the map database tests: a self-deleting temporary directory, deterministic
// payloads, a small map builder, a recording LoadSink and whole-file snapshots (to prove a
// read never changes the file on disk).
#pragma once

#include <doctest/doctest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <variant>
#include <vector>

#include "arena/arena.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"

namespace zm::test {

class TempDir {
 public:
  // On tmpfs (/dev/shm) when there is one: the tests make many small databases and their fsyncs
  // on a shared disk would dominate the run time without testing anything.
  TempDir() {
    std::error_code ec;
    const std::filesystem::path base = std::filesystem::is_directory("/dev/shm", ec) && access("/dev/shm", W_OK) == 0
                                           ? std::filesystem::path("/dev/shm")
                                           : std::filesystem::temp_directory_path();
    std::string tmpl = (base / "zm_mapdb_XXXXXX").string();
    REQUIRE(mkdtemp(tmpl.data()) != nullptr);
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] std::string File(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

inline std::vector<std::byte> MakePayload(std::int64_t id, std::uint32_t features,
                                          std::uint32_t dense_bytes) {
  std::mt19937 rng(static_cast<std::uint32_t>(id * 7919 + features));
  std::vector<Descriptor256> desc(features);
  for (auto& d : desc)
    for (auto& b : d) b = static_cast<std::uint8_t>(rng());
  std::vector<float> pts(3 * features), kps(2 * features);
  for (auto& f : pts) f = static_cast<float>(rng() % 10000) * 0.001f;
  for (auto& f : kps) f = static_cast<float>(rng() % 640);
  std::vector<std::byte> dense(dense_bytes);
  for (auto& b : dense) b = static_cast<std::byte>(rng());
  auto r = EncodePayload(PayloadParts{KeyframeId{id}, desc, pts, kps,
                                      dense_bytes > 0 ? DenseFormat::kOpaque : DenseFormat::kNone,
                                      dense, 0});
  REQUIRE(r.ok());
  return std::move(r).value();
}

// A map of `count` keyframes with ids 1..count; zone z holds `members[z]`.
struct MapSpec {
  int count = 12;
  std::uint32_t features = 20;
  std::uint32_t dense_bytes = 500;
  std::vector<std::vector<std::int64_t>> members = {{1, 2, 3, 4, 5}, {5, 6, 7, 8}, {9, 10, 11, 12}};
};

struct BuiltMap {
  std::map<std::int64_t, std::vector<std::byte>> payloads;
  std::vector<KeyframeMeta> metas;
};

inline BuiltMap BuildMap(const std::string& path, const MapSpec& spec = {},
                         MapDbWriterOptions options = {}) {
  BuiltMap built;
  auto w = MapDbWriter::Create(path, /*overwrite=*/false, options);
  REQUIRE_MESSAGE(w.ok(), w.status().ToString());
  std::vector<KeyframeRecord> recs;
  for (int i = 1; i <= spec.count; ++i) {
    // Sizes differ per keyframe so a wrong blob lands as a visible size mismatch.
    built.payloads[i] = MakePayload(i, spec.features + static_cast<std::uint32_t>(i), spec.dense_bytes);
    KeyframeMeta m;
    m.id = KeyframeId{i};
    m.stamp_s = 0.5 * i;
    m.pose = PoseFromXYYaw(i, -i, 0.1 * i, 0.25);
    m.weight = i % 3;
    m.payload_bytes = static_cast<std::uint32_t>(built.payloads[i].size());
    built.metas.push_back(m);
  }
  for (const auto& m : built.metas) recs.push_back({m, built.payloads[m.id.value]});
  REQUIRE((*w)->InsertKeyframes(recs).ok());
  std::vector<ZoneRecord> zones;
  std::vector<ZoneMember> members;
  for (std::size_t z = 0; z < spec.members.size(); ++z) {
    ZoneRecord zr;
    zr.id = ZoneId{static_cast<std::int32_t>(z)};
    zr.name = "zone" + std::to_string(z);
    zr.kind = "room";
    zr.polygon = {{0.0, 0.0}, {1.0 + static_cast<double>(z), 0.0}, {1.0, 1.0}};
    zones.push_back(zr);
    for (auto id : spec.members[z]) members.push_back({zr.id, KeyframeId{id}});
  }
  REQUIRE((*w)->ReplaceZones(zones, members).ok());
  REQUIRE((*w)->Finish().ok());
  return built;
}

inline Arena MakeArena(std::uint64_t slots, std::uint64_t slot_bytes) {
  auto created = Arena::Create({.memory_thr_keyframes = slots, .budget_bytes = 0,
                                .slot_bytes = slot_bytes, .lock = false, .prefault = false});
  REQUIRE(std::holds_alternative<Arena>(created));
  return std::move(std::get<Arena>(created));
}

inline std::unique_ptr<MapDb> OpenOrFail(const std::string& path) {
  auto db = MapDb::Open(path);
  REQUIRE_MESSAGE(db.ok(), db.status().ToString());
  return std::move(db).value();
}

// Wants everything not yet resident; records what landed where. Storage is reserved up front
// so a warm load through it allocates nothing.
class RecordingSink final : public LoadSink {
 public:
  explicit RecordingSink(std::size_t max_id = 4096) : resident_(max_id + 1, 0) {
    loaded_.reserve(max_id + 1);
  }
  bool Wants(KeyframeId id) override {
    return id.value < 0 || static_cast<std::size_t>(id.value) >= resident_.size() ||
           resident_[static_cast<std::size_t>(id.value)] == 0;
  }
  void Loaded(KeyframeId id, SlotIndex slot, std::uint32_t bytes) override {
    resident_[static_cast<std::size_t>(id.value)] = 1;
    loaded_.push_back({id, slot, bytes});
  }
  struct Entry {
    KeyframeId id;
    SlotIndex slot;
    std::uint32_t bytes;
  };
  [[nodiscard]] const std::vector<Entry>& loaded() const { return loaded_; }
  // Makes Wants(id) false, as if it were already resident (a shared member of another zone).
  void MarkResident(KeyframeId id) { resident_[static_cast<std::size_t>(id.value)] = 1; }
  // Releases every slot it was given and forgets residency.
  void ReleaseAll(Arena& arena) {
    for (const auto& e : loaded_) arena.Release(e.slot);
    Clear();
  }
  // Forgets residency (the caller releases the slots).
  void Clear() {
    std::fill(resident_.begin(), resident_.end(), std::uint8_t{0});
    loaded_.clear();
  }

 private:
  std::vector<std::uint8_t> resident_;
  std::vector<Entry> loaded_;
};

// The start of the load tests (TEST_CASE_FIXTURE): BuildMap's map in a fresh directory, opened,
// an arena of 16 slots sized for its largest keyframe and a recording sink.
struct LoadFixture {
  TempDir dir;
  std::string path = dir.File("map.db");
  BuiltMap built = BuildMap(path);
  std::unique_ptr<MapDb> db = OpenOrFail(path);
  Arena arena = MakeArena(16, db->metadata().largest_payload_bytes);
  RecordingSink sink;
};

// Replaces keyframe `id`'s payload blob in `path` by `edit(blob)` (to damage it on purpose).
inline void EditPayload(const std::string& path, std::int64_t id,
                        const std::function<void(std::vector<unsigned char>&)>& edit) {
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
  sqlite3_stmt* s = nullptr;
  REQUIRE(sqlite3_prepare_v2(db, "SELECT blob FROM payload WHERE keyframe_id=?1", -1, &s, nullptr) == SQLITE_OK);
  sqlite3_bind_int64(s, 1, id);
  REQUIRE(sqlite3_step(s) == SQLITE_ROW);
  const auto* p = static_cast<const unsigned char*>(sqlite3_column_blob(s, 0));
  std::vector<unsigned char> blob(p, p + sqlite3_column_bytes(s, 0));
  sqlite3_finalize(s);
  edit(blob);
  REQUIRE(sqlite3_prepare_v2(db, "UPDATE payload SET blob=?2 WHERE keyframe_id=?1", -1, &s, nullptr) == SQLITE_OK);
  sqlite3_bind_int64(s, 1, id);
  sqlite3_bind_blob(s, 2, blob.data(), static_cast<int>(blob.size()), SQLITE_TRANSIENT);
  REQUIRE(sqlite3_step(s) == SQLITE_DONE);
  sqlite3_finalize(s);
  sqlite3_close(db);
}

// Tries to commit a write to `path` from another connection without waiting: SQLITE_BUSY while
// some reader holds its read transaction (finished maps use a rollback journal), SQLITE_OK
// otherwise.
inline int TryWrite(const std::string& path) {
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) == SQLITE_OK);
  sqlite3_busy_timeout(db, 0);
  const int rc = sqlite3_exec(db, "BEGIN IMMEDIATE; INSERT OR REPLACE INTO meta(key, value) VALUES('zm_test_probe', 1); COMMIT;",
                              nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
  sqlite3_close(db);
  return rc & 0xff;
}

inline std::vector<char> Snapshot(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace zm::test
