// evo-exact trajectory metrics (see metrics.h for every convention).
#include "geometry/metrics.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace zm {

Result<Association> Associate(const Trajectory& ref, const Trajectory& est, double max_dt_s) {
  Association a;
  if (!ref.has_stamps || !est.has_stamps) {
    // KITTI: no stamps, evo requires equal lengths and pairs by index.
    if (ref.size() != est.size()) {
      return InvalidArgument("trajectories without stamps (KITTI) must have equal lengths: ref " +
                             std::to_string(ref.size()) + " vs est " + std::to_string(est.size()) +
                             " poses");
    }
    a.ref_index.reserve(ref.size());
    a.est_index.reserve(ref.size());
    for (std::size_t i = 0; i < ref.size(); ++i) {
      a.ref_index.push_back(i);
      a.est_index.push_back(i);
    }
    return a;
  }
  // evo: the second trajectory (est) is "longer" only when strictly longer.
  const bool est_longer = est.size() > ref.size();
  const std::vector<double>& s_short = est_longer ? ref.stamps_s : est.stamps_s;
  const std::vector<double>& s_long = est_longer ? est.stamps_s : ref.stamps_s;
  std::vector<std::size_t>& i_short = est_longer ? a.ref_index : a.est_index;
  std::vector<std::size_t>& i_long = est_longer ? a.est_index : a.ref_index;
  if (s_long.empty()) return a;
  for (std::size_t i = 0; i < s_short.size(); ++i) {
    // Nearest stamp by linear scan semantics of numpy.argmin (first minimum). The long list is
    // not assumed sorted, exactly as evo does not assume it.
    std::size_t best = 0;
    double best_diff = std::abs(s_long[0] - s_short[i]);
    for (std::size_t j = 1; j < s_long.size(); ++j) {
      const double d = std::abs(s_long[j] - s_short[i]);
      if (d < best_diff) {
        best_diff = d;
        best = j;
      }
    }
    if (best_diff <= max_dt_s) {
      i_short.push_back(i);
      i_long.push_back(best);
    }
  }
  return a;
}

AssociatedPair Reduce(const Trajectory& ref, const Trajectory& est, const Association& assoc) {
  AssociatedPair p;
  p.ref.has_stamps = ref.has_stamps;
  p.est.has_stamps = est.has_stamps;
  for (std::size_t k = 0; k < assoc.size(); ++k) {
    p.ref.Add(ref.stamps_s[assoc.ref_index[k]], ref.poses[assoc.ref_index[k]]);
    p.est.Add(est.stamps_s[assoc.est_index[k]], est.poses[assoc.est_index[k]]);
  }
  return p;
}

Result<AlignMode> ParseAlignMode(std::string_view name) {
  if (name == "none") return AlignMode::kNone;
  if (name == "se3") return AlignMode::kSe3;
  if (name == "sim3") return AlignMode::kSim3;
  return InvalidArgument("unknown alignment '" + std::string(name) +
                         "' (expected none, se3 or sim3)");
}

const char* AlignModeName(AlignMode mode) {
  switch (mode) {
    case AlignMode::kNone:
      return "none";
    case AlignMode::kSe3:
      return "se3";
    case AlignMode::kSim3:
      return "sim3";
  }
  return "?";
}

Result<Alignment> Umeyama(std::span<const Eigen::Vector3d> est,
                          std::span<const Eigen::Vector3d> ref, bool with_scale) {
  if (est.size() != ref.size()) {
    return InvalidArgument("Umeyama needs equal point counts: " + std::to_string(est.size()) +
                           " vs " + std::to_string(ref.size()));
  }
  if (est.size() < 3) {
    return InvalidArgument("Umeyama needs at least 3 associated poses, got " +
                           std::to_string(est.size()));
  }
  const double n = static_cast<double>(est.size());
  Eigen::Vector3d mean_x = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_y = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < est.size(); ++i) {
    mean_x += est[i];
    mean_y += ref[i];
  }
  mean_x /= n;
  mean_y /= n;
  // sigma_x: variance of the (est) source points; cov_xy = 1/n sum (y - my)(x - mx)^T.
  double sigma_x = 0.0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < est.size(); ++i) {
    const Eigen::Vector3d xc = est[i] - mean_x;
    const Eigen::Vector3d yc = ref[i] - mean_y;
    sigma_x += xc.squaredNorm();
    cov += yc * xc.transpose();
  }
  sigma_x /= n;
  cov /= n;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d& u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();  // cov = U D V^T
  const Eigen::Vector3d d = svd.singularValues();
  if (!(d(1) > 1e-12 * std::max(1.0, d(0)))) {
    return InvalidArgument("Umeyama: degenerate point configuration (rank < 2)");
  }
  Eigen::Vector3d s(1.0, 1.0, 1.0);
  if (u.determinant() * v.determinant() < 0.0) s(2) = -1.0;  // reflection fix
  Alignment a;
  a.rotation = u * s.asDiagonal() * v.transpose();
  if (with_scale) {
    if (!(sigma_x > 0.0)) return InvalidArgument("Umeyama: estimate points have zero spread");
    a.scale = d.dot(s) / sigma_x;
  }
  a.translation = mean_y - a.scale * (a.rotation * mean_x);
  return a;
}

