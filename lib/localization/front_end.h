// The loop's visual front-end (issue 26 §2): a camera frame's encoded colour image in, its ORB
// features out, inside the tick. One OrbExtractor (orb_extractor.h) with the map's options, so
// the loop's features are the mapping's.
//
// Process(frame):
//   1. decodes frame->colour (JPEG: libjpeg-turbo with fixed pools, DenseDecoder; PNG: libpng
//      with a fixed pool, PngDecoder) into an RGB buffer of the camera's size, reserved once;
//   2. converts it to grey and runs the extractor (depth is not needed: the localizer matches
//      the frame's 2-D keypoints to the resident keyframes' 3-D points);
//   3. writes the strongest max_features features into frame->descriptors / keypoints (strongest
//      first, so the first word_features are the frame's words), the keypoints in the map
//      camera's pixels: images may come at a lower resolution with the same field of view (the
//      simulator's scaled footprint), and zonemap's pixel convention makes that a plain scale
//      (camera.h: pixel i covers [i, i + 1)).
//
// Bad input (an empty, truncated, undecodable or wrong-size image, a codec it does not read) is
// one Status naming the frame, the image and the limit; the frame is left without features, so
// the loop goes on on odometry and counts the frame as refused.
//
// Allocation: the RGB and grey buffers are sized once; JPEG and PNG decoding run in their
// decoders' fixed pools; OpenCV's work runs inside the extractor's FrameScratch. A warm Process
// allocates nothing from the heap (tests/localization/front_end_test.cc).
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "common/status.h"
#include "localization/camera.h"
#include "localization/frame.h"
#include "localization/orb_extractor.h"
#include "mapdb/dense_codec.h"
#include "mapdb/png_decoder.h"

namespace zm {

struct FrontEndTimes {
  double decode_ms = 0.0;
  double extract_ms = 0.0;
};

class FrontEnd {
 public:
  // camera: the map's keypoint camera; images are image_width x image_height (0: the camera's).
  [[nodiscard]] static Result<std::unique_ptr<FrontEnd>> Create(const OrbOptions& options,
                                                                const CameraIntrinsics& camera,
                                                                std::uint32_t image_width = 0,
                                                                std::uint32_t image_height = 0);

  // See the file comment. frame->descriptors / keypoints must have capacity for max_features
  // (Frame::Reserve): they are refilled without allocation.
  [[nodiscard]] Status Process(Frame* frame, FrontEndTimes* times);

  [[nodiscard]] const OrbExtractor& extractor() const { return extractor_; }
  [[nodiscard]] const CameraIntrinsics& image_camera() const { return camera_; }

 private:
  FrontEnd(OrbExtractor extractor, std::unique_ptr<DenseDecoder> jpeg,
           std::unique_ptr<PngDecoder> png, const CameraIntrinsics& image_camera, double to_map_x,
           double to_map_y);

  OrbExtractor extractor_;
  std::unique_ptr<DenseDecoder> jpeg_;
  std::unique_ptr<PngDecoder> png_;
  CameraIntrinsics camera_;  // the image's (the map camera scaled to the image size)
  float to_map_x_ = 1.0f;    // image pixels -> map camera pixels
  float to_map_y_ = 1.0f;
  std::vector<std::uint8_t> rgb_;  // width * height * 3
  cv::Mat grey_;
  OrbFeatures features_;
};

}  // namespace zm
