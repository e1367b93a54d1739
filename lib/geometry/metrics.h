// Trajectory metrics with evo's exact conventions (docs/evaluation.md):
//   - association: for each stamp of the SHORTER trajectory, the nearest stamp of the longer one
//     (first minimum on ties, like numpy.argmin), kept when |dt| <= max_dt_s; not forced unique.
//     KITTI trajectories (no stamps) are paired by index and must have equal lengths.
//   - Umeyama alignment of est onto ref (SE(3), or Sim(3) with scale), with the reflection fix
//     (S = diag(1, 1, -1) when det(U) det(V) < 0).
//   - APE translation: e_i = ||R (c p_est_i) + t - p_ref_i||.
//   - RPE (delta in frames, consecutive pairs (i, i+delta) for i = 0, delta, 2 delta, ...):
//     E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), Q = ref, P = est; translation ||t(E)||, rotation
//     |log SO3(E)| (reported in degrees).
//   - statistics: rmse, mean, median (mean of the middle two for even n), std (population),
//     min, max, sse.
// Nothing here throws; degenerate inputs (too few pairs) are errors.
#pragma once

#include <cstddef>
#include <span>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "geometry/pose.h"
#include "geometry/trajectory.h"

namespace zm {

inline constexpr double kDefaultMaxDtS = 0.01;  // evo's default association tolerance

// Indices into ref and est of the associated pairs, in the order of the shorter trajectory.
struct Association {
  std::vector<std::size_t> ref_index;
  std::vector<std::size_t> est_index;
  [[nodiscard]] std::size_t size() const { return ref_index.size(); }
};
[[nodiscard]] Result<Association> Associate(const Trajectory& ref, const Trajectory& est,
                                            double max_dt_s = kDefaultMaxDtS);

// Sub-trajectories of the associated pairs (same length, pair k = element k of both).
struct AssociatedPair {
  Trajectory ref;
  Trajectory est;
};
[[nodiscard]] AssociatedPair Reduce(const Trajectory& ref, const Trajectory& est,
                                    const Association& assoc);

// x_ref ~= scale * rotation * x_est + translation.
struct Alignment {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double scale = 1.0;
};
enum class AlignMode { kNone, kSe3, kSim3 };
[[nodiscard]] Result<AlignMode> ParseAlignMode(std::string_view name);  // none|se3|sim3
[[nodiscard]] const char* AlignModeName(AlignMode mode);

// Umeyama least squares (evo's geometry.umeyama_alignment): est points onto ref points.
// Needs at least 3 pairs and non-degenerate est points.
[[nodiscard]] Result<Alignment> Umeyama(std::span<const Eigen::Vector3d> est,
                                        std::span<const Eigen::Vector3d> ref, bool with_scale);
// Applies an alignment to every pose of `traj`: p -> s R p + t, R_pose -> R R_pose.
void ApplyAlignment(const Alignment& a, Trajectory* traj);

struct ErrorStats {
  std::size_t count = 0;
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0, sse = 0;
};
// Statistics of `errors` (all zeros when empty).
[[nodiscard]] ErrorStats ComputeStats(std::span<const double> errors);

// Per-pair APE translation errors of equal-length, already associated (and aligned) poses.
[[nodiscard]] std::vector<double> ApeTranslationErrors(const Trajectory& ref,
                                                       const Trajectory& est);
struct RpeErrors {
  std::vector<double> trans_m;
  std::vector<double> rot_deg;
};
[[nodiscard]] RpeErrors RpeErrorsFor(const Trajectory& ref, const Trajectory& est,
                                     std::size_t delta_frames = 1);

// Angle of a rotation matrix, |log SO3(R)| in radians, in [0, pi].
[[nodiscard]] double RotationAngle(const Eigen::Matrix3d& r);

struct EvalOptions {
  AlignMode align = AlignMode::kNone;
  double max_dt_s = kDefaultMaxDtS;
  std::size_t rpe_delta_frames = 1;
};
struct EvalReport {
  std::size_t ref_poses = 0;
  std::size_t est_poses = 0;
  std::size_t associated = 0;
  AlignMode align = AlignMode::kNone;
  Alignment alignment;  // identity when align == kNone
  ErrorStats ape_trans_m;
  ErrorStats rpe_trans_m;
  ErrorStats rpe_rot_deg;
};
// Associates, aligns (APE and RPE are both computed on the aligned estimate, as evo does when
// asked to align), and computes APE and RPE.
[[nodiscard]] Result<EvalReport> Evaluate(const Trajectory& ref, const Trajectory& est,
                                          const EvalOptions& options = {});

}  // namespace zm
