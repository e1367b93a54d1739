// PnP-RANSAC without allocation (see pnp.h): P3P hypotheses (p3p.h) scored by inlier count and
// truncated squared error, adaptive iteration count, then Levenberg-Marquardt on the inliers with
// 6x6 normal equations and an SE(3) exponential-map update, re-classifying inliers after it.
#include "localization/pnp.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "localization/p3p.h"

namespace zm {
namespace {

// Depth below which a transformed point counts as behind the camera (metres).
constexpr double kMinInlierDepth = 1e-6;
// Sample size of the minimal solver, for the adaptive iteration count.
constexpr int kSampleSize = 3;
// Refinement limits: LM iterations per round, inlier re-classification rounds.
constexpr int kLmIterations = 30;
constexpr int kRefineRounds = 3;

Eigen::Matrix3d Hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return m;
}

// SE(3) exponential of (v, w): rotation by Rodrigues, translation through the left Jacobian V.
void ExpSe3(const Eigen::Matrix<double, 6, 1>& xi, Eigen::Matrix3d* r, Eigen::Vector3d* t) {
  const Eigen::Vector3d v = xi.head<3>();
  const Eigen::Vector3d w = xi.tail<3>();
  const double theta2 = w.squaredNorm();
  const Eigen::Matrix3d wx = Hat(w);
  double a, b, c;  // R = I + a wx + b wx^2,  V = I + b wx + c wx^2
  if (theta2 < 1e-16) {
    a = 1.0 - theta2 / 6.0;
    b = 0.5 - theta2 / 24.0;
    c = 1.0 / 6.0 - theta2 / 120.0;
  } else {
    const double theta = std::sqrt(theta2);
    a = std::sin(theta) / theta;
    b = (1.0 - std::cos(theta)) / theta2;
    c = (theta - std::sin(theta)) / (theta2 * theta);
  }
  const Eigen::Matrix3d wx2 = wx * wx;
  *r = Eigen::Matrix3d::Identity() + a * wx + b * wx2;
  *t = (Eigen::Matrix3d::Identity() + b * wx + c * wx2) * v;
}

// Probability-based RANSAC bound: samples needed so that one is all-inlier with `confidence`.
int AdaptiveIterations(double confidence, double inlier_ratio, int cap) {
  const double all_inlier = std::pow(inlier_ratio, kSampleSize);
  if (all_inlier >= 1.0) return 1;
  if (all_inlier <= 0.0) return cap;
  const double denom = std::log1p(-all_inlier);
  if (!(denom < 0.0)) return cap;
  const double need = std::ceil(std::log1p(-confidence) / denom);
  if (!(need < static_cast<double>(cap))) return cap;
  return std::max(1, static_cast<int>(need));
}


// The reprojection residual (pixels) of world point `x` against its normalised ray under the
// pose (r, t), and its Jacobian for a left perturbation of the pose (translation first, then
// rotation): the one linearisation that Refine's steps and Covariance's normal matrix share.
Eigen::Vector2d Linearize(const Eigen::Matrix3d& r, const Eigen::Vector3d& t,
                          const Eigen::Vector3d& x, const Eigen::Vector3d& ray, double fx,
                          double fy, Eigen::Matrix<double, 2, 6>* j) {
  const Eigen::Vector3d p = r * x + t;
  const double iz = 1.0 / p.z();
  const double xz = p.x() * iz;
  const double yz = p.y() * iz;
  Eigen::Matrix<double, 2, 3> jp;
  jp << fx * iz, 0.0, -fx * xz * iz, 0.0, fy * iz, -fy * yz * iz;
  j->leftCols<3>() = jp;
  j->rightCols<3>() = -jp * Hat(p);
  return {fx * (xz - ray.x()), fy * (yz - ray.y())};
}

}  // namespace

const char* PnpOutcomeName(PnpOutcome outcome) {
  switch (outcome) {
    case PnpOutcome::kOk:
      return "ok";
    case PnpOutcome::kSizeMismatch:
      return "object and image point counts differ";
    case PnpOutcome::kTooFewPoints:
      return "fewer than 4 correspondences";
    case PnpOutcome::kDegenerate:
      return "every sample degenerate";
    case PnpOutcome::kNoConsensus:
      return "no hypothesis with 4 inliers";
  }
  return "unknown";
}

PnpRansac::PnpRansac(const CameraIntrinsics& camera, const PnpParams& params,
                     std::size_t reserve_points)
    : fx_(camera.fx), fy_(camera.fy), cx_(camera.cx), cy_(camera.cy), params_(params) {
  Reserve(std::max(reserve_points, kPnpMinPoints));
}

void PnpRansac::Reserve(std::size_t n) {
  // Grows once when a call exceeds the constructor's reserve; never shrinks.
  if (world_.size() >= n) return;
  world_.resize(n);
  ray_.resize(n);
  mask_.resize(n);
}

