// OpenCV PnP-RANSAC adapter (see pnp.h): catches cv::Exception, converts rvec/tvec to a Pose3.
#include "localization/pnp.h"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <string>

namespace zm {

PnpRansac::PnpRansac(const CameraIntrinsics& camera, const PnpParams& params,
                     std::size_t reserve_points)
    : params_(params),
      camera_matrix_(cv::Mat::eye(3, 3, CV_64F)),
      rvec_(cv::Mat::zeros(3, 1, CV_64F)),
      tvec_(cv::Mat::zeros(3, 1, CV_64F)) {
  camera_matrix_.at<double>(0, 0) = camera.fx;
  camera_matrix_.at<double>(1, 1) = camera.fy;
  camera_matrix_.at<double>(0, 2) = camera.cx;
  camera_matrix_.at<double>(1, 2) = camera.cy;
  inliers_.reserve(reserve_points);
  inlier_object_.reserve(reserve_points);
  inlier_image_.reserve(reserve_points);
}

Result<PnpSolution> PnpRansac::Solve(std::span<const cv::Point3f> object,
                                     std::span<const cv::Point2f> image) {
  PnpSolution sol;
  if (object.size() != image.size() || object.size() < 6) {
    return InvalidArgument("PnP needs matching point counts >= 6, got " +
                           std::to_string(object.size()) + " and " + std::to_string(image.size()));
  }
  const int n = static_cast<int>(object.size());
  // Headers over the caller's arrays (no copy); OpenCV reads them as 1-column point sets.
  const cv::Mat obj(n, 1, CV_32FC3, const_cast<cv::Point3f*>(object.data()));
  const cv::Mat img(n, 1, CV_32FC2, const_cast<cv::Point2f*>(image.data()));
  try {
    inliers_.clear();
    const bool ok =
        cv::solvePnPRansac(obj, img, camera_matrix_, cv::noArray(), rvec_, tvec_, false,
                           params_.iterations, static_cast<float>(params_.reprojection_px),
                           params_.confidence, inliers_, cv::SOLVEPNP_EPNP);
    if (!ok || inliers_.size() < 4) return sol;
    if (params_.refine && inliers_.size() >= 6) {
      inlier_object_.clear();
      inlier_image_.clear();
      for (int i : inliers_) {
        inlier_object_.push_back(object[static_cast<std::size_t>(i)]);
        inlier_image_.push_back(image[static_cast<std::size_t>(i)]);
      }
      cv::solvePnPRefineLM(inlier_object_, inlier_image_, camera_matrix_, cv::noArray(), rvec_,
                           tvec_);
    }
  } catch (const cv::Exception& e) {
    return Internal(std::string("OpenCV solvePnPRansac failed: ") + e.what());
  }
  // Rodrigues vector -> rotation (Eigen, no allocation).
  const Eigen::Vector3d r(rvec_.at<double>(0), rvec_.at<double>(1), rvec_.at<double>(2));
  const Eigen::Vector3d t(tvec_.at<double>(0), tvec_.at<double>(1), tvec_.at<double>(2));
  if (!r.allFinite() || !t.allFinite()) return sol;
  const double angle = r.norm();
  sol.t_cam_map = Pose3::Identity();
  if (angle > 1e-12) {
    sol.t_cam_map.linear() = Eigen::AngleAxisd(angle, r / angle).toRotationMatrix();
  }
  sol.t_cam_map.translation() = t;
  sol.found = true;
  sol.inliers = static_cast<std::uint32_t>(inliers_.size());
  return sol;
}

}  // namespace zm
