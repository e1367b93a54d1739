// The closure gate (localization/closure_gate.h): verified closures must agree with odometry;
// rejected ones that agree with one another re-localize.
#include "localization/closure_gate.h"

#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "geometry/pose.h"

namespace zm {
namespace {

// A robot driving along x at 0.5 m a frame, odometry exact: the prediction is the true pose.
Pose3 Odom(int frame) { return PoseFromXYYaw(0.5 * frame, 0.0, 0.0); }

TEST_CASE("closure gate: the first closure is taken, then only those odometry can explain") {
  ClosureGate gate(
      {.base_m = 0.5, .per_m = 0.1, .rotation_deg = 15.0, .rotation_per_m_deg = 1.0, .agree = 3});
  gate.Advance(Odom(0));
  CHECK_FALSE(gate.has_fix());
  // No prior: even a pose 30 m away is accepted (a robot placed anywhere).
  CHECK(gate.Check(PoseFromXYYaw(30.0, 0.0, 0.0), Odom(0)));
  gate.Accepted();
  CHECK(gate.has_fix());
  CHECK(gate.path_since_fix_m() == doctest::Approx(0.0));

  gate.Advance(Odom(1));
  CHECK(gate.path_since_fix_m() == doctest::Approx(0.5));
  CHECK(gate.gate_m() == doctest::Approx(0.55));
  // 0.3 m off the prediction: within 0.55 m.
  CHECK(gate.Check(PoseFromXYYaw(0.8, 0.0, 0.0), Odom(1)));
  // A repeated poster 4.8 m away: refused, and so is a right place turned by 40 degrees.
  CHECK_FALSE(gate.Check(PoseFromXYYaw(5.3, 0.0, 0.0), Odom(1)));
  CHECK_FALSE(gate.Check(PoseFromXYYaw(0.5, 0.0, 40.0 * M_PI / 180.0), Odom(1)));
}

TEST_CASE("closure gate: the gate grows with the path since the last closure") {
  ClosureGate gate(
      {.base_m = 0.5, .per_m = 0.1, .rotation_deg = 15.0, .rotation_per_m_deg = 1.0, .agree = 3});
  gate.Advance(Odom(0));
  REQUIRE(gate.Check(Odom(0), Odom(0)));
  gate.Accepted();
  for (int f = 1; f <= 60; ++f) gate.Advance(Odom(f));  // 30 m without a closure
  CHECK(gate.gate_m() == doctest::Approx(3.5));
  CHECK(gate.Check(PoseFromXYYaw(30.0 + 3.0, 0.0, 0.0), Odom(60)));  // 3 m of drift: explained
  gate.Accepted();
  gate.Advance(Odom(61));
  CHECK(gate.gate_m() == doctest::Approx(0.55));  // and back to tight after it
}

TEST_CASE(
    "closure gate: rejected closures that agree on three frames re-localize, aliasing does not") {
  ClosureGate gate(
      {.base_m = 0.5, .per_m = 0.1, .rotation_deg = 15.0, .rotation_per_m_deg = 1.0, .agree = 3});
  gate.Advance(Odom(0));
  REQUIRE(gate.Check(Odom(0), Odom(0)));
  gate.Accepted();
  // The odometry-predicted pose is wrong by 6 m (a wrong closure before, or a kidnapping): the
  // map keeps saying the robot is 6 m further on.
  const auto truth = [](int f) { return PoseFromXYYaw(0.5 * f + 6.0, 0.0, 0.0); };
  gate.Advance(Odom(1));
  CHECK_FALSE(gate.Check(truth(1), Odom(1)));
  // A second inconsistent candidate in the same frame is no second vote.
  CHECK_FALSE(gate.Check(truth(1), Odom(1)));
  gate.Advance(Odom(2));
  CHECK_FALSE(gate.Check(truth(2), Odom(2)));
  gate.Advance(Odom(3));
  CHECK(gate.Check(truth(3), Odom(3)));
  CHECK(gate.relocalized());
  gate.Accepted();

  // Aliasing: the rejected closures jump between places (+4.8 m, -4.8 m, +9.6 m): never agree.
  gate.Advance(Odom(4));
  CHECK(gate.Check(truth(4), truth(4)));  // the right one, predicted right
  gate.Accepted();
  const double jumps[] = {4.8, -4.8, 9.6, 4.8, -9.6, 4.8};
  int f = 5;
  for (double j : jumps) {
    gate.Advance(Odom(f));
    const Pose3 predicted = PoseFromXYYaw(0.5 * f + 6.0, 0.0, 0.0);
    CHECK_FALSE(gate.Check(PoseFromXYYaw(0.5 * f + 6.0 + j, 0.0, 0.0), predicted));
    ++f;
  }
}

TEST_CASE("closure gate: orientations compared by the angle between them, not by yaw") {
  // A handheld camera taken as the body (a TUM recording): looking down 85 degrees, so its x
  // axis is nearly vertical and a yaw read off it swings by radians for a degree of pitch.
  const auto pose = [](double x, double pitch_deg) {
    Pose3 p = Pose3::Identity();
    p.linear() =
        Eigen::AngleAxisd(pitch_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
    p.translation() = Eigen::Vector3d(x, 0.0, 1.0);
    return p;
  };
  ClosureGate gate(
      {.base_m = 0.5, .per_m = 0.1, .rotation_deg = 15.0, .rotation_per_m_deg = 1.0, .agree = 3});
  gate.Advance(pose(0.0, 85.0));
  REQUIRE(gate.Check(pose(0.0, 85.0), pose(0.0, 85.0)));
  gate.Accepted();
  gate.Advance(pose(0.1, 85.0));
  CHECK(gate.Check(pose(0.1, 87.0), pose(0.1, 85.0)));               // 2 degrees of PnP noise
  CHECK_FALSE(gate.Check(pose(0.1, 85.0 - 40.0), pose(0.1, 85.0)));  // 40 degrees: not this place
}

TEST_CASE("closure gate: base_m 0 turns it off, options are checked") {
  ClosureGate off({.base_m = 0.0});
  off.Advance(Odom(0));
  REQUIRE(off.Check(Odom(0), Odom(0)));
  off.Accepted();
  off.Advance(Odom(1));
  CHECK(off.Check(PoseFromXYYaw(100.0, 0.0, 3.0), Odom(1)));
  CHECK(ValidateClosureGateOptions({}).ok());
  CHECK_FALSE(ValidateClosureGateOptions({.base_m = -1.0}).ok());
  CHECK_FALSE(ValidateClosureGateOptions({.agree = 0}).ok());
  CHECK(ValidateClosureGateOptions({.rotation_deg = 0.0}).message().find("rotation_deg") !=
        std::string::npos);
}

}  // namespace
}  // namespace zm
