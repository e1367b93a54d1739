// A keyframe payload from a colour and a depth image, as every zonemap map stores one since issue
// 26: ORB features from the one OrbExtractor (descriptors strongest first, keypoints), the colour
// image as JPEG and the depth as RVL in millimetres (DenseFormat::kJpegColourRvlDepth, what the
// simulator stores), and the features' 3-D points NOT stored but decoded from that depth at load
// (kPayloadPointsFromDepth), so a map has one derivation of a keyframe's points. Used by
// `zonemap import-tum` and `zonemap import-rtabmap --features orb`.
#pragma once

#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "common/status.h"
#include "localization/orb_extractor.h"
#include "mapdb/keyframe_payload.h"

namespace zm {

struct DenseKeyframeOptions {
  int jpeg_quality = 95;          // OpenCV's default, what RTAB-Map's cv::imencode(".jpg") uses
  std::uint32_t cloud_step = 5;   // the resident cloud's decimation (the simulator's default)
};

struct OrbKeyframe {
  std::vector<std::byte> payload;    // an EncodePayload blob
  std::uint32_t features = 0;
  std::uint32_t with_point = 0;      // features with a depth (the extractor's count)
  std::uint32_t resident_bytes = 0;  // what it occupies in a slot once decoded
  double extract_ms = 0.0;           // OrbExtractor::Extract alone
};

// Builds keyframe `id`'s payload from `colour` (8UC1/8UC3 BGR/8UC4 of the extractor's camera
// size) and `depth` (16UC1 at depth.units_per_m, or 32FC1 metres, same size; required: the
// payload's points come from it). `features` is the caller's reusable extractor output.
// `keypoint_scale` maps the image's pixels to the map camera's when the images are smaller
// than the calibration (RTAB-Map's decimated images): the stored keypoints are in the map
// camera's pixels, as DenseDecoder's points from depth expect.
struct KeypointScale {
  double x = 1.0;
  double y = 1.0;
};
[[nodiscard]] Result<OrbKeyframe> BuildOrbKeyframe(OrbExtractor& extractor, OrbFeatures& features,
                                                   const cv::Mat& colour, const DepthImage& depth,
                                                   KeyframeId id,
                                                   const DenseKeyframeOptions& options = {},
                                                   KeypointScale keypoint_scale = {});

}  // namespace zm
