// One camera frame as the tick loop sees it: odometry pose and the frame's features. Produced by
// the simulator's localization run (frames file), by the live line protocol, or by a ROS
// bridge. Capacity is reserved once (Reserve) so refilling a Frame in the loop never allocates.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "geometry/pose.h"
#include "mapdb/keyframe_payload.h"

namespace zm {

// How a frame's image is encoded (the bytes of Frame::colour / Frame::depth).
enum class ImageCodec : std::uint8_t { kNone, kJpeg, kPng, kRvl };

struct Frame {
  std::uint64_t index = 0;
  double stamp_s = 0.0;
  Pose3 odom = Pose3::Identity();          // odometry pose (drifting "odom" frame)
  std::vector<Descriptor256> descriptors;  // size() = feature count
  std::vector<float> keypoints;            // 2 per feature (u, v) pixels, same camera as the map
  // A camera's frame (issue 26): its colour image encoded (JPEG or PNG, the map camera's size),
  // and its depth (RVL, or a 16-bit PNG at depth_units_per_m) when the source has one. The loop's
  // front-end (front_end.h) decodes the colour and extracts the features into descriptors and
  // keypoints. Empty for a frame that carries its features (a host's own front-end, or the
  // simulator's descriptor oracle).
  ImageCodec colour_codec = ImageCodec::kNone;
  std::vector<std::byte> colour;
  ImageCodec depth_codec = ImageCodec::kNone;
  std::vector<std::byte> depth;
  double depth_units_per_m = 1000.0;

  void Reserve(std::size_t max_features, std::size_t max_colour_bytes = 0,
               std::size_t max_depth_bytes = 0) {
    descriptors.reserve(max_features);
    keypoints.reserve(2 * max_features);
    colour.reserve(max_colour_bytes);
    depth.reserve(max_depth_bytes);
  }
  [[nodiscard]] bool has_image() const { return colour_codec != ImageCodec::kNone; }
  [[nodiscard]] std::uint32_t feature_count() const {
    return static_cast<std::uint32_t>(descriptors.size());
  }
};

}  // namespace zm
