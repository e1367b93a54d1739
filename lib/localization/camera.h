// The camera convention shared by the localizer and the simulator (which renders observations
// with the same pinhole model), so both sides agree on what a keypoint (u, v) means.
//
// Frames (all right-handed, metres, radians):
//   map / odom / body : x forward, y left, z up (REP-103). A robot pose T_map_body is a Pose3.
//   camera            : x right, y down, z forward (optical frame, REP-103 "_optical").
// The camera is mounted at the body origin looking along body +x, no tilt: so
//   T_body_cam = BodyToCamera() is a pure rotation with  x_cam = -y_body, y_cam = -z_body,
//   z_cam = +x_body. The camera pose in the map is T_map_cam = T_map_body * BodyToCamera(), and a
//   map point p is seen at p_cam = T_map_cam^-1 * p. The camera height is the pose's z.
// Pinhole without distortion: u = fx * x/z + cx, v = fy * y/z + cy; a point is visible when
//   z >= kMinDepthM and 0 <= u < width, 0 <= v < height (pixel centres at integer + 0.5 are not
//   assumed; u, v are continuous image coordinates as OpenCV's projectPoints gives them).
#pragma once

#include <Eigen/Geometry>

#include "geometry/pose.h"
#include "mapdb/map_db.h"

namespace zm {

// Points closer than this in front of the camera are not projected (not observable).
inline constexpr double kMinDepthM = 0.1;

// T_body_cam: the camera's pose in the body frame (rotation only, see the file comment).
[[nodiscard]] Pose3 BodyToCamera();

// T_map_cam for a body pose T_map_body.
[[nodiscard]] Pose3 CameraPoseInMap(const Pose3& t_map_body);

// Body pose back from a camera pose: T_map_body = T_map_cam * BodyToCamera()^-1.
[[nodiscard]] Pose3 BodyPoseFromCamera(const Pose3& t_map_cam);

// Projects a point given in the camera frame. Returns false (uv untouched) when it is behind
// the camera or closer than kMinDepthM, or falls outside the width x height image.
// The same camera at another resolution with the same field of view. With pixel i covering
// [i, i + 1) (Project's convention: the pixel holding u is floor(u)) this is a plain scale of
// fx, cx by width / k.width and fy, cy by height / k.height.
[[nodiscard]] CameraIntrinsics ScaledIntrinsics(const CameraIntrinsics& k, std::uint32_t width,
                                                std::uint32_t height);

[[nodiscard]] bool Project(const CameraIntrinsics& k, const Eigen::Vector3d& p_cam,
                           Eigen::Vector2d* uv);

}  // namespace zm
