// The synthetic building of the tests that need a map database but not a localizable one:
// square rooms side by side along x, their keyframes written to a zonemap map database, and a
// patrol of frames back and forth along the corridor through them. The tick loop's, the public
// API's, basic's accounting and the long-term-memory graph's tests each need a slightly
// different building; the spec says how (layout, payloads, links, zones), so each test keeps the
// exact map its expectations were counted on. (tests/runtime/rooms_map.h is the other kind: a
// map whose frames the localizer really recognises, for the daemon and control tests.)
//
// Determinism: everything random comes from one std::mt19937 seeded by spec.seed, drawn in a
// fixed order (per keyframe: its dense payload, then its weight; then the loop closures), and
// handed back so that frames drawn afterwards continue the same sequence.
#pragma once

#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "geometry/pose.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "runtime/frames_file.h"

namespace zm::test {

inline constexpr CameraIntrinsics kTestCamera{
    .fx = 320, .fy = 320, .cx = 320, .cy = 240, .width = 640, .height = 480};

struct BuildingSpec {
  int rooms = 8;
  int keyframes_per_room = 20;
  double room_m = 10.0;  // square rooms, room r spanning x in [r * room_m, (r + 1) * room_m]
  std::uint32_t seed = 7;
  // Where keyframe k (0-based) of room `room` stands; empty = along the corridor through the
  // rooms' middle (y = room_m / 2), 0.5 m apart from 0.25 m into the room.
  std::function<Pose3(int room, int k)> keyframe_pose{};
  // true: 40 random features and 2.0-2.5 kB of random dense bytes (DenseFormat::kOpaque);
  // false: one zero descriptor, the point (0, 0, 1) at image point `keypoint`, no dense part.
  bool dense_payloads = true;
  std::array<float, 2> keypoint{1.0f, 1.0f};
  bool random_weights = false;  // weights 0..3; every 17th id an intermediate node (-1)
  bool neighbour_links = false;  // id - 1 -> id
  // Loop closures between random keyframes (one in three a local-space closure, the others
  // global), every other one stored both ways as RTAB-Map stores every edge.
  int random_closures = 0;
  enum class Zones {
    kOnePerRoom,   // "room<r>", the room's square
    kOneCorridor,  // one zone "corridor" of kind corridor holding every keyframe
    kNone,
  };
  Zones zones = Zones::kOnePerRoom;
  std::vector<std::array<double, 2>> corridor_polygon{};  // for kOneCorridor
  bool camera = true;                                  // kTestCamera written
  std::string source{};                                // MapDbWriter::SetSource when not empty
  const std::vector<std::int64_t>* last_working_memory = nullptr;  // recorded when given
};

// What was written, in id order (ids 1..N, room by room), and the generator after it.
struct Building {
  std::vector<KeyframeMeta> keyframes;
  std::vector<LinkRecord> links;
  std::vector<ZoneRecord> zones;
  std::vector<ZoneMember> members;
  std::mt19937 rng;
};

inline std::vector<std::byte> BuildingPayload(const BuildingSpec& spec, std::int64_t id,
                                              std::mt19937& rng) {
  if (!spec.dense_payloads) {
    const Descriptor256 d{};
    const float pt[3] = {0, 0, 1};
    auto p = EncodePayload(
        PayloadParts{KeyframeId{id}, {&d, 1}, pt, spec.keypoint, DenseFormat::kNone, {}, 0});
    REQUIRE(p.ok());
    return std::move(p).value();
  }
  constexpr std::uint32_t kFeatures = 40;
  std::vector<Descriptor256> desc(kFeatures);
  for (auto& d : desc)
    for (auto& b : d) b = static_cast<std::uint8_t>(rng());
  std::vector<float> pts(3 * kFeatures), kps(2 * kFeatures);
  for (auto& f : pts) f = static_cast<float>(rng() % 1000) * 0.01f;
  for (auto& f : kps) f = static_cast<float>(rng() % 640);
  std::vector<std::byte> dense(2000 + rng() % 500);
  for (auto& b : dense) b = static_cast<std::byte>(rng());
  auto p =
      EncodePayload(PayloadParts{KeyframeId{id}, desc, pts, kps, DenseFormat::kOpaque, dense, 0});
  REQUIRE(p.ok());
  return std::move(p).value();
}

// Writes the map database at `db_path` (overwriting it).
inline Building WriteBuilding(const std::string& db_path, const BuildingSpec& spec) {
  Building map;
  std::mt19937& rng = map.rng;
  rng.seed(spec.seed);
  std::vector<std::vector<std::byte>> payloads;
  std::int64_t id = 1;
  for (int room = 0; room < spec.rooms; ++room) {
    const double x0 = room * spec.room_m;
    if (spec.zones == BuildingSpec::Zones::kOnePerRoom) {
      ZoneRecord z;
      z.id = ZoneId{room};
      z.name = "room" + std::to_string(room);
      z.kind = "room";
      z.polygon = {{x0, 0.0}, {x0 + spec.room_m, 0.0}, {x0 + spec.room_m, spec.room_m},
                   {x0, spec.room_m}};
      map.zones.push_back(z);
    }
    for (int k = 0; k < spec.keyframes_per_room; ++k, ++id) {
      payloads.push_back(BuildingPayload(spec, id, rng));
      KeyframeMeta m;
      m.id = KeyframeId{id};
      m.pose = spec.keyframe_pose ? spec.keyframe_pose(room, k)
                                  : PoseFromXYYaw(x0 + 0.25 + 0.5 * k, spec.room_m / 2, 0.0);
      if (spec.random_weights) m.weight = id % 17 == 0 ? -1 : static_cast<std::int32_t>(rng() % 4);
      m.payload_bytes = static_cast<std::uint32_t>(payloads.back().size());
      map.keyframes.push_back(m);
      if (spec.zones == BuildingSpec::Zones::kOnePerRoom) {
        map.members.push_back({ZoneId{room}, m.id});
      } else if (spec.zones == BuildingSpec::Zones::kOneCorridor) {
        map.members.push_back({ZoneId{0}, m.id});
      }
      if (spec.neighbour_links && id > 1) {
        map.links.push_back(LinkRecord{KeyframeId{id - 1}, KeyframeId{id}, LinkKind::kNeighbor});
      }
    }
  }
  const auto n = static_cast<std::uint32_t>(id - 1);
  for (int i = 0; i < spec.random_closures; ++i) {
    const std::int64_t a = 1 + static_cast<std::int64_t>(rng() % n);
    const std::int64_t b = 1 + static_cast<std::int64_t>(rng() % n);
    if (a == b) continue;
    const LinkKind t = i % 3 == 0 ? LinkKind::kLocalSpaceClosure : LinkKind::kGlobalClosure;
    map.links.push_back(LinkRecord{KeyframeId{a}, KeyframeId{b}, t});
    if (i % 2 == 0) map.links.push_back(LinkRecord{KeyframeId{b}, KeyframeId{a}, t});
  }
  if (spec.zones == BuildingSpec::Zones::kOneCorridor) {
    ZoneRecord z;
    z.id = ZoneId{0};
    z.name = "corridor";
    z.kind = "corridor";
    z.polygon = spec.corridor_polygon;
    map.zones.push_back(z);
  }

  auto w = MapDbWriter::Create(db_path, /*overwrite=*/true);
  REQUIRE_MESSAGE(w.ok(), w.status().ToString());
  std::vector<KeyframeRecord> recs;
  for (std::size_t i = 0; i < map.keyframes.size(); ++i) recs.push_back({map.keyframes[i], payloads[i]});
  REQUIRE((*w)->InsertKeyframes(recs).ok());
  if (!map.links.empty()) REQUIRE((*w)->InsertLinks(map.links).ok());
  if (!map.zones.empty()) REQUIRE((*w)->ReplaceZones(map.zones, map.members).ok());
  if (spec.camera) REQUIRE((*w)->SetCamera(kTestCamera).ok());
  if (!spec.source.empty()) REQUIRE((*w)->SetSource(spec.source).ok());
  if (spec.last_working_memory != nullptr) {
    std::vector<KeyframeId> ids;
    for (auto i : *spec.last_working_memory) ids.push_back(KeyframeId{i});
    REQUIRE((*w)->SetLastWorkingMemory(ids, "test").ok());
  }
  REQUIRE((*w)->Finish().ok());
  return map;
}

// One patrol frame's odometry pose on the corridor (y = room_m / 2) and its stamp.
struct PatrolPose {
  double x = 0.0, y = 0.0, yaw = 0.0, stamp_s = 0.0;
};

// Writes `frames` frames at 2 Hz (0.5 s apart) walking a triangle wave over the corridor, so
// every room is left and re-entered several times; each frame has 30 random descriptors drawn
// from `rng` (continue the map's: Building::rng). Returns the poses written.
inline std::vector<PatrolPose> WritePatrolFrames(const std::string& path, const BuildingSpec& spec,
                                                 int frames, std::mt19937& rng) {
  auto fw = FrameWriter::Create(path, kTestCamera, 2.0);
  REQUIRE(fw.ok());
  std::vector<PatrolPose> poses;
  Frame f;
  const double length = spec.rooms * spec.room_m - 1.0;
  const double y = spec.room_m / 2;
  for (int i = 0; i < frames; ++i) {
    const double phase = std::fmod(i * 1.7, 2.0 * length);
    const double x = 0.5 + (phase < length ? phase : 2.0 * length - phase);
    const double yaw = phase < length ? 0.0 : M_PI;
    f.index = static_cast<std::uint64_t>(i);
    f.stamp_s = 0.5 * i;
    f.odom = PoseFromXYYaw(x, y, yaw, 0.0);
    f.descriptors.assign(30, Descriptor256{});
    for (auto& d : f.descriptors)
      for (auto& b : d) b = static_cast<std::uint8_t>(rng());
    f.keypoints.assign(60, 100.0f);
    REQUIRE(fw->Append(f).ok());
    poses.push_back({x, y, yaw, f.stamp_s});
  }
  REQUIRE(fw->Finish().ok());
  return poses;
}

}  // namespace zm::test
