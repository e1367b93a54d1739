// The loop's visual front-end (see front_end.h).
#include "localization/front_end.h"

#include <chrono>
#include <cstring>
#include <exception>
#include <opencv2/imgcodecs.hpp>
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
  return std::unique_ptr<FrontEnd>(new FrontEnd(
      std::move(extractor), std::move(jpeg), image,
      static_cast<double>(camera.width) / image_width, static_cast<double>(camera.height) / image_height));
}

FrontEnd::FrontEnd(OrbExtractor extractor, std::unique_ptr<DenseDecoder> jpeg,
                   const CameraIntrinsics& camera, double to_map_x, double to_map_y)
    : extractor_(std::move(extractor)),
      jpeg_(std::move(jpeg)),
      camera_(camera),
      to_map_x_(static_cast<float>(to_map_x)),
      to_map_y_(static_cast<float>(to_map_y)),
      rgb_(std::size_t{camera.width} * camera.height * 3),
      png_(static_cast<int>(camera.height), static_cast<int>(camera.width), CV_8UC3),
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
  switch (frame->colour_codec) {
    case ImageCodec::kJpeg: {
      const Status s = jpeg_->DecodeJpegRgb(frame->colour, camera_.width, camera_.height, rgb_);
      if (!s.ok()) return Status(s.code(), what() + ": " + s.message());
      const cv::Mat rgb(h, w, CV_8UC3, rgb_.data());
      cv::cvtColor(rgb, grey_, cv::COLOR_RGB2GRAY);
      break;
    }
    case ImageCodec::kPng: {
      // cv::imdecode allocates (libpng, its row buffers): inside the extractor's scratch.
      ScratchScope scope(extractor_.scratch());
      try {
        const cv::Mat buf(1, static_cast<int>(frame->colour.size()), CV_8UC1, frame->colour.data());
        cv::imdecode(buf, cv::IMREAD_COLOR, &png_);
      } catch (const std::exception& e) {
        return Corrupt(what() + " (PNG): " + e.what());
      }
      if (png_.empty()) return Corrupt(what() + " (PNG) cannot be decoded");
      if (png_.cols != w || png_.rows != h) {
        return InvalidArgument(what() + " " + std::to_string(png_.cols) + "x" +
                               std::to_string(png_.rows) + " != camera " + std::to_string(w) +
                               "x" + std::to_string(h));
      }
      cv::cvtColor(png_, grey_, cv::COLOR_BGR2GRAY);
      break;
    }
    default:
      return InvalidArgument(what() + ": codec not readable (JPEG or PNG)");
  }
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
