// A small synthetic building for the public API's tests: a row of square rooms along x (one
// zone each), keyframes along the corridor through them, and a back-and-forth patrol. Written
// three ways so every way into the API sees the same map: a zonemap map database (MapLoop), a
// frames file (MapLoop's replay) and a GeoJSON zone file plus keyframe poses (ZoneManager).
#pragma once

#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "runtime/frames_file.h"
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
  std::mt19937 rng(11);
  auto w = MapDbWriter::Create(s->db, true);
  REQUIRE(w.ok());
  std::vector<std::vector<std::byte>> payloads;
  std::vector<KeyframeRecord> recs;
  std::vector<ZoneMember> members;
  std::vector<ZoneRecord> zones;
  std::ofstream geo(s->zones);
  geo << "{\"type\": \"FeatureCollection\", \"features\": [\n";
  std::int64_t id = 1;
  for (int room = 0; room < kRooms; ++room) {
    ZoneRecord z;
    z.id = ZoneId{room};
    z.name = "room" + std::to_string(room);
    z.kind = "room";
    const double x0 = room * kRoomM;
    z.polygon = {{x0, 0.0}, {x0 + kRoomM, 0.0}, {x0 + kRoomM, kRoomM}, {x0, kRoomM}};
    zones.push_back(z);
    geo << (room ? ",\n" : "") << "{\"type\": \"Feature\", \"properties\": {\"name\": \"" << z.name
        << "\", \"kind\": \"room\"}, \"geometry\": {\"type\": \"Polygon\", \"coordinates\": [[["
        << x0 << ", 0], [" << x0 + kRoomM << ", 0], [" << x0 + kRoomM << ", " << kRoomM << "], ["
        << x0 << ", " << kRoomM << "], [" << x0 << ", 0]]]}}";
    for (int k = 0; k < kKeyframesPerRoom; ++k, ++id) {
      std::vector<Descriptor256> desc(40);
      for (auto& d : desc)
        for (auto& b : d) b = static_cast<std::uint8_t>(rng());
      std::vector<float> pts(120), kps(80);
      for (auto& f : pts) f = static_cast<float>(rng() % 1000) * 0.01f;
      for (auto& f : kps) f = static_cast<float>(rng() % 640);
      std::vector<std::byte> dense(2000 + rng() % 500);
      for (auto& b : dense) b = static_cast<std::byte>(rng());
      auto payload = EncodePayload(
          PayloadParts{KeyframeId{id}, desc, pts, kps, DenseFormat::kOpaque, dense, 0});
      REQUIRE(payload.ok());
      payloads.push_back(std::move(payload).value());
      KeyframeMeta m;
      m.id = KeyframeId{id};
      m.pose = PoseFromXYYaw(x0 + 0.25 + 0.5 * k, 5.0, 0.0, 0.0);
      m.payload_bytes = static_cast<std::uint32_t>(payloads.back().size());
      members.push_back({z.id, m.id});
      recs.push_back({m, {}});
      s->keyframes.push_back({.id = {id}, .pose = XYYaw(x0 + 0.25 + 0.5 * k, 5.0, 0.0),
                              .weight = 0, .bytes = m.payload_bytes});
    }
  }
  geo << "\n]}\n";
  geo.close();
  for (std::size_t i = 0; i < recs.size(); ++i) recs[i].payload = payloads[i];
  REQUIRE((*w)->InsertKeyframes(recs).ok());
  REQUIRE((*w)->ReplaceZones(zones, members).ok());
  const CameraIntrinsics cam{.fx = 320, .fy = 320, .cx = 320, .cy = 240, .width = 640, .height = 480};
  REQUIRE((*w)->SetCamera(cam).ok());
  REQUIRE((*w)->Finish().ok());

  auto fw = FrameWriter::Create(s->frames, cam, 2.0);
  REQUIRE(fw.ok());
  Frame f;
  const double length = kRooms * kRoomM - 1.0;
  for (int i = 0; i < patrol_frames; ++i) {
    const double phase = std::fmod(i * 1.7, 2.0 * length);
    const double x = 0.5 + (phase < length ? phase : 2.0 * length - phase);
    const double yaw = phase < length ? 0.0 : M_PI;
    f.index = static_cast<std::uint64_t>(i);
    f.stamp_s = 0.5 * i;
    f.odom = PoseFromXYYaw(x, 5.0, yaw, 0.0);
    f.descriptors.assign(30, Descriptor256{});
    for (auto& d : f.descriptors)
      for (auto& b : d) b = static_cast<std::uint8_t>(rng());
    f.keypoints.assign(60, 100.0f);
    REQUIRE(fw->Append(f).ok());
    s->patrol.push_back(XYYaw(x, 5.0, yaw));
    s->stamps.push_back(f.stamp_s);
  }
  REQUIRE(fw->Finish().ok());
}

}  // namespace zm::test
