// The input gate's rules (see input_gate.h).
#include "runtime/input_gate.h"

#include <cmath>

#include <Eigen/Geometry>

namespace zm {

MapExtent ExtentOf(const MapIndex& index) {
  Eigen::AlignedBox3d box;  // empty until extended
  for (KfIndex k = 0; k < index.keyframe_count(); ++k) box.extend(index.position(k));
  MapExtent e;
  if (!box.isEmpty()) {
    e.min = box.min();
    e.max = box.max();
  }
  return e;
}

const char* RejectRule(RejectReason reason) {
  switch (reason) {
    case RejectReason::kStampNotIncreasing:
      return "stamp not greater than the last accepted frame's";
    case RejectReason::kStampOutOfRange:
      return "stamp not finite or beyond 2^32 s";
    case RejectReason::kQuaternionNotUnit:
      return "quaternion length beyond [input] quaternion_tolerance";
    case RejectReason::kPositionOutsideMap:
      return "position beyond the map's extent + [input] max_distance_from_map_m";
    case RejectReason::kRouteOutsideMap:
      return "a waypoint beyond the map's extent + [input] max_distance_from_map_m";
    default:
      return "";
  }
}

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

bool InputGate::AcceptFrame(double stamp_s, const Pose3& odom, double quaternion_norm,
                            const Pose3& map_from_odom, RejectReason* why) {
  const double stamp = stamp_s;
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
  if (!InsideExtent(map_from_odom * odom.translation())) {
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

void GatedFrameSource::Attach(const InputOptions& options, const MapExtent& extent,
                              const Pose3* map_from_odom) {
  gate_.emplace(options, extent);
  map_from_odom_ = map_from_odom;
}

Result<bool> GatedFrameSource::Next(Frame* frame) {
  for (;;) {
    ZM_ASSIGN_OR_RETURN(const bool more, inner_.Next(frame));
    if (!more || !gate_) return more;
    RejectReason why = RejectReason::kSyntax;
    // A recorded pose is a rotation matrix already: its quaternion is unit.
    if (gate_->AcceptFrame(*frame, 1.0, *map_from_odom_, &why)) return true;
    rejects_.Add(why);
  }
}

}  // namespace zm
