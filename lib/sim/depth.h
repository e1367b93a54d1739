// Dense keyframe payloads: a depth image rendered from the floor plan and compressed as a 16-bit
// PNG (DenseFormat::kPngDepth16), so keyframe sizes behave like real RGB-D keyframes (the PNG
// size depends on the scene). Per image column one ray is cast on the grid; each row then hits
// the wall, the floor or the ceiling by the room's geometry (walls and furniture full height).
// Depth has range-dependent noise (sigma = 1.5 mm + 2.5 mm * z^2, a structured-light model) so
// the compressed size is realistic; pixels beyond the range are 0 (no return).
//
// Invariants: the image is width x height CV_16UC1 in millimetres, every value 0 or in
// [1, range]; the same inputs and Rng state give the same bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/status.h"
#include "geometry/pose.h"
#include "sim/building.h"
#include "sim/observe.h"
#include "sim/rng.h"

namespace zm::sim {

struct DepthOptions {
  std::uint32_t width = 320;   // dense resolution (the camera's FOV is kept)
  std::uint32_t height = 240;
  double range_m = 10.0;
  int png_compression = 3;  // cv::IMWRITE_PNG_COMPRESSION
};

// Renders the depth seen from body pose `t_map_body` on `floor` and PNG-encodes it into *png.
Status RenderDepthPng(const Building& building, int floor, const Pose3& t_map_body,
                      const CameraModel& camera, const DepthOptions& options, Rng& rng,
                      std::vector<std::byte>* png);

}  // namespace zm::sim
