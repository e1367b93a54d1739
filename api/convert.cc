// Public <-> core conversions, and the library's version.
#include "convert.h"

#include <cmath>
#include <string>

#ifndef ZM_VERSION_STRING
#define ZM_VERSION_STRING "unknown"
#endif

namespace zonemap {

const char* Version() { return ZM_VERSION_STRING; }

namespace internal {

Status ToPublic(const zm::Status& s) {
  if (s.ok()) return Status::Ok();
  StatusCode code = StatusCode::kInternal;
  switch (s.code()) {
    case zm::StatusCode::kOk: code = StatusCode::kOk; break;
    case zm::StatusCode::kInvalidArgument: code = StatusCode::kInvalidArgument; break;
    case zm::StatusCode::kNotFound: code = StatusCode::kNotFound; break;
    case zm::StatusCode::kCorrupt: code = StatusCode::kCorrupt; break;
    case zm::StatusCode::kOutOfRange: code = StatusCode::kOutOfRange; break;
    case zm::StatusCode::kResourceExhausted: code = StatusCode::kResourceExhausted; break;
    case zm::StatusCode::kFailedPrecondition: code = StatusCode::kFailedPrecondition; break;
    case zm::StatusCode::kIoError: code = StatusCode::kIoError; break;
    case zm::StatusCode::kUnsupported: code = StatusCode::kUnsupported; break;
    case zm::StatusCode::kInternal: code = StatusCode::kInternal; break;
  }
  return Status(code, s.message());
}

zm::Result<zm::Pose3> ToPose3(const Pose& p, std::string_view what) {
  const double v[7] = {p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw};
  for (double x : v) {
    if (!std::isfinite(x)) return zm::InvalidArgument(std::string(what) + " has a non-finite value");
  }
  const Eigen::Quaterniond q(p.qw, p.qx, p.qy, p.qz);
  const double norm = q.norm();
  if (norm < 0.5 || norm > 1.5) {
    return zm::InvalidArgument(std::string(what) + ": quaternion norm " + std::to_string(norm) +
                               " is not unit (accepted: [0.5, 1.5], normalised)");
  }
  zm::Pose3 out = zm::Pose3::Identity();
  out.linear() = q.normalized().toRotationMatrix();
  out.translation() = Eigen::Vector3d(p.x, p.y, p.z);
  return out;
}

Pose FromPose3(const zm::Pose3& p) {
  const Eigen::Quaterniond q(p.linear());
  const Eigen::Vector3d t = p.translation();
  return Pose{t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
}

}  // namespace internal
}  // namespace zonemap
