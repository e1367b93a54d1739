// TUM/KITTI parsing and round trips.
#include "geometry/trajectory.h"

#include <doctest/doctest.h>

#include <cmath>
#include <string>

namespace zm {
namespace {

TEST_CASE("TUM parse: comments, separators, quaternion w last and normalised") {
  const std::string text =
      "# header\n"
      "1.5 1 2 3 0 0 0 1\n"
      "\n"
      "2.5,4,5,6,0,0,0.7071068,0.7071068\n"
      "3.5\t0 0 0 0 0 0 2\r\n";
  auto t = ParseTrajectory(text, TrajectoryFormat::kTum, "x.tum");
  REQUIRE(t.ok());
  REQUIRE(t->size() == 3);
  CHECK(t->stamps_s[1] == doctest::Approx(2.5));
  CHECK(t->poses[0].translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  CHECK(Yaw(t->poses[1]) == doctest::Approx(M_PI / 2).epsilon(1e-6));
  CHECK(t->poses[2].linear().isApprox(Eigen::Matrix3d::Identity()));  // qw=2 normalised
}

TEST_CASE("TUM parse errors name the line") {
  auto bad = ParseTrajectory("0 1 2 3\n", TrajectoryFormat::kTum, "f.tum");
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.status().message().find("f.tum:1") != std::string::npos);
  CHECK_FALSE(ParseTrajectory("0 1 2 3 0 0 0 x\n", TrajectoryFormat::kTum).ok());
  CHECK_FALSE(ParseTrajectory("0 1 2 3 0 0 0 0\n", TrajectoryFormat::kTum).ok());
}

TEST_CASE("TUM and KITTI round trip") {
  Trajectory t;
  for (int i = 0; i < 5; ++i) {
    Pose3 p = PoseFromXYYaw(0.3 * i, -0.1 * i, 0.4 * i, 0.05 * i);
    p.rotate(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d::UnitX()));
    t.Add(100.0 + 0.1 * i, p);
  }
  for (TrajectoryFormat f : {TrajectoryFormat::kTum, TrajectoryFormat::kKitti}) {
    auto back = ParseTrajectory(FormatTrajectory(t, f), f);
    REQUIRE(back.ok());
    REQUIRE(back->size() == t.size());
    CHECK(back->has_stamps == (f == TrajectoryFormat::kTum));
    for (std::size_t i = 0; i < t.size(); ++i) {
      CHECK((back->poses[i].matrix() - t.poses[i].matrix()).cwiseAbs().maxCoeff() < 1e-8);
      if (f == TrajectoryFormat::kTum)
        CHECK(back->stamps_s[i] == doctest::Approx(t.stamps_s[i]));
      else
        CHECK(back->stamps_s[i] == static_cast<double>(i));
    }
  }
  CHECK_FALSE(ParseTrajectoryFormat("csv").ok());
  CHECK_FALSE(ReadTrajectory("/nonexistent/x.tum", TrajectoryFormat::kTum).ok());
}

}  // namespace
}  // namespace zm