std::uint64_t PnpRansac::NextRandom() {
  // xorshift64*: tiny state, no allocation, same stream on every platform.
  rng_state_ ^= rng_state_ >> 12;
  rng_state_ ^= rng_state_ << 25;
  rng_state_ ^= rng_state_ >> 27;
  return rng_state_ * 0x2545F4914F6CDD1Dull;
}

PnpRansac::Score PnpRansac::Evaluate(const Eigen::Matrix3d& r, const Eigen::Vector3d& t,
                                     std::uint8_t* mask) const {
  const double thr2 = params_.reprojection_px * params_.reprojection_px;
  Score s;
  for (std::size_t i = 0; i < count_; ++i) {
    const Eigen::Vector3d p = r * world_[i] + t;
    double e2 = thr2;
    if (p.z() > kMinInlierDepth) {
      const double inv_z = 1.0 / p.z();
      const double du = fx_ * (p.x() * inv_z - ray_[i].x());
      const double dv = fy_ * (p.y() * inv_z - ray_[i].y());
      e2 = du * du + dv * dv;
    }
    const bool inlier = p.z() > kMinInlierDepth && e2 <= thr2;
    if (inlier) ++s.inliers;
    s.cost += std::min(e2, thr2);
    if (mask != nullptr) mask[i] = inlier ? 1 : 0;
  }
  return s;
}

