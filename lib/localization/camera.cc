// Camera convention (see camera.h): body x forward/y left/z up, camera x right/y down/z forward.
#include "localization/camera.h"

namespace zm {

Pose3 BodyToCamera() {
  Pose3 t = Pose3::Identity();
  Eigen::Matrix3d r;
  // Columns are the camera axes expressed in the body frame.
  r.col(0) = Eigen::Vector3d(0.0, -1.0, 0.0);  // x_cam (right)   = -y_body
  r.col(1) = Eigen::Vector3d(0.0, 0.0, -1.0);  // y_cam (down)    = -z_body
  r.col(2) = Eigen::Vector3d(1.0, 0.0, 0.0);   // z_cam (forward) = +x_body
  t.linear() = r;
  return t;
}

Pose3 CameraPoseInMap(const Pose3& t_map_body) { return t_map_body * BodyToCamera(); }

Pose3 BodyPoseFromCamera(const Pose3& t_map_cam) { return t_map_cam * BodyToCamera().inverse(); }

bool Project(const CameraIntrinsics& k, const Eigen::Vector3d& p_cam, Eigen::Vector2d* uv) {
  if (!(p_cam.z() >= kMinDepthM)) return false;  // also rejects NaN
  const double u = k.fx * p_cam.x() / p_cam.z() + k.cx;
  const double v = k.fy * p_cam.y() / p_cam.z() + k.cy;
  if (!(u >= 0.0 && v >= 0.0 && u < static_cast<double>(k.width) &&
        v < static_cast<double>(k.height))) {
    return false;
  }
  *uv = Eigen::Vector2d(u, v);
  return true;
}

CameraIntrinsics ScaledIntrinsics(const CameraIntrinsics& k, std::uint32_t width,
                                  std::uint32_t height) {
  const double sx = static_cast<double>(width) / k.width;
  const double sy = static_cast<double>(height) / k.height;
  return {.fx = k.fx * sx, .fy = k.fy * sy, .cx = k.cx * sx, .cy = k.cy * sy, .width = width,
          .height = height};
}

}  // namespace zm
