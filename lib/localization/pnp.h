// The adapter around OpenCV's solvePnPRansac (+ solvePnPRefineLM on the inliers): the only
// place the localizer touches cv::, where cv::Exception is caught and turned into a Status.
//
// Allocation: the adapter's own buffers (camera matrix, rvec/tvec, inlier indices, inlier
// subsets) are allocated once in the constructor and reused; the cv::Mat views over the
// caller's correspondences are headers only. OpenCV itself allocates inside solvePnPRansac
// (its RANSAC registrator, per-hypothesis EPnP matrices, the inlier mask) and inside
// solvePnPRefineLM; that is the one allocating step of a localization tick, bounded by the
// iteration count, and documented in docs/localization.md.
//
// Conventions: object points in the map frame (metres), image points in pixels of an
// undistorted pinhole camera (camera.h); the solution is T_cam_map (map -> camera), as OpenCV's
// rvec/tvec give it.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <span>
#include <vector>

#include "common/status.h"
#include "geometry/pose.h"
#include "mapdb/map_db.h"

namespace zm {

struct PnpParams {
  double reprojection_px = 4.0;  // RANSAC inlier threshold
  int iterations = 100;          // RANSAC iterations
  double confidence = 0.99;
  bool refine = true;  // Levenberg-Marquardt on the inliers after RANSAC
};

struct PnpSolution {
  bool found = false;  // RANSAC produced a model
  std::uint32_t inliers = 0;
  Pose3 t_cam_map = Pose3::Identity();
};

class PnpRansac {
 public:
  PnpRansac(const CameraIntrinsics& camera, const PnpParams& params, std::size_t reserve_points);
  // Solves for the camera pose. A failed RANSAC is a value (found = false); an OpenCV exception
  // is a Status naming it. Needs object.size() == image.size() >= 6.
  [[nodiscard]] Result<PnpSolution> Solve(std::span<const cv::Point3f> object,
                                          std::span<const cv::Point2f> image);

 private:
  PnpParams params_;
  cv::Mat camera_matrix_;  // 3x3 CV_64F
  cv::Mat rvec_;           // 3x1 CV_64F
  cv::Mat tvec_;           // 3x1 CV_64F
  std::vector<int> inliers_;
  std::vector<cv::Point3f> inlier_object_;
  std::vector<cv::Point2f> inlier_image_;
};

}  // namespace zm
