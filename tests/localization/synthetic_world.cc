// Synthetic corridor world for the localization tests (see synthetic_world.h).
#include "synthetic_world.h"

#include <doctest/doctest.h>

#include <algorithm>

#include "localization/camera.h"

namespace zm::test {

World::World(const WorldOptions& options) : options_(options), rng_(options.seed) {
  std::uniform_real_distribution<double> ux(0.0, options.length_m);
  std::uniform_real_distribution<double> uz(-1.0, 1.5);
  std::uniform_int_distribution<int> byte(0, 255);
  const auto per_wall = static_cast<std::size_t>(options.landmarks_per_m * options.length_m);
  for (int wall = 0; wall < 2; ++wall) {
    const double y = wall == 0 ? options.half_width_m : -options.half_width_m;
    for (std::size_t i = 0; i < per_wall; ++i) {
      landmarks_.emplace_back(ux(rng_), y, uz(rng_));
      Descriptor256 d;
      for (auto& b : d) b = static_cast<std::uint8_t>(byte(rng_));
      descriptors_.push_back(d);
    }
  }
}

Observation World::Observe(const Pose3& t_map_body) {
  Observation obs;
  const Pose3 t_cam_map = CameraPoseInMap(t_map_body).inverse();
  std::normal_distribution<double> noise(0.0, options_.keypoint_noise_px);
  std::uniform_int_distribution<int> bit(0, 255);
  for (std::size_t i = 0; i < landmarks_.size(); ++i) {
    const Eigen::Vector3d p_cam = t_cam_map * landmarks_[i];
    Eigen::Vector2d uv;
    if (p_cam.norm() > options_.max_range_m || !Project(camera_, p_cam, &uv)) continue;
    Descriptor256 d = descriptors_[i];
    for (int f = 0; f < options_.bit_flips; ++f) {
      const int b = bit(rng_);
      d[static_cast<std::size_t>(b / 8)] ^= static_cast<std::uint8_t>(1u << (b % 8));
    }
    obs.descriptors.push_back(d);
    for (int k = 0; k < 3; ++k) obs.points.push_back(static_cast<float>(landmarks_[i][k]));
    obs.keypoints.push_back(static_cast<float>(uv.x() + noise(rng_)));
    obs.keypoints.push_back(static_cast<float>(uv.y() + noise(rng_)));
    if (obs.descriptors.size() >= options_.max_features) break;
  }
  return obs;
}

void KeyframeStore::Add(KeyframeId id, const Pose3& pose, const Observation& obs) {
  PayloadParts parts;
  parts.id = id;
  parts.descriptors = obs.descriptors;
  parts.points = obs.points;
  parts.keypoints = obs.keypoints;
  auto blob = EncodePayload(parts);
  REQUIRE(blob.ok());
  blobs_.push_back(std::move(*blob));
  auto view = DecodePayload(blobs_.back());
  REQUIRE(view.ok());
  keyframes_.push_back(ResidentKeyframe{id, pose, *view});
}

std::vector<ResidentKeyframe> KeyframeStore::InXRange(double x_min, double x_max) const {
  std::vector<ResidentKeyframe> out;
  for (const auto& k : keyframes_) {
    const double x = k.pose.translation().x();
    if (x >= x_min && x <= x_max) out.push_back(k);
  }
  return out;
}

Frame MakeFrame(std::uint64_t index, double stamp_s, const Pose3& odom, const Observation& obs) {
  Frame f;
  f.index = index;
  f.stamp_s = stamp_s;
  f.odom = odom;
  f.descriptors = obs.descriptors;
  f.keypoints = obs.keypoints;
  return f;
}

}  // namespace zm::test
