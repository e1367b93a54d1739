// A small map for the session and control tests: a row of square rooms along x (one zone
// each), keyframes along the corridor through them, and frames that the localizer can really
// close a loop on: a frame at x observes the 3-D points of the keyframe nearest to x with that
// keyframe's descriptors, projected from the frame's own pose (so PnP recovers the pose, and its
// covariance is a real one). Frames can also be made unrecognisable (random descriptors).
#pragma once

#include <doctest/doctest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "localization/camera.h"
#include "localization/frame.h"
#include "mapdb/dense_codec.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "mapdb/rvl.h"
#include "runtime/line_protocol.h"

namespace zm::test {

class RoomsMap {
 public:
  static constexpr double kRoomM = 10.0;
  static constexpr int kPoints = 40;

  // dense: every keyframe also carries a small RGB-D image (JPEG + RVL, as `zonemap sim` writes
  // them), decoded into its slot on every load, so the load path includes the dense decoder.
  RoomsMap(int rooms, int keyframes_per_room, const std::string& tag, bool dense = false)
      : rooms_(rooms), per_room_(keyframes_per_room), dense_(dense) {
    dir_ = std::filesystem::temp_directory_path() /
           ("zm_rooms_" + tag + "_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    db_ = (dir_ / "map.db").string();
    Build();
  }
  ~RoomsMap() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  RoomsMap(const RoomsMap&) = delete;
  RoomsMap& operator=(const RoomsMap&) = delete;

  [[nodiscard]] const std::string& db() const { return db_; }
  [[nodiscard]] const std::filesystem::path& dir() const { return dir_; }
  [[nodiscard]] int keyframes() const { return rooms_ * per_room_; }
  [[nodiscard]] int keyframes_per_room() const { return per_room_; }
  [[nodiscard]] double length_m() const { return rooms_ * kRoomM; }
  [[nodiscard]] static const CameraIntrinsics& Camera() {
    static const CameraIntrinsics k{320, 320, 320, 240, 640, 480};
    return k;
  }

  // A frame with odometry pose (x, 5, heading 0) at `stamp`. recognisable: it sees the nearest
  // keyframe's points; otherwise random descriptors nothing matches.
  [[nodiscard]] Frame FrameAt(double stamp, double x, bool recognisable, double odom_dx = 0.0) {
    Frame f;
    f.stamp_s = stamp;
    f.odom = PoseFromXYYaw(x + odom_dx, 5.0, 0.0);
    const Pose3 truth = PoseFromXYYaw(x, 5.0, 0.0);
    if (!recognisable) {
      f.descriptors.resize(30);
      for (auto& d : f.descriptors)
        for (auto& b : d) b = static_cast<std::uint8_t>(rng_());
      f.keypoints.assign(60, 100.0f);
      return f;
    }
    int nearest = 0;
    for (int k = 1; k < keyframes(); ++k) {
      if (std::abs(KeyframeX(k) - x) < std::abs(KeyframeX(nearest) - x)) nearest = k;
    }
    const Pose3 t_cam_map = CameraPoseInMap(truth).inverse();
    for (int i = 0; i < kPoints; ++i) {
      const Eigen::Vector3d p = points_[static_cast<std::size_t>(nearest)][static_cast<std::size_t>(i)];
      Eigen::Vector2d uv;
      if (!Project(Camera(), t_cam_map * p, &uv)) continue;
      f.descriptors.push_back(descriptors_[static_cast<std::size_t>(nearest)][static_cast<std::size_t>(i)]);
      f.keypoints.push_back(static_cast<float>(uv.x()));
      f.keypoints.push_back(static_cast<float>(uv.y()));
    }
    return f;
  }
  [[nodiscard]] std::string FrameLine(double stamp, double x, bool recognisable) {
    return FormatFrameLine(FrameAt(stamp, x, recognisable));
  }
  [[nodiscard]] double KeyframeX(int k) const {
    const int room = k / per_room_;
    const double step = kRoomM / per_room_;
    return room * kRoomM + 0.5 * step + step * (k % per_room_);
  }

 private:
  void Build() {
    auto w = MapDbWriter::Create(db_, true);
    REQUIRE(w.ok());
    std::vector<std::vector<std::byte>> payloads;
    std::vector<KeyframeRecord> recs;
    std::vector<ZoneMember> members;
    std::vector<ZoneRecord> zones;
    std::uniform_real_distribution<double> ahead(2.0, 8.0), side(-3.0, 3.0), up(-1.0, 2.0);
    for (int room = 0; room < rooms_; ++room) {
      ZoneRecord z;
      z.id = ZoneId{room};
      z.name = "room" + std::to_string(room);
      z.kind = "room";
      const double x0 = room * kRoomM;
      z.polygon = {{x0, 0.0}, {x0 + kRoomM, 0.0}, {x0 + kRoomM, kRoomM}, {x0, kRoomM}};
      zones.push_back(z);
      for (int i = 0; i < per_room_; ++i) {
        const int k = room * per_room_ + i;
        const Pose3 pose = PoseFromXYYaw(KeyframeX(k), 5.0, 0.0);
        const Pose3 t_cam_map = CameraPoseInMap(pose).inverse();
        std::vector<Eigen::Vector3d> pts;
        std::vector<Descriptor256> desc;
        std::vector<float> xyz, kps;
        while (static_cast<int>(pts.size()) < kPoints) {
          const Eigen::Vector3d p(KeyframeX(k) + ahead(rng_), 5.0 + side(rng_), up(rng_));
          Eigen::Vector2d uv;
          if (!Project(Camera(), t_cam_map * p, &uv)) continue;
          pts.push_back(p);
          Descriptor256 d;
          for (auto& b : d) b = static_cast<std::uint8_t>(rng_());
          desc.push_back(d);
          xyz.insert(xyz.end(), {static_cast<float>(p.x()), static_cast<float>(p.y()),
                                 static_cast<float>(p.z())});
          kps.insert(kps.end(), {static_cast<float>(uv.x()), static_cast<float>(uv.y())});
        }
        points_.push_back(pts);
        descriptors_.push_back(desc);
        const KeyframeId id{k + 1};
        PayloadParts parts{id, desc, xyz, kps, DenseFormat::kNone, {}, 0};
        std::vector<std::byte> both;
        if (dense_) {
          std::vector<std::uint8_t> rgb(kDenseW * kDenseH * 3);
          const auto kk = static_cast<std::size_t>(k);
          for (std::size_t j = 0; j < rgb.size(); ++j) rgb[j] = static_cast<std::uint8_t>(j * 7 + kk);
          DepthImage16 depth{kDenseW, kDenseH, std::vector<std::uint16_t>(kDenseW * kDenseH)};
          for (std::size_t j = 0; j < depth.pixels.size(); ++j) {
            depth.pixels[j] = static_cast<std::uint16_t>(1000 + (j * 13 + kk) % 3000);
          }
          auto jpeg = EncodeJpegRgb(rgb, kDenseW, kDenseH, 90);
          REQUIRE(jpeg.ok());
          const std::vector<std::byte> rvl = EncodeRvlDepth(depth);
          both = std::move(jpeg).value();
          parts.dense_split = static_cast<std::uint32_t>(both.size());
          both.insert(both.end(), rvl.begin(), rvl.end());
          parts.dense_format = DenseFormat::kJpegColourRvlDepth;
          parts.dense = both;
          parts.dense_width = kDenseW;
          parts.dense_height = kDenseH;
          parts.cloud_step = 4;
        }
        auto payload = EncodePayload(parts);
        REQUIRE_MESSAGE(payload.ok(), payload.status().ToString());
        payloads.push_back(std::move(payload).value());
        KeyframeMeta m;
        m.id = id;
        m.pose = pose;
        // The slot bytes the keyframe needs: the decoded layout for a dense one.
        m.payload_bytes = static_cast<std::uint32_t>(
            dense_ ? DecodedLayoutFor(payloads.back().size(), static_cast<std::uint32_t>(desc.size()),
                                      kDenseW, kDenseH, 4, /*points_from_depth=*/false)
                         .end
                   : payloads.back().size());
        members.push_back({z.id, m.id});
        recs.push_back({m, {}});
      }
    }
    for (std::size_t i = 0; i < recs.size(); ++i) recs[i].payload = payloads[i];
    REQUIRE((*w)->InsertKeyframes(recs).ok());
    REQUIRE((*w)->ReplaceZones(zones, members).ok());
    REQUIRE((*w)->SetCamera(Camera()).ok());
    REQUIRE((*w)->Finish().ok());
  }

  static constexpr std::uint32_t kDenseW = 32, kDenseH = 24;
  int rooms_, per_room_;
  bool dense_ = false;
  std::filesystem::path dir_;
  std::string db_;
  std::mt19937 rng_{42};
  std::vector<std::vector<Eigen::Vector3d>> points_;
  std::vector<std::vector<Descriptor256>> descriptors_;
};

}  // namespace zm::test
