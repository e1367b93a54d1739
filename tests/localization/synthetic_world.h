// A small synthetic world for the localization tests: a straight corridor whose two walls carry
// random 3-D landmarks with random 256-bit descriptors, observed through the pinhole model of
// lib/localization/camera.h with keypoint noise and descriptor bit flips. Keyframes are real
// payloads (EncodePayload/DecodePayload), so the localizer reads them exactly as it reads arena
// slots. Seeded: every run is identical.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "geometry/pose.h"
#include "localization/frame.h"
#include "localization/localizer.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"

namespace zm::test {

struct WorldOptions {
  std::uint32_t seed = 1;
  double length_m = 50.0;
  double half_width_m = 2.0;
  double landmarks_per_m = 20.0;  // per wall
  double max_range_m = 8.0;       // observations beyond this are not made
  int bit_flips = 8;              // per observation, of 256
  double keypoint_noise_px = 0.5;
  std::size_t max_features = 400;
};

struct Observation {
  std::vector<Descriptor256> descriptors;
  std::vector<float> points;     // map frame, 3 per feature
  std::vector<float> keypoints;  // pixels, 2 per feature
};

class World {
 public:
  explicit World(const WorldOptions& options);
  [[nodiscard]] const CameraIntrinsics& camera() const { return camera_; }
  // What a camera on a robot at T_map_body sees (noise and flips drawn from the world's rng).
  [[nodiscard]] Observation Observe(const Pose3& t_map_body);

 private:
  WorldOptions options_;
  CameraIntrinsics camera_{500.0, 500.0, 320.0, 240.0, 640, 480};
  std::mt19937 rng_;
  std::vector<Eigen::Vector3d> landmarks_;
  std::vector<Descriptor256> descriptors_;
};

// Keyframes built from observations, with their payload blobs kept alive here.
class KeyframeStore {
 public:
  void Add(KeyframeId id, const Pose3& pose, const Observation& obs);
  [[nodiscard]] const std::vector<ResidentKeyframe>& all() const { return keyframes_; }
  // The keyframes whose pose x lies in [x_min, x_max]: a "resident subset".
  [[nodiscard]] std::vector<ResidentKeyframe> InXRange(double x_min, double x_max) const;

 private:
  std::vector<std::vector<std::byte>> blobs_;
  std::vector<ResidentKeyframe> keyframes_;
};

[[nodiscard]] Frame MakeFrame(std::uint64_t index, double stamp_s, const Pose3& odom,
                              const Observation& obs);

}  // namespace zm::test
