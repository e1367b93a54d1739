// evo-exact metrics: the reference values of docs/evaluation.md on TUM fr1/xyz, plus synthetic
// checks of association, Umeyama (incl. the reflection case) and RPE.
#include "geometry/metrics.h"

#include <doctest/doctest.h>

#include <cmath>
#include <random>
#include <string>

namespace zm {
namespace {

const std::string kDir = std::string(ZM_SHARED_DIR) + "/data/trajectories/tum_fr1_xyz/";

// Reference values are printed with 6 decimals: agree to 1e-6.
void CheckRef(double value, double expected) { CHECK(std::abs(value - expected) <= 1e-6); }

struct Fr1 {
  Trajectory ref, est;
};
Fr1 LoadFr1() {
  auto ref = ReadTrajectory(kDir + "groundtruth.txt", TrajectoryFormat::kTum);
  auto est = ReadTrajectory(kDir + "estimate_rgbdslam.txt", TrajectoryFormat::kTum);
  REQUIRE(ref.ok());
  REQUIRE(est.ok());
  return {*ref, *est};
}

TEST_CASE("fr1/xyz: association 785 of 788") {
  const Fr1 d = LoadFr1();
  CHECK(d.ref.size() == 3000);
  CHECK(d.est.size() == 788);
  auto a = Associate(d.ref, d.est);
  REQUIRE(a.ok());
  CHECK(a->size() == 785);
}

TEST_CASE("fr1/xyz: APE SE(3)-aligned matches evo") {
  const Fr1 d = LoadFr1();
  auto r = Evaluate(d.ref, d.est, {.align = AlignMode::kSe3});
  REQUIRE(r.ok());
  CHECK(r->associated == 785);
  CheckRef(r->ape_trans_m.rmse, 0.013470);
  CheckRef(r->ape_trans_m.mean, 0.012024);
  CheckRef(r->ape_trans_m.median, 0.011183);
  CheckRef(r->ape_trans_m.std, 0.006071);
  CheckRef(r->ape_trans_m.max, 0.034760);
  CHECK(r->alignment.scale == 1.0);
}

TEST_CASE("fr1/xyz: APE Sim(3)-aligned matches evo") {
  const Fr1 d = LoadFr1();
  auto r = Evaluate(d.ref, d.est, {.align = AlignMode::kSim3});
  REQUIRE(r.ok());
  CheckRef(r->ape_trans_m.rmse, 0.013389);
  CheckRef(r->alignment.scale, 1.008001);
}

TEST_CASE("fr1/xyz: RPE translation delta 1 unaligned matches evo") {
  const Fr1 d = LoadFr1();
  auto r = Evaluate(d.ref, d.est, {.align = AlignMode::kNone});
  REQUIRE(r.ok());
  CHECK(r->rpe_trans_m.count == 784);
  CheckRef(r->rpe_trans_m.rmse, 0.005764);
  // SE(3) alignment cannot change relative errors.
  auto a = Evaluate(d.ref, d.est, {.align = AlignMode::kSe3});
  REQUIRE(a.ok());
  CHECK(a->rpe_trans_m.rmse == doctest::Approx(r->rpe_trans_m.rmse).epsilon(1e-9));
  CHECK(a->rpe_rot_deg.rmse == doctest::Approx(r->rpe_rot_deg.rmse).epsilon(1e-9));
}

TEST_CASE("association: nearest stamp of the longer, tolerance, not unique, first on ties") {
  Trajectory ref, est;
  for (int i = 0; i < 10; ++i) ref.Add(i * 1.0, PoseFromXYYaw(i, 0, 0));
  est.Add(2.004, Pose3::Identity());
  est.Add(2.006, Pose3::Identity());   // also nearest to 2: not forced unique
  est.Add(5.5, Pose3::Identity());     // equidistant from 5 and 6, both > 0.01: dropped
  est.Add(7.0101, Pose3::Identity());  // just outside 0.01
  auto a = Associate(ref, est);
  REQUIRE(a.ok());
  REQUIRE(a->size() == 2);
  CHECK(a->ref_index[0] == 2);
  CHECK(a->ref_index[1] == 2);
  CHECK(a->est_index[1] == 1);
  auto wide = Associate(ref, est, 0.5);
  REQUIRE(wide.ok());
  REQUIRE(wide->size() == 4);
  CHECK(wide->ref_index[2] == 5);  // tie: first minimum, like numpy.argmin
  // The shorter side drives: swapping roles gives the mirrored pairs.
  auto swapped = Associate(est, ref);
  REQUIRE(swapped.ok());
  CHECK(swapped->size() == 2);
  CHECK(swapped->est_index[0] == 2);
  Trajectory k1, k2;
  k1.has_stamps = k2.has_stamps = false;
  k1.Add(0, Pose3::Identity());
  CHECK_FALSE(Associate(k1, k2).ok());  // KITTI lengths must match
}

TEST_CASE("Umeyama recovers a similarity, including a reflection-prone configuration") {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<Eigen::Vector3d> est, ref;
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.5, -2.0, 3.0);
  for (int i = 0; i < 50; ++i) {
    est.emplace_back(n01(rng), n01(rng), n01(rng));
    ref.push_back(1.7 * (r * est.back()) + t);
  }
  auto a = Umeyama(est, ref, true);
  REQUIRE(a.ok());
  CHECK(a->scale == doctest::Approx(1.7));
  CHECK((a->rotation - r).norm() < 1e-9);
  CHECK((a->translation - t).norm() < 1e-9);
  // Planar points mirrored: the unconstrained optimum is a reflection; the fix keeps det = +1.
  std::vector<Eigen::Vector3d> p, q;
  for (int i = 0; i < 20; ++i) {
    p.emplace_back(n01(rng), n01(rng), 0.0);
    q.emplace_back(p.back().x(), -p.back().y(), 0.0);
  }
  auto b = Umeyama(p, q, false);
  REQUIRE(b.ok());
  CHECK(b->rotation.determinant() == doctest::Approx(1.0));
  CHECK_FALSE(Umeyama(std::span(p).first(2), std::span(q).first(2), false).ok());
}

TEST_CASE("RPE: a constant per-step error shows up in every pair, and population statistics") {
  Trajectory ref, est;
  for (int i = 0; i < 6; ++i) {
    ref.Add(i, PoseFromXYYaw(i * 1.0, 0, 0));
    est.Add(i, PoseFromXYYaw(i * 1.1, 0, i * 0.01));
  }
  const RpeErrors e = RpeErrorsFor(ref, est, 1);
  REQUIRE(e.trans_m.size() == 5);
  CHECK(e.rot_deg[0] == doctest::Approx(0.01 * 180.0 / M_PI));
  CHECK(RpeErrorsFor(ref, est, 2).trans_m.size() == 2);  // pairs (0,2), (2,4)
  const std::vector<double> v{1.0, 2.0, 3.0, 4.0};
  const ErrorStats s = ComputeStats(v);
  CHECK(s.median == 2.5);
  CHECK(s.std == doctest::Approx(std::sqrt(1.25)));
  CHECK(s.sse == 30.0);
  CHECK(s.rmse == doctest::Approx(std::sqrt(7.5)));
  CHECK(RotationAngle(Eigen::AngleAxisd(3.0, Eigen::Vector3d::UnitY()).toRotationMatrix()) ==
        doctest::Approx(3.0));
}

}  // namespace
}  // namespace zm
