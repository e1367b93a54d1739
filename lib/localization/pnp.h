// PnP-RANSAC of our own: a P3P minimal solver (p3p.h) inside a seeded RANSAC, then a
// Levenberg-Marquardt refinement of the pose on the inliers. It replaces the former adapter over
// OpenCV's solvePnPRansac (EPnP) + solvePnPRefineLM, which allocated on every call and so broke
// invariant 2 (docs/design.md) on every tick that verified a loop-closure candidate.
//
// Allocation: every buffer (points in double precision, normalised image rays, the inlier masks)
// is sized in the constructor from reserve_points. A call with more points grows them once; a
// call within the capacity allocates nothing (tests/localization/pnp_test.cc counts operator new
// and malloc). All solver scratch is fixed-size Eigen (no Eigen::MatrixXd) or on the stack.
//
// Determinism: the RNG (xorshift) is reseeded from PnpParams::seed at every Solve(), so the same
// input gives the same pose and inliers whatever ran before.
//
// Conventions: object points in the map frame (metres), image points in pixels of the undistorted
// pinhole camera of camera.h; the solution is T_cam_map (map -> camera), as OpenCV's rvec/tvec
// gave it. A point is an inlier when it lies in front of the camera and its reprojection error is
// at most reprojection_px pixels (OpenCV's test, plus the cheirality check).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core/types.hpp>
#include <span>
#include <vector>

#include "geometry/pose.h"
#include "mapdb/map_db.h"

namespace zm {

// Fewest correspondences Solve() accepts: a 3-point sample plus one point that can disagree.
inline constexpr std::size_t kPnpMinPoints = 4;

struct PnpParams {
  double reprojection_px = 4.0;  // RANSAC inlier threshold, pixels
  int iterations = 100;          // RANSAC iterations at most (fewer once confidence is reached)
  double confidence = 0.99;      // adaptive stop: P(at least one all-inlier sample)
  bool refine = true;            // Levenberg-Marquardt on the inliers after RANSAC
  std::uint64_t seed = 0x9E3779B97F4A7C15ull;  // RNG seed, reapplied at every Solve()
};

// Why a Solve() found no pose (kOk when it did). Values, never exceptions.
enum class PnpOutcome : std::uint8_t {
  kOk,
  kSizeMismatch,  // object and image spans differ in length
  kTooFewPoints,  // fewer than kPnpMinPoints correspondences
  kDegenerate,    // every sample was degenerate (collinear or coincident points) or had no root
  kNoConsensus,   // hypotheses existed but none had kPnpMinPoints inliers
};

[[nodiscard]] const char* PnpOutcomeName(PnpOutcome outcome);

struct PnpSolution {
  bool found = false;  // RANSAC produced a model with >= kPnpMinPoints inliers
  PnpOutcome outcome = PnpOutcome::kNoConsensus;
  std::uint32_t inliers = 0;     // of the final (refined) pose
  std::uint32_t iterations = 0;  // RANSAC samples drawn
  Pose3 t_cam_map = Pose3::Identity();
  // Uncertainty of t_cam_map from the normal equations on the inliers: sigma^2 (J^T J)^-1 for a
  // left perturbation t_cam_map <- Exp(xi) t_cam_map, xi = (v, w) (metres, radians; the LM
  // refinement's parametrisation), sigma^2 = sum of squared pixel residuals / (2 inliers - 6).
  // Only reprojection noise is in it (not map-point noise): a lower bound on the true spread.
  // Not finite when J^T J is singular.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  double rms_px = 0.0;  // RMS reprojection error over the inliers
};

class PnpRansac {
 public:
  PnpRansac(const CameraIntrinsics& camera, const PnpParams& params, std::size_t reserve_points);

  // Solves for the camera pose (see the file comment). Every failure is a value in the result.
  [[nodiscard]] PnpSolution Solve(std::span<const cv::Point3f> object,
                                  std::span<const cv::Point2f> image);

  // Inlier flags (1 = inlier) of the last Solve(), one per correspondence; empty before the first.
  [[nodiscard]] std::span<const std::uint8_t> inlier_mask() const { return {mask_.data(), count_}; }
  [[nodiscard]] const PnpParams& params() const { return params_; }

 private:
  struct Score {
    std::uint32_t inliers = 0;
    double cost = 0.0;  // sum of squared pixel errors, each truncated at the threshold (MSAC)
  };
  // Counts inliers of (r, t) over all points; writes the mask when `mask` is non-null.
  Score Evaluate(const Eigen::Matrix3d& r, const Eigen::Vector3d& t, std::uint8_t* mask) const;
  // Levenberg-Marquardt on the points flagged in mask_; updates (r, t) in place.
  void Refine(Eigen::Matrix3d* r, Eigen::Vector3d* t) const;
  // PnpSolution::covariance and rms_px of (r, t) over the points flagged in mask_.
  void Covariance(const Eigen::Matrix3d& r, const Eigen::Vector3d& t, PnpSolution* sol) const;
  void Reserve(std::size_t n);
  std::uint64_t NextRandom();

  double fx_, fy_, cx_, cy_;
  PnpParams params_;
  std::uint64_t rng_state_ = 1;
  std::size_t count_ = 0;               // correspondences of the last Solve()
  std::vector<Eigen::Vector3d> world_;  // object points, metres (double)
  std::vector<Eigen::Vector3d> ray_;    // ((u-cx)/fx, (v-cy)/fy, 1)
  std::vector<std::uint8_t> mask_;      // inliers of the current pose
};

}  // namespace zm