void ApplyAlignment(const Alignment& a, Trajectory* traj) {
  for (Pose3& p : traj->poses) {
    const Eigen::Vector3d t = a.scale * (a.rotation * p.translation()) + a.translation;
    const Eigen::Matrix3d r = a.rotation * p.linear();
    p.linear() = r;
    p.translation() = t;
  }
}

ErrorStats ComputeStats(std::span<const double> errors) {
  ErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  const double n = static_cast<double>(errors.size());
  double sum = 0.0;
  s.min = errors[0];
  s.max = errors[0];
  for (double e : errors) {
    sum += e;
    s.sse += e * e;
    s.min = std::min(s.min, e);
    s.max = std::max(s.max, e);
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(s.sse / n);
  double var = 0.0;
  for (double e : errors) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);  // population, like numpy.std
  std::vector<double> sorted(errors.begin(), errors.end());
  std::sort(sorted.begin(), sorted.end());
  const std::size_t mid = sorted.size() / 2;
  s.median = sorted.size() % 2 == 1 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
  return s;
}

std::vector<double> ApeTranslationErrors(const Trajectory& ref, const Trajectory& est) {
  const std::size_t n = std::min(ref.size(), est.size());
  std::vector<double> e(n);
  for (std::size_t i = 0; i < n; ++i) {
    e[i] = (est.poses[i].translation() - ref.poses[i].translation()).norm();
  }
  return e;
}

double RotationAngle(const Eigen::Matrix3d& r) {
  // acos((tr - 1) / 2) loses precision near 0 and pi; the quaternion form does not.
  const Eigen::Quaterniond q(r);
  const double vec = q.vec().norm();
  return 2.0 * std::atan2(vec, std::abs(q.w()));
}

RpeErrors RpeErrorsFor(const Trajectory& ref, const Trajectory& est, std::size_t delta_frames) {
  RpeErrors out;
  const std::size_t n = std::min(ref.size(), est.size());
  if (delta_frames == 0) return out;
  for (std::size_t i = 0; i + delta_frames < n; i += delta_frames) {
    const std::size_t j = i + delta_frames;
    const Pose3 q_rel = ref.poses[i].inverse() * ref.poses[j];
    const Pose3 p_rel = est.poses[i].inverse() * est.poses[j];
    const Pose3 e = q_rel.inverse() * p_rel;
    out.trans_m.push_back(e.translation().norm());
    out.rot_deg.push_back(RotationAngle(e.linear()) * 180.0 / std::numbers::pi);
  }
  return out;
}

Result<EvalReport> Evaluate(const Trajectory& ref, const Trajectory& est,
                            const EvalOptions& options) {
  EvalReport r;
  r.ref_poses = ref.size();
  r.est_poses = est.size();
  r.align = options.align;
  ZM_ASSIGN_OR_RETURN(Association assoc, Associate(ref, est, options.max_dt_s));
  r.associated = assoc.size();
  if (assoc.size() < 2) {
    return InvalidArgument("only " + std::to_string(assoc.size()) + " of " +
                           std::to_string(std::min(ref.size(), est.size())) +
                           " poses associated within " + std::to_string(options.max_dt_s) +
                           " s; at least 2 are needed");
  }
  AssociatedPair pair = Reduce(ref, est, assoc);
  if (options.align != AlignMode::kNone) {
    std::vector<Eigen::Vector3d> pe(pair.est.size());
    std::vector<Eigen::Vector3d> pr(pair.ref.size());
    for (std::size_t i = 0; i < pe.size(); ++i) {
      pe[i] = pair.est.poses[i].translation();
      pr[i] = pair.ref.poses[i].translation();
    }
    ZM_ASSIGN_OR_RETURN(r.alignment, Umeyama(pe, pr, options.align == AlignMode::kSim3));
    ApplyAlignment(r.alignment, &pair.est);
  }
  const std::vector<double> ape = ApeTranslationErrors(pair.ref, pair.est);
  r.ape_trans_m = ComputeStats(ape);
  const RpeErrors rpe = RpeErrorsFor(pair.ref, pair.est, options.rpe_delta_frames);
  r.rpe_trans_m = ComputeStats(rpe.trans_m);
  r.rpe_rot_deg = ComputeStats(rpe.rot_deg);
  return r;
}

}  // namespace zm
