// ORB features from a camera image, with OpenCV's cv::ORB, and their 3-D points from the depth
// image through the pinhole model of camera.h. One extractor serves mapping, the loop and import
// (issue 26): the same options give the same features wherever an image comes from.
//
// Extract():
//   1. checks the inputs (one clear error naming the thing and the limit): colour 8UC1 (grey),
//      8UC3 (BGR) or 8UC4 (BGRA) of exactly the camera's width x height; depth empty (no 3-D
//      points) or 16UC1 (units_per_m units, 1000 for millimetres, 5000 for TUM RGB-D) or 32FC1
//      (metres) of the same size; the output buffer's capacity >= max_features;
//   2. converts to grey into a member cv::Mat (reused: no allocation after the first frame);
//   3. cv::ORB::detectAndCompute (exceptions caught here and turned into a Status);
//   4. orders the features strongest first (response, then v, then u: deterministic), so the
//      first `word_features` of them are the bag-of-words subset (RTAB-Map's Kp/MaxFeatures) and
//      all `max_features` serve verification (Vis/MaxFeatures);
//   5. for each feature, reads the depth at the nearest pixel; a depth that is zero, not finite,
//      below min_depth_m or above max_depth_m (when set) leaves the feature without a 3-D point
//      (has_point = 0, point NaN) but keeps its keypoint and descriptor.
//
// Keypoints are in zonemap's pixel convention (camera.h: pixel i covers [i, i + 1), its centre is
// i + 0.5), i.e. OpenCV's keypoint + 0.5; a calibration made in OpenCV's convention (centres at
// integers) needs 0.5 added to cx and cy to be used with them. Points are in the CAMERA frame
// (x right, y down, z forward, metres): x = (u - cx) z / fx, y = (v - cy) z / fy, the inverse
// of Project() in camera.h for the same (u, v), with the depth of the pixel holding (u, v).
//
// Allocation: the output buffer is the caller's, sized once (OrbFeatures(capacity)); the grey
// image and the ordering permutation are members reused frame after frame. What OpenCV 4.6's ORB
// allocates inside detectAndCompute on every call (its image pyramid, per-level keypoint
// vectors, the FAST/Harris scratch, the blurred levels, the keypoint and descriptor outputs:
// about 90 operator new and 30 malloc calls at 320x240) is served by the extractor's own
// FrameScratch (arena/frame_scratch.h), a region reserved once in Create() from the camera's
// size: Extract() runs OpenCV inside a ScratchScope, Mat data reaches the region through
// scratch_mat_allocator.h and operator new through the program's hook (zm_scratch_new; the
// test suites' counting allocator). A program without the hook still works: its operator new
// requests go to the heap. scratch_stats() tells how much of the region a frame used and whether
// a request ever overflowed it. Create() also runs one extraction on a synthetic image, so that
// OpenCV's one-time initialisation (thread-local data, the OpenCL probe) happens there, on the
// heap, and not in the first tick.
//
// Threads: the constructor calls cv::setNumThreads(0), a PROCESS-wide setting: OpenCV then runs
// its parallel loops on the calling thread. The tick is single-threaded by design, its time must
// not include a thread pool's wake-ups, and under qemu-user OpenCV's worker threads spin.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <opencv2/features2d.hpp>
#include <vector>

#include "arena/frame_scratch.h"
#include "common/status.h"
#include "localization/frame_scratch_size.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"

