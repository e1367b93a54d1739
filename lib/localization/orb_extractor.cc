// ORB adapter over OpenCV (see orb_extractor.h). OpenCV exceptions stop here.
#include "localization/orb_extractor.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <opencv2/core/ocl.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "localization/scratch_mat_allocator.h"

namespace zm {
namespace {

constexpr std::uint32_t kMaxOrbFeatures = 1u << 16;

std::string TypeName(int type) { return cv::typeToString(type); }

std::string Size(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

}  // namespace

std::size_t FrameScratchBytesFor(const CameraIntrinsics& camera) {
  return FrameScratchBytesFor(camera.width, camera.height);
}

Status ValidateOrbOptions(const OrbOptions& o) {
  if (o.max_features < 1 || o.max_features > kMaxOrbFeatures) {
    return InvalidArgument("orb max_features " + std::to_string(o.max_features) + " outside [1, " +
                           std::to_string(kMaxOrbFeatures) + "]");
  }
  if (o.word_features < 1 || o.word_features > o.max_features) {
    return InvalidArgument("orb word_features " + std::to_string(o.word_features) +
                           " outside [1, max_features " + std::to_string(o.max_features) + "]");
  }
  if (!(o.scale_factor > 1.0f && o.scale_factor <= 4.0f)) {
    return InvalidArgument("orb scale_factor " + std::to_string(o.scale_factor) +
                           " outside (1, 4]");
  }
  if (o.levels < 1 || o.levels > 16) {
    return InvalidArgument("orb levels " + std::to_string(o.levels) + " outside [1, 16]");
  }
  if (o.patch_size < 2 || o.patch_size > 255 || o.edge_threshold > 255) {
    return InvalidArgument("orb patch_size " + std::to_string(o.patch_size) +
                           " outside [2, 255] or edge_threshold " +
                           std::to_string(o.edge_threshold) + " > 255");
  }
  if (o.fast_threshold < 1 || o.fast_threshold > 254) {
    return InvalidArgument("orb fast_threshold " + std::to_string(o.fast_threshold) +
                           " outside [1, 254]");
  }
  if (!(o.min_depth_m >= 0.0) || !std::isfinite(o.min_depth_m) ||
      !(o.max_depth_m == 0.0 || (std::isfinite(o.max_depth_m) && o.max_depth_m > o.min_depth_m))) {
    return InvalidArgument("orb depth range [" + std::to_string(o.min_depth_m) + ", " +
                           std::to_string(o.max_depth_m) +
                           "] m: need min >= 0 and max 0 (no limit) or > min");
  }
  return Status::Ok();
}

Result<OrbExtractor> OrbExtractor::Create(const OrbOptions& options,
                                          const CameraIntrinsics& camera) {
  ZM_RETURN_IF_ERROR(ValidateOrbOptions(options));
  if (!(camera.fx > 0.0 && camera.fy > 0.0 && std::isfinite(camera.fx) &&
        std::isfinite(camera.fy) && std::isfinite(camera.cx) && std::isfinite(camera.cy)) ||
      camera.width == 0 || camera.height == 0 || camera.width > kMaxDenseSide ||
      camera.height > kMaxDenseSide) {
    return InvalidArgument("orb camera fx " + std::to_string(camera.fx) + " fy " +
                           std::to_string(camera.fy) + " size " +
                           Size(static_cast<int>(camera.width), static_cast<int>(camera.height)) +
                           ": need finite positive focal lengths and sides in [1, " +
                           std::to_string(kMaxDenseSide) + "]");
  }
  try {
    // Process-wide: OpenCV's parallel loops run on the calling thread (see the header).
    cv::setNumThreads(0);
    // No OpenCL device on the targets; probing for one would allocate in the first tick.
    cv::ocl::setUseOpenCL(false);
    UseScratchForMatData();
    cv::Ptr<cv::ORB> orb = cv::ORB::create(
        static_cast<int>(options.max_features), options.scale_factor,
        static_cast<int>(options.levels), static_cast<int>(options.edge_threshold),
        /*firstLevel=*/0, /*WTA_K=*/2, cv::ORB::HARRIS_SCORE, static_cast<int>(options.patch_size),
        static_cast<int>(options.fast_threshold));
    std::string error;
    std::unique_ptr<FrameScratch> scratch = FrameScratch::Create(
        options.scratch_bytes != 0 ? options.scratch_bytes : FrameScratchBytesFor(camera), &error);
    if (scratch == nullptr) return ResourceExhausted("orb extractor: " + error);
    OrbExtractor extractor(options, camera, std::move(orb), std::move(scratch));
    // One extraction on a synthetic textured frame, on the heap: OpenCV's one-time set-up
    // (thread-local data, lazily built tables) happens here and not in the first tick.
    cv::Mat warm(static_cast<int>(camera.height), static_cast<int>(camera.width), CV_8UC1);
    cv::randu(warm, 0, 256);
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    extractor.orb_->detectAndCompute(warm, cv::noArray(), keypoints, descriptors);
    return extractor;
  } catch (const std::exception& e) {
    return Internal(std::string("cv::ORB::create failed: ") + e.what());
  }
}

OrbExtractor::OrbExtractor(const OrbOptions& options, const CameraIntrinsics& camera,
                           cv::Ptr<cv::ORB> orb, std::unique_ptr<FrameScratch> scratch)
    : options_(options),
      camera_(camera),
      orb_(std::move(orb)),
      scratch_(std::move(scratch)),
      grey_(static_cast<int>(camera.height), static_cast<int>(camera.width), CV_8UC1),
      order_(2 * std::size_t{options.max_features}) {}

Status OrbExtractor::CheckInputs(const cv::Mat& colour, const DepthImage& depth,
                                 const OrbFeatures& out) const {
  const int w = static_cast<int>(camera_.width);
  const int h = static_cast<int>(camera_.height);
  if (colour.empty()) return InvalidArgument("colour image is empty");
  const int type = colour.type();
  if (type != CV_8UC1 && type != CV_8UC3 && type != CV_8UC4) {
    return InvalidArgument("colour image type " + TypeName(type) +
                           " not supported (8UC1 grey, 8UC3 BGR or 8UC4 BGRA)");
  }
  if (colour.cols != w || colour.rows != h) {
    return InvalidArgument("colour image " + Size(colour.cols, colour.rows) + " != camera " +
                           Size(w, h));
  }
  if (!depth.image.empty()) {
    const int dtype = depth.image.type();
    if (dtype != CV_16UC1 && dtype != CV_32FC1) {
      return InvalidArgument("depth image type " + TypeName(dtype) +
                             " not supported (16UC1 with units_per_m, or 32FC1 metres)");
    }
    if (depth.image.cols != w || depth.image.rows != h) {
      return InvalidArgument("depth image " + Size(depth.image.cols, depth.image.rows) +
                             " != colour " + Size(w, h));
    }
    if (dtype == CV_16UC1 && !(depth.units_per_m > 0.0 && std::isfinite(depth.units_per_m))) {
      return InvalidArgument("depth units_per_m " + std::to_string(depth.units_per_m) +
                             " not finite and > 0");
    }
  }
  if (out.capacity() < options_.max_features) {
    return InvalidArgument("feature buffer capacity " + std::to_string(out.capacity()) +
                           " < max_features " + std::to_string(options_.max_features));
  }
  return Status::Ok();
}

Status OrbExtractor::Extract(const cv::Mat& colour, const DepthImage& depth, OrbFeatures* out) {
  out->count = 0;
  out->word_count = 0;
  out->with_point = 0;
  ZM_RETURN_IF_ERROR(CheckInputs(colour, depth, *out));

  // Everything OpenCV allocates from here on comes from the scratch, and is freed before the
  // scope closes: the detector's outputs are locals declared after the scope.
  ScratchScope scope(*scratch_);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  try {
    const cv::Mat* grey = &colour;  // grey input is read in place, never written
    if (colour.type() != CV_8UC1) {
      cv::cvtColor(colour, grey_,
                   colour.type() == CV_8UC3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
      grey = &grey_;
    }
    orb_->detectAndCompute(*grey, cv::noArray(), keypoints, descriptors);
  } catch (const std::exception& e) {
    return Internal(std::string("ORB extraction failed: ") + e.what());
  }
  const auto detected = static_cast<std::uint32_t>(keypoints.size());
  if (detected == 0) return Status::Ok();
  if (descriptors.rows != static_cast<int>(detected) ||
      descriptors.cols != static_cast<int>(kDescriptorBytes) || descriptors.type() != CV_8UC1) {
    return Internal("ORB returned " + std::to_string(descriptors.rows) + "x" +
                    std::to_string(descriptors.cols) + " descriptors for " +
                    std::to_string(detected) + " keypoints");
  }

  // Strongest first; ties broken by position so the order never depends on OpenCV's.
  if (order_.size() < detected) order_.resize(detected);  // only if ORB exceeded 2x max_features
  for (std::uint32_t i = 0; i < detected; ++i) order_[i] = i;
  std::sort(order_.begin(), order_.begin() + detected, [&](std::uint32_t a, std::uint32_t b) {
    const cv::KeyPoint& ka = keypoints[a];
    const cv::KeyPoint& kb = keypoints[b];
    if (ka.response != kb.response) return ka.response > kb.response;
    if (ka.pt.y != kb.pt.y) return ka.pt.y < kb.pt.y;
    if (ka.pt.x != kb.pt.x) return ka.pt.x < kb.pt.x;
    return a < b;
  });
  const std::uint32_t n = std::min(detected, options_.max_features);

  const bool has_depth = !depth.image.empty();
  const bool depth16 = has_depth && depth.image.type() == CV_16UC1;
  const double inv_units = depth16 ? 1.0 / depth.units_per_m : 1.0;
  const int w = static_cast<int>(camera_.width);
  const int h = static_cast<int>(camera_.height);
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  std::uint32_t with_point = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t src = order_[i];
    const cv::KeyPoint& kp = keypoints[src];
    std::memcpy(out->descriptors[i].data(), descriptors.ptr<std::uint8_t>(static_cast<int>(src)),
                kDescriptorBytes);
    // zonemap's pixel convention (camera.h): pixel i covers [i, i + 1), so its centre is i + 0.5;
    // OpenCV puts pixel centres at integers.
    const float u = kp.pt.x + 0.5f;
    const float v = kp.pt.y + 0.5f;
    out->keypoints[2 * std::size_t{i}] = u;
    out->keypoints[2 * std::size_t{i} + 1] = v;
    out->responses[i] = kp.response;
    double z = 0.0;
    if (has_depth) {
      const int x = std::clamp(static_cast<int>(std::floor(u)), 0, w - 1);  // the pixel holding it
      const int y = std::clamp(static_cast<int>(std::floor(v)), 0, h - 1);
      z = depth16 ? depth.image.at<std::uint16_t>(y, x) * inv_units
                  : static_cast<double>(depth.image.at<float>(y, x));
    }
    const bool valid = has_depth && std::isfinite(z) && z > 0.0 && z >= options_.min_depth_m &&
                       (options_.max_depth_m == 0.0 || z <= options_.max_depth_m);
    out->has_point[i] = valid ? 1 : 0;
    float* p = &out->points[3 * std::size_t{i}];
    if (valid) {
      p[0] = static_cast<float>((static_cast<double>(u) - camera_.cx) * z / camera_.fx);
      p[1] = static_cast<float>((static_cast<double>(v) - camera_.cy) * z / camera_.fy);
      p[2] = static_cast<float>(z);
      ++with_point;
    } else {
      p[0] = p[1] = p[2] = kNan;
    }
  }
  out->count = n;
  out->word_count = std::min(n, options_.word_features);
  out->with_point = with_point;
  return Status::Ok();
}

}  // namespace zm
