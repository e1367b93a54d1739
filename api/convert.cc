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

zm::Result<GatedPose> ToPose3(const Pose& p, std::string_view what) {
  const double v[7] = {p.x, p.y, p.z, p.qx, p.qy, p.qz, p.qw};
  for (double x : v) {
    if (!std::isfinite(x)) return zm::InvalidArgument(std::string(what) + " has a non-finite value");
  }
  const Eigen::Quaterniond q(p.qw, p.qx, p.qy, p.qz);
  GatedPose out;
  out.quaternion_norm = q.norm();
  // A zero quaternion is no rotation: left as identity here, refused by the gate (its norm).
  if (out.quaternion_norm > 1e-12) out.pose.linear() = q.normalized().toRotationMatrix();
  out.pose.translation() = Eigen::Vector3d(p.x, p.y, p.z);
  return out;
}

Pose FromPose3(const zm::Pose3& p) {
  const Eigen::Quaterniond q(p.linear());
  const Eigen::Vector3d t = p.translation();
  return Pose{t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
}

zm::Result<zm::Profile> ProfileOrDefaults(const std::string& name_or_path) {
  if (!name_or_path.empty()) return zm::LoadProfile(name_or_path);
  zm::Profile p;
  p.source = std::string(kNoProfileSource);
  return p;
}

}  // namespace internal
}  // namespace zonemap
