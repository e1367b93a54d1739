// The consistency check on verified loop closures: a closure must agree with odometry.
//
// PnP on a repeated poster or an identical ward verifies just as well as on the right place
// (issue 26's aliasing: 4.8 m and 9.6 m jumps between identical décor), so inliers alone cannot
// reject it. RTAB-Map rejects such closures after optimising the graph (RGBD/OptimizeMaxError:
// a link whose error is too large for its covariance); with a fixed map and one pose to correct
// the same test is simpler: the closure's body pose must lie within what odometry can have
// drifted since the last accepted closure,
//
//   |t_closure - t_predicted| <= base_m + per_m * path,
//   angle(R_closure^T R_predicted) <= rotation_deg + rotation_per_m_deg * path
//
// where path is the odometry path length since that closure. Before the first closure there is
// no prior and everything is accepted (start-up, a robot placed anywhere).
//
// A gate that only grows with distance would lock a robot out after one wrong closure (or a
// kidnapping): every right closure would then be "inconsistent" until the gate had grown to the
// jump. So the rejected closures are themselves a hypothesis: when `agree` of them, on different
// ticks and in a row, put the robot at the same place (within base_m of one another through
// odometry), the map is trusted over odometry and the last one is accepted (re-localization).
// Aliasing seldom does that: consecutive frames see different décor.
//
// No allocation; one object per localizer; all of it is O(1) per call.
#pragma once

#include <cstdint>

#include "common/status.h"
#include "geometry/pose.h"

namespace zm {

struct ClosureGateOptions {
  double base_m = 0.5;              // 0: the check is off (every verified closure is accepted)
  double per_m = 0.1;               // metres of allowed disagreement per metre travelled
  double rotation_deg = 15.0;       // the angle between the two orientations (any axis)
  double rotation_per_m_deg = 1.0;  // degrees per metre travelled
  std::uint32_t agree = 3;          // rejected closures in a row that agree: re-localize
};

[[nodiscard]] Status ValidateClosureGateOptions(const ClosureGateOptions& o);

class ClosureGate {
 public:
  explicit ClosureGate(ClosureGateOptions options) : o_(options) {}

  // Once per frame, before Check: the odometry pose (body in the odom frame).
  void Advance(const Pose3& odom);

  // Whether a verified closure putting the body at t_map_body is accepted, given the pose
  // odometry predicts. A closure the gate accepts by agreement (re-localization) returns true
  // with relocalized() set. Call Accepted() when the caller takes it.
  [[nodiscard]] bool Check(const Pose3& t_map_body, const Pose3& predicted);
  void Accepted();

  [[nodiscard]] bool enabled() const { return o_.base_m > 0.0; }
  [[nodiscard]] bool has_fix() const { return has_fix_; }
  [[nodiscard]] bool relocalized() const { return relocalized_; }
  [[nodiscard]] double path_since_fix_m() const { return path_m_; }
  [[nodiscard]] double gate_m() const { return o_.base_m + o_.per_m * path_m_; }
  [[nodiscard]] double gate_rotation_rad() const;
  [[nodiscard]] const ClosureGateOptions& options() const { return o_; }

 private:
  ClosureGateOptions o_;
  bool has_fix_ = false;
  bool has_odom_ = false;
  bool relocalized_ = false;
  Pose3 odom_ = Pose3::Identity();  // this frame's
  double path_m_ = 0.0;
  std::uint64_t frame_ = 0;  // Advance() calls
  // The rejected closures' own hypothesis: the correction T_map_odom they imply, how many in a
  // row agree with it, and the frame of the last one (one vote per frame).
  Pose3 alt_correction_ = Pose3::Identity();
  std::uint32_t alt_votes_ = 0;
  std::uint64_t alt_frame_ = 0;
};

}  // namespace zm
