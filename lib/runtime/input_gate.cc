// The input gate's rules (see input_gate.h).
#include "runtime/input_gate.h"

#include <cmath>

namespace zm {

InputGate::InputGate(const InputOptions& options, const MapExtent& extent)
    : options_(options), extent_(extent) {
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(options.max_distance_from_map_m);
  lo_ = extent.min - margin;
  hi_ = extent.max + margin;
}

bool InputGate::InsideExtent(const Eigen::Vector3d& p) const {
  // Written so that NaN compares false and is refused.
  return p.x() >= lo_.x() && p.x() <= hi_.x() && p.y() >= lo_.y() && p.y() <= hi_.y() &&
         p.z() >= lo_.z() && p.z() <= hi_.z();
}

bool InputGate::AcceptFrame(const Frame& frame, double quaternion_norm, const Pose3& map_from_odom,
                            RejectReason* why) {
  const double stamp = frame.stamp_s;
  if (!(std::abs(stamp) <= kMaxStampS)) {
    *why = RejectReason::kStampOutOfRange;
    return false;
  }
  if (has_stamp_ && !(stamp > last_stamp_s_)) {
    *why = RejectReason::kStampNotIncreasing;
    return false;
  }
  if (!(std::abs(quaternion_norm - 1.0) <= options_.quaternion_tolerance)) {
    *why = RejectReason::kQuaternionNotUnit;
    return false;
  }
  if (!InsideExtent(map_from_odom * frame.odom.translation())) {
    *why = RejectReason::kPositionOutsideMap;
    return false;
  }
  has_stamp_ = true;
  last_stamp_s_ = stamp;
  return true;
}

bool InputGate::AcceptRoute(std::span<const Eigen::Vector3d> waypoints) const {
  for (const Eigen::Vector3d& p : waypoints) {
    if (!InsideExtent(p)) return false;
  }
  return true;
}

}  // namespace zm