void PnpRansac::Refine(Eigen::Matrix3d* r, Eigen::Vector3d* t) const {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  // Sum of squared pixel residuals of the masked points; +inf if one falls behind the camera.
  auto cost_of = [&](const Eigen::Matrix3d& rr, const Eigen::Vector3d& tt) {
    double cost = 0.0;
    for (std::size_t i = 0; i < count_; ++i) {
      if (mask_[i] == 0) continue;
      const Eigen::Vector3d p = rr * world_[i] + tt;
      if (!(p.z() > kMinInlierDepth)) return std::numeric_limits<double>::infinity();
      const double du = fx_ * (p.x() / p.z() - ray_[i].x());
      const double dv = fy_ * (p.y() / p.z() - ray_[i].y());
      cost += du * du + dv * dv;
    }
    return cost;
  };
  double cost = cost_of(*r, *t);
  double lambda = 1e-3;
  for (int it = 0; it < kLmIterations && std::isfinite(cost); ++it) {
    // Normal equations for a left perturbation T <- Exp(xi) T, xi = (v, w):
    // dp/dxi = [I, -[p]x], residual r = (fx (x/z - xn), fy (y/z - yn)).
    Mat6 h = Mat6::Zero();
    Vec6 g = Vec6::Zero();
    for (std::size_t i = 0; i < count_; ++i) {
      if (mask_[i] == 0) continue;
      Eigen::Matrix<double, 2, 6> j;
      const Eigen::Vector2d res = Linearize(*r, *t, world_[i], ray_[i], fx_, fy_, &j);
      h.noalias() += j.transpose() * j;
      g.noalias() += j.transpose() * res;
    }
    bool improved = false;
    while (!improved && lambda < 1e10) {
      Mat6 damped = h;
      damped.diagonal() += lambda * h.diagonal().cwiseMax(1e-9);
      const Vec6 xi = -damped.ldlt().solve(g);
      if (!xi.allFinite()) break;
      Eigen::Matrix3d dr;
      Eigen::Vector3d dt;
      ExpSe3(xi, &dr, &dt);
      const Eigen::Matrix3d r_new = dr * *r;
      const Eigen::Vector3d t_new = dr * *t + dt;
      const double c_new = cost_of(r_new, t_new);
      if (c_new < cost) {
        const double gain = cost - c_new;
        *r = r_new;
        *t = t_new;
        cost = c_new;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = true;
        if (xi.squaredNorm() < 1e-24 || gain <= 1e-14 * cost) return;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) return;  // no step lowers the cost: at the minimum to rounding
  }
}

void PnpRansac::Covariance(const Eigen::Matrix3d& r, const Eigen::Vector3d& t,
                           PnpSolution* sol) const {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  // The Gauss-Newton normal matrix of Refine() at the final pose (same Jacobian), and the
  // residual variance with 2 equations per inlier and 6 unknowns.
  Mat6 h = Mat6::Zero();
  double sse = 0.0;
  std::uint32_t n = 0;
  for (std::size_t i = 0; i < count_; ++i) {
    if (mask_[i] == 0) continue;
    Eigen::Matrix<double, 2, 6> j;
    const Eigen::Vector2d res = Linearize(r, t, world_[i], ray_[i], fx_, fy_, &j);
    h.noalias() += j.transpose() * j;
    sse += res.squaredNorm();
    ++n;
  }
  sol->rms_px = n > 0 ? std::sqrt(sse / n) : 0.0;
  const double dof = 2.0 * n - 6.0;
  const Eigen::FullPivLU<Mat6> lu(h);
  if (dof <= 0.0 || !lu.isInvertible()) {
    sol->covariance = Mat6::Constant(std::numeric_limits<double>::infinity());
    return;
  }
  sol->covariance = (sse / dof) * lu.inverse();
}

PnpSolution PnpRansac::Solve(std::span<const cv::Point3f> object,
                             std::span<const cv::Point2f> image) {
  PnpSolution sol;
  count_ = 0;
  if (object.size() != image.size()) {
    sol.outcome = PnpOutcome::kSizeMismatch;
    return sol;
  }
  if (object.size() < kPnpMinPoints) {
    sol.outcome = PnpOutcome::kTooFewPoints;
    return sol;
  }
  const std::size_t n = object.size();
  Reserve(n);
  count_ = n;
  for (std::size_t i = 0; i < n; ++i) {
    world_[i] = Eigen::Vector3d(static_cast<double>(object[i].x), static_cast<double>(object[i].y), static_cast<double>(object[i].z));
    ray_[i] =
        Eigen::Vector3d((static_cast<double>(image[i].x) - cx_) / fx_, (static_cast<double>(image[i].y) - cy_) / fy_, 1.0);
  }
  rng_state_ = params_.seed != 0 ? params_.seed : 1;  // xorshift state must be non-zero

  const int cap = std::max(1, params_.iterations);
  int needed = cap;
  Score best;
  bool have_model = false;
  Eigen::Matrix3d best_r = Eigen::Matrix3d::Identity();
  Eigen::Vector3d best_t = Eigen::Vector3d::Zero();
  std::array<P3pPose, 4> poses;
  int it = 0;
  for (; it < needed; ++it) {
    // Three distinct indices; Lemire's multiply-shift maps 32 random bits onto [0, n).
    std::array<std::size_t, 3> idx{};
    for (int k = 0; k < 3; ++k) {
      bool fresh = false;
      while (!fresh) {
        idx[static_cast<std::size_t>(k)] =
            static_cast<std::size_t>(((NextRandom() >> 32) * n) >> 32);
        fresh = true;
        for (int m = 0; m < k; ++m) {
          fresh = fresh && idx[static_cast<std::size_t>(m)] != idx[static_cast<std::size_t>(k)];
        }
      }
    }
    const std::array<Eigen::Vector3d, 3> world{world_[idx[0]], world_[idx[1]], world_[idx[2]]};
    const std::array<Eigen::Vector3d, 3> rays{ray_[idx[0]], ray_[idx[1]], ray_[idx[2]]};
    const int solutions = SolveP3p(world, rays, &poses);
    for (int s = 0; s < solutions; ++s) {
      const P3pPose& pose = poses[static_cast<std::size_t>(s)];
      const Score score = Evaluate(pose.r_cam_world, pose.t_cam_world, nullptr);
      if (!have_model || score.inliers > best.inliers ||
          (score.inliers == best.inliers && score.cost < best.cost)) {
        have_model = true;
        best = score;
        best_r = pose.r_cam_world;
        best_t = pose.t_cam_world;
        needed = AdaptiveIterations(
            params_.confidence, static_cast<double>(best.inliers) / static_cast<double>(n), cap);
      }
    }
  }
  sol.iterations = static_cast<std::uint32_t>(it);
  if (!have_model) {
    sol.outcome = PnpOutcome::kDegenerate;
    return sol;
  }
  best = Evaluate(best_r, best_t, mask_.data());
  if (best.inliers < kPnpMinPoints) {
    sol.outcome = PnpOutcome::kNoConsensus;
    return sol;
  }
  // Refine on the inliers, re-classify with the refined pose, and repeat while the consensus
  // grows: the minimal-sample pose misclassifies points near the threshold.
  for (int round = 0; params_.refine && round < kRefineRounds; ++round) {
    Eigen::Matrix3d r = best_r;
    Eigen::Vector3d t = best_t;
    Refine(&r, &t);
    const Score refined = Evaluate(r, t, nullptr);
    if (refined.inliers < best.inliers) break;  // keep the mask of best_r/best_t
    const bool same = refined.inliers == best.inliers;
    best_r = r;
    best_t = t;
    best = Evaluate(best_r, best_t, mask_.data());
    if (same) break;
  }
  // Re-orthonormalise: the exponential-map products drift from SO(3) only by rounding.
  const Eigen::Quaterniond q(best_r);
  sol.t_cam_map = Pose3::Identity();
  sol.t_cam_map.linear() = q.normalized().toRotationMatrix();
  sol.t_cam_map.translation() = best_t;
  sol.inliers = best.inliers;
  Covariance(sol.t_cam_map.linear(), best_t, &sol);
  sol.found = true;
  sol.outcome = PnpOutcome::kOk;
  return sol;
}

}  // namespace zm
