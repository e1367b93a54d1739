// The camera convention the simulator shares: body x forward / y left / z up, camera x right /
// y down / z forward, pinhole projection.
#include "localization/camera.h"

#include <doctest/doctest.h>

#include "localization/localizer.h"

namespace zm {
namespace {

const CameraIntrinsics kCam{500.0, 500.0, 320.0, 240.0, 640, 480};

Eigen::Vector3d BodyPointInCamera(const Pose3& t_map_body, const Eigen::Vector3d& p_map) {
  return CameraPoseInMap(t_map_body).inverse() * p_map;
}

TEST_CASE("body to camera: ahead is the image centre, left is u < cx, up is v < cy") {
  const Pose3 body = Pose3::Identity();
  Eigen::Vector2d uv;
  REQUIRE(Project(kCam, BodyPointInCamera(body, {5, 0, 0}), &uv));
  CHECK(uv.x() == doctest::Approx(320.0));
  CHECK(uv.y() == doctest::Approx(240.0));
  REQUIRE(Project(kCam, BodyPointInCamera(body, {5, 1, 0}), &uv));
  CHECK(uv.x() == doctest::Approx(320.0 - 100.0));  // left of the robot: left in the image
  REQUIRE(Project(kCam, BodyPointInCamera(body, {5, 0, 1}), &uv));
  CHECK(uv.y() == doctest::Approx(240.0 - 100.0));                         // above: up in the image
  CHECK_FALSE(Project(kCam, BodyPointInCamera(body, {-5, 0, 0}), &uv));    // behind
  CHECK_FALSE(Project(kCam, BodyPointInCamera(body, {0.05, 0, 0}), &uv));  // too close
  CHECK_FALSE(Project(kCam, BodyPointInCamera(body, {1, 5, 0}), &uv));     // outside the image
  CHECK(BodyToCamera().linear().determinant() == doctest::Approx(1.0));
}

TEST_CASE("camera pose follows the body pose and the body pose comes back") {
  const Pose3 body = PoseFromXYYaw(3.0, -2.0, 1.2, 0.4);
  const Pose3 cam = CameraPoseInMap(body);
  CHECK((BodyPoseFromCamera(cam).matrix() - body.matrix()).norm() < 1e-12);
  // Camera optical axis (z) is the body's forward axis (x) in the map.
  CHECK((cam.linear().col(2) - body.linear().col(0)).norm() < 1e-12);
  Eigen::Vector2d uv;
  const Eigen::Vector3d ahead = body * Eigen::Vector3d(4, 0, 0);
  REQUIRE(Project(kCam, cam.inverse() * ahead, &uv));
  CHECK(uv.x() == doctest::Approx(320.0));
}

TEST_CASE("odometry correction: T_map_odom * odom recovers the map pose") {
  const Pose3 truth = PoseFromXYYaw(10.0, 1.0, 0.3);
  const Pose3 odom = PoseFromXYYaw(9.0, 2.5, 0.1);  // drifted
  const Pose3 t_map_cam = CameraPoseInMap(truth);   // what an exact PnP returns
  const Pose3 corr = MapFromOdomCorrection(t_map_cam, odom);
  CHECK(((corr * odom).matrix() - truth.matrix()).norm() < 1e-12);
}

}  // namespace
}  // namespace zm
