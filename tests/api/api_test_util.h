// A small synthetic building for the public API's tests (tests/support/test_building.h): a row of
// square rooms along x (one zone each), keyframes along the corridor through them, and a
// back-and-forth patrol. Written three ways so every way into the API sees the same map: a zonemap map database (MapLoop), a
// frames file (MapLoop's replay) and a GeoJSON zone file plus keyframe poses (ZoneManager).
#pragma once

#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "mapdb/map_db.h"
#include "support/test_building.h"
#include "zonemap/zonemap.h"

namespace zm::test {

constexpr int kRooms = 8;
constexpr double kRoomM = 10.0;
constexpr int kKeyframesPerRoom = 20;

struct ApiScenario {
  std::filesystem::path dir;
  std::string db, frames, zones;
  std::vector<zonemap::KeyframeInfo> keyframes;  // ids 1..N, bytes = payload size
  std::vector<zonemap::Pose> patrol;             // the frames' odometry poses, one a tick
  std::vector<double> stamps;
  ~ApiScenario() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

inline zonemap::Pose XYYaw(double x, double y, double yaw) {
  return {x, y, 0.0, 0.0, 0.0, std::sin(yaw / 2), std::cos(yaw / 2)};
}

inline void BuildApiScenario(ApiScenario* s, int patrol_frames, const std::string& tag) {
  s->dir = std::filesystem::temp_directory_path() /
           ("zm_api_test_" + std::to_string(::getpid()) + "_" + tag);
  std::filesystem::create_directories(s->dir);
  s->db = (s->dir / "map.db").string();
  s->frames = (s->dir / "frames.bin").string();
  s->zones = (s->dir / "zones.geojson").string();
  const BuildingSpec spec{.rooms = kRooms, .keyframes_per_room = kKeyframesPerRoom,
                          .room_m = kRoomM, .seed = 11};
  Building map = WriteBuilding(s->db, spec);

  // The same zones as GeoJSON and the same keyframes as the public API's KeyframeInfo.
  std::ofstream geo(s->zones);
  geo << "{\"type\": \"FeatureCollection\", \"features\": [\n";
  for (std::size_t i = 0; i < map.zones.size(); ++i) {
    const ZoneRecord& z = map.zones[i];
    const double x0 = z.polygon[0][0];
    geo << (i ? ",\n" : "") << "{\"type\": \"Feature\", \"properties\": {\"name\": \"" << z.name
        << "\", \"kind\": \"room\"}, \"geometry\": {\"type\": \"Polygon\", \"coordinates\": [[["
        << x0 << ", 0], [" << x0 + kRoomM << ", 0], [" << x0 + kRoomM << ", " << kRoomM << "], ["
        << x0 << ", " << kRoomM << "], [" << x0 << ", 0]]]}}";
  }
  geo << "\n]}\n";
  geo.close();
  for (const KeyframeMeta& m : map.keyframes) {
    const auto t = m.pose.translation();
    s->keyframes.push_back({.id = {m.id.value}, .pose = XYYaw(t.x(), t.y(), 0.0),
                            .weight = 0, .bytes = m.payload_bytes});
  }

  for (const PatrolPose& p : WritePatrolFrames(s->frames, spec, patrol_frames, map.rng)) {
    s->patrol.push_back(XYYaw(p.x, p.y, p.yaw));
    s->stamps.push_back(p.stamp_s);
  }
}

}  // namespace zm::test
