// Poses: SE(3) as Eigen::Isometry3d (map frame, metres, radians). Header-only helpers shared by
// every module; trajectory I/O and metrics live beside this file.
#pragma once

#include <Eigen/Geometry>
#include <cmath>

namespace zm {

using Pose3 = Eigen::Isometry3d;

// Planar pose (x, y, yaw) lifted to SE(3) at height z.
inline Pose3 PoseFromXYYaw(double x, double y, double yaw, double z = 0.0) {
  Pose3 p = Pose3::Identity();
  p.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.translation() = Eigen::Vector3d(x, y, z);
  return p;
}

// Heading about the map's z axis, in (-pi, pi].
inline double Yaw(const Pose3& p) { return std::atan2(p.linear()(1, 0), p.linear()(0, 0)); }

}  // namespace zm
