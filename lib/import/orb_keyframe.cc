#include "import/orb_keyframe.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <string>

#include "mapdb/dense_codec.h"
#include "mapdb/rvl.h"

namespace zm {

Result<OrbKeyframe> BuildOrbKeyframe(OrbExtractor& extractor, OrbFeatures& features,
                                     const cv::Mat& colour, const DepthImage& depth, KeyframeId id,
                                     const DenseKeyframeOptions& options,
                                     KeypointScale keypoint_scale) {
  const std::string what = "keyframe " + std::to_string(id.value);
  if (depth.image.empty()) {
    return InvalidArgument(what + ": no depth image (a keyframe's 3-D points come from its depth)");
  }
  const auto t0 = std::chrono::steady_clock::now();
  ZM_RETURN_IF_ERROR(extractor.Extract(colour, depth, &features).Annotate(what));
  const double extract_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const std::uint32_t w = static_cast<std::uint32_t>(colour.cols);
  const std::uint32_t h = static_cast<std::uint32_t>(colour.rows);

  // Colour as RGB for the JPEG encoder (the payload's colour is RGB, dense_codec.h).
  cv::Mat rgb;
  if (colour.channels() == 1) {
    cv::cvtColor(colour, rgb, cv::COLOR_GRAY2RGB);
  } else if (colour.channels() == 4) {
    cv::cvtColor(colour, rgb, cv::COLOR_BGRA2RGB);
  } else {
    cv::cvtColor(colour, rgb, cv::COLOR_BGR2RGB);
  }
  if (!rgb.isContinuous()) rgb = rgb.clone();

  // Depth in millimetres (the payload's unit): 0 = none, beyond 65.535 m = none.
  DepthImage16 mm;
  mm.width = w;
  mm.height = h;
  mm.pixels.resize(std::size_t{w} * h);
  const double to_mm = depth.image.type() == CV_32FC1 ? 1000.0 : 1000.0 / depth.units_per_m;
  for (std::uint32_t v = 0; v < h; ++v) {
    for (std::uint32_t u = 0; u < w; ++u) {
      const double raw = depth.image.type() == CV_32FC1
                             ? static_cast<double>(depth.image.at<float>(static_cast<int>(v), static_cast<int>(u)))
                             : static_cast<double>(depth.image.at<std::uint16_t>(static_cast<int>(v), static_cast<int>(u)));
      const double m = raw * to_mm;
      mm.pixels[std::size_t{v} * w + u] =
          std::isfinite(m) && m >= 0.5 && m < 65535.5 ? static_cast<std::uint16_t>(std::lround(m)) : 0;
    }
  }

  if (keypoint_scale.x != 1.0 || keypoint_scale.y != 1.0) {
    for (std::uint32_t i = 0; i < features.count; ++i) {
      features.keypoints[2 * i] =
          static_cast<float>(static_cast<double>(features.keypoints[2 * i]) * keypoint_scale.x);
      features.keypoints[2 * i + 1] =
          static_cast<float>(static_cast<double>(features.keypoints[2 * i + 1]) * keypoint_scale.y);
    }
  }
  ZM_ASSIGN_OR_RETURN(
      DenseKeyframePayload p,
      EncodeDenseKeyframe(
          id, std::span<const Descriptor256>(features.descriptors.data(), features.count),
          std::span<const float>(features.keypoints.data(), 2 * std::size_t{features.count}),
          {.rgb = std::span<const std::uint8_t>(rgb.data, rgb.total() * 3),
           .depth = &mm,
           .width = w,
           .height = h,
           .jpeg_quality = options.jpeg_quality,
           .cloud_step = options.cloud_step}));
  OrbKeyframe out;
  out.payload = std::move(p.payload);
  out.features = features.count;
  out.with_point = features.with_point;
  out.extract_ms = extract_ms;
  out.resident_bytes = p.resident_bytes;
  return out;
}

}  // namespace zm
