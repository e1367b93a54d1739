// The loop's visual front-end (see front_end.h).
#include "localization/front_end.h"

#include <chrono>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <string>

#include "arena/frame_scratch.h"
#include "common/elapsed.h"

namespace zm {

using Clock = std::chrono::steady_clock;

Result<std::unique_ptr<FrontEnd>> FrontEnd::Create(const OrbOptions& options,
                                                   const CameraIntrinsics& camera,
                                                   std::uint32_t image_width,
                                                   std::uint32_t image_height) {
  if (image_width == 0 || image_height == 0) {
    image_width = camera.width;
    image_height = camera.height;
  }
  const CameraIntrinsics image = ScaledIntrinsics(camera, image_width, image_height);
  ZM_ASSIGN_OR_RETURN(OrbExtractor extractor, OrbExtractor::Create(options, image));
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<DenseDecoder> jpeg, DenseDecoder::Create(image));
  ZM_ASSIGN_OR_RETURN(std::unique_ptr<PngDecoder> png, PngDecoder::Create());
  return std::unique_ptr<FrontEnd>(new FrontEnd(std::move(extractor), std::move(jpeg),
                                                std::move(png), image,
                                                static_cast<double>(camera.width) / image_width,
                                                static_cast<double>(camera.height) / image_height));
}

FrontEnd::FrontEnd(OrbExtractor extractor, std::unique_ptr<DenseDecoder> jpeg,
                   std::unique_ptr<PngDecoder> png, const CameraIntrinsics& camera, double to_map_x,
                   double to_map_y)
    : extractor_(std::move(extractor)),
      jpeg_(std::move(jpeg)),
      png_(std::move(png)),
      camera_(camera),
      to_map_x_(static_cast<float>(to_map_x)),
      to_map_y_(static_cast<float>(to_map_y)),
      rgb_(std::size_t{camera.width} * camera.height * 3),
      grey_(static_cast<int>(camera.height), static_cast<int>(camera.width), CV_8UC1),
      features_(extractor_.options().max_features) {}

Status FrontEnd::Process(Frame* frame, FrontEndTimes* times) {
  frame->descriptors.clear();
  frame->keypoints.clear();
  *times = {};
  const auto what = [&] { return "frame " + std::to_string(frame->index) + ": colour image"; };
  if (frame->colour.empty()) return InvalidArgument(what() + " is empty");
  const int w = static_cast<int>(camera_.width);
  const int h = static_cast<int>(camera_.height);
  auto t0 = Clock::now();
  Status decoded;
  switch (frame->colour_codec) {
    case ImageCodec::kJpeg:
      decoded = jpeg_->DecodeJpegRgb(frame->colour, camera_.width, camera_.height, rgb_);
      break;
    case ImageCodec::kPng:
      decoded = png_->DecodeRgb(frame->colour, camera_.width, camera_.height, rgb_);
      break;
    default:
      return InvalidArgument(what() + ": codec not readable (JPEG or PNG)");
  }
  if (!decoded.ok()) return Status(decoded.code(), what() + ": " + decoded.message());
  cv::cvtColor(cv::Mat(h, w, CV_8UC3, rgb_.data()), grey_, cv::COLOR_RGB2GRAY);
  times->decode_ms = MsSince(t0);
  t0 = Clock::now();
  const Status s = extractor_.Extract(grey_, {}, &features_);
  times->extract_ms = MsSince(t0);
  if (!s.ok()) return Status(s.code(), "frame " + std::to_string(frame->index) + ": " + s.message());
  const std::uint32_t n = features_.count;
  frame->descriptors.resize(n);
  frame->keypoints.resize(2 * std::size_t{n});
  if (n > 0) {
    std::memcpy(frame->descriptors.data(), features_.descriptors.data(), n * kDescriptorBytes);
    for (std::size_t i = 0; i < n; ++i) {
      frame->keypoints[2 * i] = features_.keypoints[2 * i] * to_map_x_;
      frame->keypoints[2 * i + 1] = features_.keypoints[2 * i + 1] * to_map_y_;
    }
  }
  return Status::Ok();
}

}  // namespace zm
