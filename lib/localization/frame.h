// One camera frame as the tick loop sees it: odometry pose and the frame's features. Produced by
// the simulator's localization run (frames file), by the live line protocol, or by a ROS
// bridge. Capacity is reserved once (Reserve) so refilling a Frame in the loop never allocates.
#pragma once

#include <cstdint>
#include <vector>

#include "geometry/pose.h"
#include "mapdb/keyframe_payload.h"

namespace zm {

struct Frame {
  std::uint64_t index = 0;
  double stamp_s = 0.0;
  Pose3 odom = Pose3::Identity();          // odometry pose (drifting "odom" frame)
  std::vector<Descriptor256> descriptors;  // size() = feature count
  std::vector<float> keypoints;            // 2 per feature (u, v) pixels, same camera as the map

  void Reserve(std::size_t max_features) {
    descriptors.reserve(max_features);
    keypoints.reserve(2 * max_features);
  }
  [[nodiscard]] std::uint32_t feature_count() const {
    return static_cast<std::uint32_t>(descriptors.size());
  }
};

}  // namespace zm