namespace zm {

// One options struct for both of RTAB-Map's limits (its guide defaults).
struct OrbOptions {
  std::uint32_t max_features = 1000;  // Vis/MaxFeatures: kept for verification (PnP)
  std::uint32_t word_features = 500;  // Kp/MaxFeatures: the strongest, quantized into words
  float scale_factor = 2.0f;          // ORB/ScaleFactor (RTAB-Map 2; OpenCV's default 1.2)
  std::uint32_t levels = 3;           // ORB/NLevels (RTAB-Map 3)
  std::uint32_t edge_threshold = 19;  // ORB/EdgeThreshold, pixels
  std::uint32_t patch_size = 31;      // ORB/PatchSize, pixels
  std::uint32_t fast_threshold = 20;  // FAST/Threshold, grey levels
  double min_depth_m = 0.1;           // nearer depths give no 3-D point (camera.h kMinDepthM)
  double max_depth_m = 0.0;           // farther depths give no 3-D point; 0 = no limit
  // The region OpenCV's per-frame allocations come from; 0 = FrameScratchBytesFor(camera).
  std::size_t scratch_bytes = 0;
};

// The scratch a frame of the camera's size needs (frame_scratch_size.h); the memory budget counts
// what the region reserves for it (budget.h).
[[nodiscard]] std::size_t FrameScratchBytesFor(const CameraIntrinsics& camera);

// Checks ranges (word_features <= max_features, scale > 1, ...); names the field and the limit.
[[nodiscard]] Status ValidateOrbOptions(const OrbOptions& options);

// The caller-owned output: fixed capacity, refilled by every Extract() without allocation.
// Feature i: descriptors[i], keypoints[2i..2i+1] = (u, v) pixels, points[3i..3i+2] = camera-frame
// metres (NaN when has_point[i] == 0), responses[i] the ORB (Harris) score.
struct OrbFeatures {
  explicit OrbFeatures(std::uint32_t capacity)
      : descriptors(capacity),
        keypoints(2 * std::size_t{capacity}),
        points(3 * std::size_t{capacity}),
        has_point(capacity),
        responses(capacity) {}
  [[nodiscard]] std::uint32_t capacity() const {
    return static_cast<std::uint32_t>(descriptors.size());
  }

  std::uint32_t count = 0;       // features written (<= capacity)
  std::uint32_t word_count = 0;  // the first min(count, word_features): the bag-of-words subset
  std::uint32_t with_point = 0;  // features with a 3-D point
  std::vector<Descriptor256> descriptors;
  std::vector<float> keypoints;
  std::vector<float> points;
  std::vector<std::uint8_t> has_point;
  std::vector<float> responses;
};

// A depth image and its units: 16UC1 values are divided by units_per_m (1000: millimetres,
// 5000: TUM RGB-D); 32FC1 values are metres and units_per_m is not used. An empty image means
// no depth (no 3-D points).
struct DepthImage {
  cv::Mat image;
  double units_per_m = 1000.0;
};

class OrbExtractor {
 public:
  // Validates the options and the camera (positive focal lengths and size), creates cv::ORB.
  [[nodiscard]] static Result<OrbExtractor> Create(const OrbOptions& options,
                                                   const CameraIntrinsics& camera);

  // Extracts the features of `colour` (and their points from `depth`) into out; see the file
  // comment. On error out->count == 0 and the Status names the input and the limit.
  [[nodiscard]] Status Extract(const cv::Mat& colour, const DepthImage& depth, OrbFeatures* out);

  [[nodiscard]] const OrbOptions& options() const { return options_; }
  [[nodiscard]] FrameScratchStats scratch_stats() const { return scratch_->stats(); }
  // The region OpenCV's per-frame work comes from, for a caller's own OpenCV calls in the tick
  // (the front-end's PNG decoding).
  [[nodiscard]] FrameScratch& scratch() { return *scratch_; }
  [[nodiscard]] const CameraIntrinsics& camera() const { return camera_; }

 private:
  OrbExtractor(const OrbOptions& options, const CameraIntrinsics& camera, cv::Ptr<cv::ORB> orb,
               std::unique_ptr<FrameScratch> scratch);
  [[nodiscard]] Status CheckInputs(const cv::Mat& colour, const DepthImage& depth,
                                   const OrbFeatures& out) const;

  OrbOptions options_;
  CameraIntrinsics camera_;
  cv::Ptr<cv::ORB> orb_;
  std::unique_ptr<FrameScratch> scratch_;  // OpenCV's per-frame allocations (never null)
  cv::Mat grey_;                           // reused conversion target
  std::vector<std::uint32_t> order_;       // strongest-first permutation
};

}  // namespace zm
