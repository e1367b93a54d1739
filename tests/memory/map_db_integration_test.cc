// The working set against the real map database (MapDb, not the fake): semantic zone loads are
// one transaction each, slots hold exactly the payload bytes on disk, overlapping members are
// read once, and resident never exceeds K_max. Builds a tiny database in a temporary file.
#include <doctest/doctest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <map>
#include <variant>

#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "memory/map_index.h"
#include "memory/plan.h"
#include "memory/semantic_policy.h"
#include "memory/working_set.h"

namespace zm {
namespace {

std::vector<std::byte> Payload(std::int64_t id, std::uint32_t features) {
  std::vector<Descriptor256> desc(features);
  for (std::uint32_t i = 0; i < features; ++i) desc[i].fill(static_cast<std::uint8_t>(id + i));
  std::vector<float> pts(3 * features, static_cast<float>(id)), kps(2 * features, 1.0f);
  auto r = EncodePayload(PayloadParts{KeyframeId{id}, desc, pts, kps, DenseFormat::kNone, {}, 0});
  REQUIRE(r.ok());
  return std::move(r).value();
}

TEST_CASE("working set + semantic policy against MapDb: one transaction per zone load") {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("zm_memory_it_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "map.db").string();
  // 12 keyframes; zones {1..5}, {5..8}, {9..12} (keyframe 5 shared).
  const std::vector<std::vector<std::int64_t>> zones{{1, 2, 3, 4, 5}, {5, 6, 7, 8}, {9, 10, 11, 12}};
  std::map<std::int64_t, std::vector<std::byte>> payloads;
  {
    auto w = MapDbWriter::Create(path, /*overwrite=*/true);
    REQUIRE_MESSAGE(w.ok(), w.status().ToString());
    std::vector<KeyframeRecord> recs;
    std::vector<KeyframeMeta> metas;
    for (std::int64_t i = 1; i <= 12; ++i) {
      payloads[i] = Payload(i, 10 + static_cast<std::uint32_t>(i));
      KeyframeMeta m;
      m.id = KeyframeId{i};
      m.pose = PoseFromXYYaw(static_cast<double>(i), 0.0, 0.0);
      m.payload_bytes = static_cast<std::uint32_t>(payloads[i].size());
      metas.push_back(m);
    }
    for (const auto& m : metas) recs.push_back({m, payloads[m.id.value]});
    REQUIRE((*w)->InsertKeyframes(recs).ok());
    std::vector<ZoneRecord> zr;
    std::vector<ZoneMember> members;
    for (std::size_t z = 0; z < zones.size(); ++z) {
      ZoneRecord r;
      r.id = ZoneId{static_cast<std::int32_t>(z)};
      r.name = "zone" + std::to_string(z);
      r.kind = "room";
      r.polygon = {{0.0, 0.0}, {1.0, 0.0}, {1.0, 1.0}};
      zr.push_back(r);
      for (auto id : zones[z]) members.push_back({r.id, KeyframeId{id}});
    }
    REQUIRE((*w)->ReplaceZones(zr, members).ok());
    REQUIRE((*w)->Finish().ok());
  }
  auto db = MapDb::Open(path);
  REQUIRE_MESSAGE(db.ok(), db.status().ToString());
  auto kfs = (*db)->Keyframes();
  auto links = (*db)->Links();
  auto members = (*db)->ZoneMembers();
  REQUIRE(kfs.ok());
  REQUIRE(links.ok());
  REQUIRE(members.ok());
  MapIndexInput in;
  in.keyframes = *kfs;
  in.links = *links;
  in.members = *members;
  in.zone_count = static_cast<std::int32_t>((*db)->metadata().zone_count);
  auto index = MapIndex::Build(in);
  REQUIRE(index.ok());

  constexpr std::uint32_t kKMax = 8;
  auto created = Arena::Create({.memory_thr_keyframes = kKMax, .budget_bytes = 0,
                                .slot_bytes = (*db)->metadata().largest_payload_bytes,
                                .lock = false, .prefault = false});
  REQUIRE(std::holds_alternative<Arena>(created));
  Arena& arena = std::get<Arena>(created);
  WorkingSet ws(*index, arena, **db, kKMax);
  SemanticPolicy policy(*index, SemanticOptions{kKMax});
  Plan plan(*index);

  std::uint32_t transactions = 0, loaded = 0;
  for (std::int32_t z : {0, 1, 2, 0, 1}) {
    TickContext ctx;
    ctx.zone = ZoneId{z};
    TickTelemetry t;
    plan.Clear();
    policy.PlanBeforeLocalize(ctx, &plan);
    Status s = ws.Apply(plan, &t);
    REQUIRE_MESSAGE(s.ok(), s.ToString());
    CHECK(t.db_transactions == (plan.zones_loaded().empty() ? 0U : 1U));
    CHECK(t.peak_resident_keyframes <= kKMax);
    transactions += t.db_transactions;
    loaded += t.keyframes_loaded;
    for (const auto& r : ws.resident()) {  // every slot holds exactly the bytes on disk
      const auto& want = payloads[r.id.value];
      REQUIRE(std::memcmp(arena.Slot(r.slot).data(), want.data(), want.size()) == 0);
    }
  }
  // 0: +5. 1: +3 (5 shared, fits). 2: evict 0 (frees 1..4; 5 stays with 1), +4.
  // 0: evict 1 (frees 6..8; 5 is wanted by 0, so it is pinned, not re-read), evict 2, +4 (1..4).
  // 1: +3 (6..8), fits beside 0.
  CHECK(transactions == 5);
  CHECK(ws.max_resident_seen() <= kKMax);
  CHECK(loaded == 5 + 3 + 4 + 4 + 3);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace zm
