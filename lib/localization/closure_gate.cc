#include "localization/closure_gate.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace zm {
namespace {

// The angle of the rotation between two orientations, in [0, pi]. Not the yaw difference: a
// handheld camera's pose (a TUM recording, taken as the body) can point its x axis anywhere,
// and a yaw read off such a rotation swings by radians for a degree of pitch.
double RotationError(const Pose3& a, const Pose3& b) {
  return std::fabs(Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle());
}

}  // namespace

Status ValidateClosureGateOptions(const ClosureGateOptions& o) {
  if (!(o.base_m >= 0.0) || !(o.base_m <= 1e3))
    return InvalidArgument("closure gate base_m must be in [0, 1000] m");
  if (!(o.per_m >= 0.0) || !(o.per_m <= 10.0))
    return InvalidArgument("closure gate per_m must be in [0, 10] m per m");
  if (!(o.rotation_deg > 0.0) || !(o.rotation_deg <= 180.0))
    return InvalidArgument("closure gate rotation_deg (closure_gate_deg) must be in (0, 180]");
  if (!(o.rotation_per_m_deg >= 0.0) || !(o.rotation_per_m_deg <= 180.0))
    return InvalidArgument("closure gate rotation_per_m_deg must be in [0, 180]");
  if (o.agree < 1 || o.agree > 1000)
    return InvalidArgument("closure gate agree must be in [1, 1000]");
  return Status::Ok();
}

void ClosureGate::Advance(const Pose3& odom) {
  if (has_odom_) path_m_ += (odom.translation() - odom_.translation()).norm();
  odom_ = odom;
  has_odom_ = true;
  ++frame_;
  relocalized_ = false;
}

double ClosureGate::gate_rotation_rad() const {
  return std::min(180.0, o_.rotation_deg + o_.rotation_per_m_deg * path_m_) * std::numbers::pi /
         180.0;
}

bool ClosureGate::Check(const Pose3& t_map_body, const Pose3& predicted) {
  relocalized_ = false;
  if (!enabled() || !has_fix_) return true;
  const double err = (t_map_body.translation() - predicted.translation()).norm();
  if (err <= gate_m() && RotationError(t_map_body, predicted) <= gate_rotation_rad()) return true;

  // Inconsistent with odometry: a vote for the hypothesis it implies.
  const Pose3 correction = t_map_body * odom_.inverse();
  if (alt_votes_ > 0 && frame_ != alt_frame_) {
    const Pose3 alt_body = alt_correction_ * odom_;
    const bool agrees =
        (alt_body.translation() - t_map_body.translation()).norm() <= o_.base_m &&
        RotationError(alt_body, t_map_body) <= o_.rotation_deg * std::numbers::pi / 180.0;
    alt_votes_ = agrees ? alt_votes_ + 1 : 1;
  } else if (alt_votes_ == 0) {
    alt_votes_ = 1;
  }
  // (a second inconsistent candidate in the same frame replaces the hypothesis, no new vote)
  alt_correction_ = correction;
  alt_frame_ = frame_;
  if (alt_votes_ >= o_.agree) {
    relocalized_ = true;
    return true;
  }
  return false;
}

void ClosureGate::Accepted() {
  has_fix_ = true;
  path_m_ = 0.0;
  alt_votes_ = 0;
}

}  // namespace zm
