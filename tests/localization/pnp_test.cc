// The allocation-free PnP-RANSAC (lib/localization/pnp.h) and its P3P solver (p3p.h):
// - the P3P roots contain the true pose, the polynomial root finder finds every simple root;
// - on synthetic scenes (random points, random camera, 0.5 px noise, 0-50 % outliers) it
//   recovers the pose to millimetres and agrees with OpenCV's solvePnPRansac + solvePnPRefineLM
//   (kept here ONLY as the reference) on the pose and on the inliers;
// - failures are values; results are deterministic;
// - a warm Solve() and a warm Localize() that verifies a candidate allocate nothing: global
//   operator new is counted (support/counting_allocator.h) and so is malloc (sanitizer malloc
//   hooks under ASan, every call; glibc mallinfo2 bytes in use otherwise, the net only).
#include "localization/pnp.h"

#include <doctest/doctest.h>
#include <malloc.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <opencv2/calib3d.hpp>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "arena/sanitizers.h"
#include "localization/camera.h"
#include "localization/localizer.h"
#include "localization/p3p.h"
#include "support/counting_allocator.h"
#include "synthetic_world.h"

#if ZM_ASAN
#define ZM_PNP_TEST_ASAN 1
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*,
                                                                             std::size_t),
                                                         void (*free_hook)(const volatile void*));
#else
#define ZM_PNP_TEST_ASAN 0
#endif

namespace zm {
namespace {

#if ZM_PNP_TEST_ASAN
thread_local std::uint64_t t_mallocs = 0;
void OnMalloc(const volatile void*, std::size_t) { ++t_mallocs; }
void OnFree(const volatile void*) {}
#endif

// Counts malloc calls (ASan: every call on this thread, through the sanitizer's hooks) or, without
// ASan, the change of glibc's bytes in use (mallinfo2: catches a block kept, not one freed again).
class MallocProbe {
 public:
  MallocProbe() {
#if ZM_PNP_TEST_ASAN
    static const bool installed = __sanitizer_install_malloc_and_free_hooks(OnMalloc, OnFree) != 0;
    REQUIRE(installed);
    start_ = t_mallocs;
#else
    start_ = InUse();
#endif
  }
  // Zero when nothing was allocated (see the class comment for what each build can see).
  [[nodiscard]] std::uint64_t count() const {
#if ZM_PNP_TEST_ASAN
    return t_mallocs - start_;
#else
    return InUse() - start_;
#endif
  }

 private:
#if !ZM_PNP_TEST_ASAN
  static std::uint64_t InUse() {
    const struct mallinfo2 m = mallinfo2();
    return m.uordblks + m.hblkhd;
  }
#endif
  std::uint64_t start_ = 0;
};

const CameraIntrinsics kVgaCamera{500.0, 500.0, 320.0, 240.0, 640, 480};

struct Scene {
  Pose3 t_cam_map = Pose3::Identity();
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
  std::vector<bool> outlier;
};

// n points at 2-10 m in front of a random camera, seen with Gaussian pixel noise; a fraction
// (exactly round(n * outlier_ratio), chosen at random) gets a uniform random pixel instead.
Scene MakeScene(std::uint32_t seed, std::size_t n, double outlier_ratio, double noise_px = 0.5) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Scene s;
  Eigen::Quaterniond q(gauss(rng), gauss(rng), gauss(rng), gauss(rng));
  Pose3 t_map_cam = Pose3::Identity();
  t_map_cam.linear() = q.normalized().toRotationMatrix();
  t_map_cam.translation() =
      Eigen::Vector3d(10 * unit(rng) - 5, 10 * unit(rng) - 5, 10 * unit(rng) - 5);
  s.t_cam_map = t_map_cam.inverse();
  for (std::size_t i = 0; i < n; ++i) {
    const double u = 640.0 * unit(rng);
    const double v = 480.0 * unit(rng);
    const double depth = 2.0 + 8.0 * unit(rng);
    const Eigen::Vector3d p_cam(depth * (u - kVgaCamera.cx) / kVgaCamera.fx,
                                depth * (v - kVgaCamera.cy) / kVgaCamera.fy, depth);
    const Eigen::Vector3d p = t_map_cam * p_cam;
    s.object.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                          static_cast<float>(p.z()));
    s.image.emplace_back(static_cast<float>(u + noise_px * gauss(rng)),
                         static_cast<float>(v + noise_px * gauss(rng)));
  }
  std::vector<std::size_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  s.outlier.assign(n, false);
  const auto outliers =
      static_cast<std::size_t>(std::lround(outlier_ratio * static_cast<double>(n)));
  for (std::size_t k = 0; k < outliers; ++k) {
    s.outlier[order[k]] = true;
    s.image[order[k]] =
        cv::Point2f(static_cast<float>(640.0 * unit(rng)), static_cast<float>(480.0 * unit(rng)));
  }
  return s;
}

struct PoseError {
  double position_m;  // distance between the camera centres
  double angle_deg;   // angle of the relative rotation
};

PoseError Compare(const Pose3& est_cam_map, const Pose3& truth_cam_map) {
  const double position =
      (est_cam_map.inverse().translation() - truth_cam_map.inverse().translation()).norm();
  const Eigen::AngleAxisd diff(
      Eigen::Matrix3d(est_cam_map.linear().transpose() * truth_cam_map.linear()));
  return {position, diff.angle() * 180.0 / M_PI};
}

struct CvResult {
  bool ok = false;
  Pose3 t_cam_map = Pose3::Identity();
  std::vector<std::uint8_t> mask;
  std::size_t inliers = 0;
};

// The former adapter's calls, verbatim: EPnP RANSAC, then LM on the inliers.
CvResult SolveWithOpenCv(const Scene& s, int iterations) {
  const cv::Mat k = (cv::Mat_<double>(3, 3) << kVgaCamera.fx, 0, kVgaCamera.cx, 0, kVgaCamera.fy,
                     kVgaCamera.cy, 0, 0, 1);
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  CvResult out;
  out.ok = cv::solvePnPRansac(s.object, s.image, k, cv::noArray(), rvec, tvec, false, iterations,
                              4.0f, 0.99, inliers, cv::SOLVEPNP_EPNP);
  if (!out.ok) return out;
  std::vector<cv::Point3f> obj;
  std::vector<cv::Point2f> img;
  for (int i : inliers) {
    obj.push_back(s.object[static_cast<std::size_t>(i)]);
    img.push_back(s.image[static_cast<std::size_t>(i)]);
  }
  if (inliers.size() >= 6) cv::solvePnPRefineLM(obj, img, k, cv::noArray(), rvec, tvec);
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) out.t_cam_map.linear()(i, j) = r.at<double>(i, j);
    out.t_cam_map.translation()[i] = tvec.at<double>(i);
  }
  out.mask.assign(s.object.size(), 0);
  for (int i : inliers) out.mask[static_cast<std::size_t>(i)] = 1;
  out.inliers = inliers.size();
  return out;
}

TEST_CASE("polynomial roots: every simple real root in the interval, none outside") {
  // (x - 1)(x - 2)(x - 3)(x - 4) = x^4 - 10x^3 + 35x^2 - 50x + 24
  const double quartic[5] = {24, -50, 35, -10, 1};
  double roots[4];
  REQUIRE(RealPolynomialRoots(quartic, 4, 0.0, 10.0, roots) == 4);
  for (int i = 0; i < 4; ++i) CHECK(roots[i] == doctest::Approx(i + 1).epsilon(1e-12));
  CHECK(RealPolynomialRoots(quartic, 4, 2.5, 10.0, roots) == 2);  // only 3 and 4
  const double no_real[3] = {1, 0, 1};                            // x^2 + 1
  CHECK(RealPolynomialRoots(no_real, 2, -10.0, 10.0, roots) == 0);
  const double lowered[5] = {-2, 1, 0, 0, 0};  // vanishing leading terms: x - 2
  REQUIRE(RealPolynomialRoots(lowered, 4, 0.0, 10.0, roots) == 1);
  CHECK(roots[0] == doctest::Approx(2.0));
}

TEST_CASE("P3P: one of the solutions is the true pose, degenerate triangles give none") {
  int found = 0;
  const int trials = 500;
  for (int trial = 0; trial < trials; ++trial) {
    const Scene s = MakeScene(static_cast<std::uint32_t>(1000 + trial), 3, 0.0, 0.0);
    std::array<Eigen::Vector3d, 3> world, rays;
    for (std::size_t k = 0; k < 3; ++k) {
      world[k] =
          Eigen::Vector3d(double{s.object[k].x}, double{s.object[k].y}, double{s.object[k].z});
      rays[k] = Eigen::Vector3d((double{s.image[k].x} - kVgaCamera.cx) / kVgaCamera.fx,
                                (double{s.image[k].y} - kVgaCamera.cy) / kVgaCamera.fy, 1.0);
    }
    std::array<P3pPose, 4> poses;
    const int n = SolveP3p(world, rays, &poses);
    bool match = false;
    for (int i = 0; i < n; ++i) {
      Pose3 est = Pose3::Identity();
      est.linear() = poses[static_cast<std::size_t>(i)].r_cam_world;
      est.translation() = poses[static_cast<std::size_t>(i)].t_cam_world;
      const PoseError e = Compare(est, s.t_cam_map);
      match = match || (e.position_m < 1e-4 && e.angle_deg < 1e-3);  // float inputs
    }
    found += match ? 1 : 0;
  }
  MESSAGE("P3P recovered the true pose in " << found << "/" << trials << " random triangles");
  CHECK(found >= trials * 99 / 100);

  std::array<P3pPose, 4> poses;
  const std::array<Eigen::Vector3d, 3> rays{Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.1, 0, 1),
                                            Eigen::Vector3d(0, 0.1, 1)};
  const std::array<Eigen::Vector3d, 3> collinear{Eigen::Vector3d(0, 0, 5), Eigen::Vector3d(1, 0, 5),
                                                 Eigen::Vector3d(2, 0, 5)};
  CHECK(SolveP3p(collinear, rays, &poses) == 0);
  const std::array<Eigen::Vector3d, 3> coincident{
      Eigen::Vector3d(0, 0, 5), Eigen::Vector3d(0, 0, 5), Eigen::Vector3d(0, 1, 5)};
  CHECK(SolveP3p(coincident, rays, &poses) == 0);
}

TEST_CASE("PnP-RANSAC recovers random poses with 0-50% outliers and agrees with OpenCV") {
  const PnpParams params{.iterations = 300};
  PnpRansac pnp(kVgaCamera, params, 256);
  std::size_t max_disagree = 0;
  for (const double ratio : {0.0, 0.1, 0.3, 0.5}) {
    for (std::uint32_t seed = 1; seed <= 5; ++seed) {
      CAPTURE(ratio);
      CAPTURE(seed);
      const Scene s = MakeScene(seed, 200, ratio);
      const PnpSolution ours = pnp.Solve(s.object, s.image);
      const CvResult ref = SolveWithOpenCv(s, params.iterations);
      REQUIRE(ours.found);
      CHECK(ours.outcome == PnpOutcome::kOk);
      REQUIRE(ref.ok);
      const PoseError e_ours = Compare(ours.t_cam_map, s.t_cam_map);
      const PoseError e_ref = Compare(ref.t_cam_map, s.t_cam_map);
      CHECK(e_ours.position_m < 0.01);
      CHECK(e_ours.angle_deg < 0.1);
      CHECK(e_ref.position_m < 0.01);
      CHECK(e_ref.angle_deg < 0.1);
      // Ours against OpenCV's, and the inlier sets: true inliers all kept, outliers (whose random
      // pixel can land near the true projection by chance) at most one. OpenCV reports the
      // inliers of its unrefined 5-point EPnP hypothesis, which misses a few noisy true inliers:
      // the sets may differ by 5 % of the points, and where they differ OpenCV is the one wrong.
      const PoseError e_pair = Compare(ours.t_cam_map, ref.t_cam_map);
      CHECK(e_pair.position_m < 0.01);
      CHECK(e_pair.angle_deg < 0.1);
      const auto mask = pnp.inlier_mask();
      REQUIRE(mask.size() == s.object.size());
      std::size_t missed = 0, false_inliers = 0, disagree = 0, ours_wrong = 0;
      for (std::size_t i = 0; i < mask.size(); ++i) {
        if (!s.outlier[i] && mask[i] == 0) ++missed;
        if (s.outlier[i] && mask[i] == 1) ++false_inliers;
        if (mask[i] != ref.mask[i]) {
          ++disagree;
          if ((mask[i] == 1) == s.outlier[i]) ++ours_wrong;
        }
      }
      CHECK(missed == 0);
      CHECK(false_inliers <= 1);
      CHECK(disagree <= s.object.size() / 20);
      CHECK(ours_wrong <= 1);
      CHECK(ours.inliers + 1u >= ref.inliers);
      max_disagree = std::max(max_disagree, disagree);
      if (seed == 1) {
        MESSAGE("outliers " << ratio << ": ours " << e_ours.position_m * 1e3 << " mm "
                            << e_ours.angle_deg << " deg " << ours.inliers << " inliers in "
                            << ours.iterations << " samples; OpenCV " << e_ref.position_m * 1e3
                            << " mm " << e_ref.angle_deg << " deg " << ref.inliers << " inliers");
      }
    }
  }
  MESSAGE("largest inlier-set difference from OpenCV: " << max_disagree << " of 200 points");
}

TEST_CASE("PnP failures are values: mismatched, too few, degenerate, no consensus") {
  PnpRansac pnp(kVgaCamera, {}, 64);
  const Scene s = MakeScene(3, 50, 0.0);
  const std::span<const cv::Point3f> obj(s.object);
  const std::span<const cv::Point2f> img(s.image);

  PnpSolution r = pnp.Solve(obj, img.first(49));
  CHECK_FALSE(r.found);
  CHECK(r.outcome == PnpOutcome::kSizeMismatch);
  r = pnp.Solve(obj.first(3), img.first(3));
  CHECK_FALSE(r.found);
  CHECK(r.outcome == PnpOutcome::kTooFewPoints);
  CHECK(std::string(PnpOutcomeName(r.outcome)).find("4") != std::string::npos);

  // Every map point on one line: each sample is collinear, no hypothesis at all.
  std::vector<cv::Point3f> line;
  for (int i = 0; i < 50; ++i) line.emplace_back(0.1f * static_cast<float>(i), 1.0f, 5.0f);
  r = pnp.Solve(line, img);
  CHECK_FALSE(r.found);
  CHECK(r.outcome == PnpOutcome::kDegenerate);

  // Correspondences that belong to no pose: hypotheses fit their own sample and little else.
  Scene noise = MakeScene(4, 200, 1.0);
  r = pnp.Solve(noise.object, noise.image);
  CHECK(r.inliers < 10);
  CHECK(r.iterations == 100);  // no consensus: the full budget is spent
}

TEST_CASE("PnP is deterministic: the same input gives the same pose and inliers") {
  PnpRansac pnp(kVgaCamera, {}, 256);
  const Scene s = MakeScene(11, 200, 0.3);
  const Scene other = MakeScene(12, 150, 0.5);
  const PnpSolution a = pnp.Solve(s.object, s.image);
  (void)pnp.Solve(other.object, other.image);  // state from another solve must not leak
  const PnpSolution b = pnp.Solve(s.object, s.image);
  REQUIRE(a.found);
  CHECK(a.inliers == b.inliers);
  CHECK(a.iterations == b.iterations);
  CHECK(a.t_cam_map.matrix() == b.t_cam_map.matrix());
  // Without refinement the pose is the best minimal-sample hypothesis: still close.
  PnpRansac raw(kVgaCamera, {.refine = false}, 256);
  const PnpSolution c = raw.Solve(s.object, s.image);
  REQUIRE(c.found);
  CHECK(Compare(c.t_cam_map, s.t_cam_map).position_m < 0.1);
}

TEST_CASE("the malloc probe sees a malloc") {
  MallocProbe probe;
  // volatile: the call must not be elided. 64 KiB: without ASan the probe reads glibc's bytes
  // in use, and a small block can come out of the per-thread cache, which counts as in use
  // already (whether one is there depends on what the tests before this one freed).
  void* volatile block = std::malloc(std::size_t{64} << 10);
  CHECK(probe.count() > 0);
  std::free(block);
}

TEST_CASE("a warm PnP solve allocates nothing, and a call beyond the reserve grows once") {
  const Scene s = MakeScene(21, 200, 0.3);
  PnpRansac pnp(kVgaCamera, {}, 16);  // reserve below the call's 200 points
  {
    test::AllocationCounter grow;
    REQUIRE(pnp.Solve(s.object, s.image).found);
    CHECK(grow.allocations() > 0);  // the one growth
  }
  for (int round = 0; round < 3; ++round) {
    const Scene warm = MakeScene(30 + static_cast<std::uint32_t>(round), 200, 0.5);
    test::AllocationCounter allocs;
    MallocProbe mallocs;
    const PnpSolution r = pnp.Solve(warm.object, warm.image);
    CHECK(allocs.allocations() == 0);
    CHECK(allocs.bytes() == 0);
    CHECK(mallocs.count() == 0);
    CHECK(r.found);
  }
}

TEST_CASE("a warm localizer tick that verifies and accepts a candidate allocates nothing") {
  test::World world({});
  test::KeyframeStore store;
  for (int i = 0; i <= 40; ++i) {
    const Pose3 pose = PoseFromXYYaw(i, 0.0, 0.0);
    store.Add(KeyframeId{i + 1}, pose, world.Observe(pose));
  }
  const Pose3 truth = PoseFromXYYaw(10.2, 0.1, 0.02);
  const Frame frame = test::MakeFrame(0, 0.0, truth, world.Observe(truth));
  const Frame next = test::MakeFrame(1, 0.5, truth, world.Observe(truth));  // fresh noise
  Localizer loc({}, world.camera());
  REQUIRE(loc.Localize(frame, truth, store.all()).accepted);  // warm-up
  test::AllocationCounter allocs;
  MallocProbe mallocs;
  const LocalizeResult r = loc.Localize(next, truth, store.all());
  CHECK(allocs.allocations() == 0);
  CHECK(mallocs.count() == 0);
  CHECK(r.accepted);
  CHECK(r.candidates_examined >= 1);
  CHECK(r.inliers >= 20);
  CHECK((r.t_map_body.translation() - truth.translation()).norm() < 0.05);
}

TEST_CASE("the PnP covariance predicts the spread of the pose over noise draws" *
          doctest::test_suite("slow")) {
  // One geometry, 400 draws of 1 px pixel noise: the empirical covariance of the left
  // perturbation xi (T_est = Exp(xi) T_true) against the solutions' sigma^2 (J^T J)^-1; then the
  // camera position in the map, as BodyCovarianceFromCamera carries it to the robot.
  const Scene clean = MakeScene(77, 150, 0.0, 0.0);
  const Pose3 t_map_cam = clean.t_cam_map.inverse();
  PnpRansac pnp(kVgaCamera, {}, 256);
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss(0.0, 1.0);
  constexpr int kDraws = 400;
  Eigen::Matrix<double, 6, 6> predicted = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 6> empirical = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix3d position_emp = Eigen::Matrix3d::Zero();
  std::vector<Eigen::Matrix<double, 6, 1>> xis;
  for (int d = 0; d < kDraws; ++d) {
    std::vector<cv::Point2f> image = clean.image;
    for (auto& p : image) {
      p.x += static_cast<float>(gauss(rng));
      p.y += static_cast<float>(gauss(rng));
    }
    const PnpSolution sol = pnp.Solve(clean.object, image);
    REQUIRE(sol.found);
    REQUIRE(sol.covariance.allFinite());
    CHECK(sol.rms_px == doctest::Approx(1.0).epsilon(0.3));
    predicted += sol.covariance / kDraws;
    const Pose3 delta = sol.t_cam_map * clean.t_cam_map.inverse();
    Eigen::Matrix<double, 6, 1> xi;
    xi.head<3>() = delta.translation();  // first order: V(w) = I
    const Eigen::AngleAxisd aa(Eigen::Matrix3d(delta.linear()));
    xi.tail<3>() = aa.angle() * aa.axis();
    xis.push_back(xi);
    empirical += xi * xi.transpose() / kDraws;
    const Eigen::Vector3d dp = sol.t_cam_map.inverse().translation() - t_map_cam.translation();
    position_emp += dp * dp.transpose() / kDraws;
  }
  for (int i = 0; i < 6; ++i) {
    CAPTURE(i);
    CHECK(empirical(i, i) / predicted(i, i) == doctest::Approx(1.0).epsilon(0.35));
  }
  // Mean squared Mahalanobis distance of the draws: 6 (the dimension) when calibrated.
  const Eigen::Matrix<double, 6, 6> inv = predicted.inverse();
  double m2 = 0.0;
  for (const auto& xi : xis) m2 += xi.dot(inv * xi) / kDraws;
  CHECK(m2 == doctest::Approx(6.0).epsilon(0.25));
  MESSAGE("PnP covariance over "
          << kDraws << " draws: empirical/predicted variances "
          << (empirical.diagonal().cwiseQuotient(predicted.diagonal())).transpose()
          << "; mean squared Mahalanobis " << m2 << " (6 when calibrated)");
  // The body (= camera centre here) position covariance in the map frame.
  const Eigen::Matrix3d position_pred =
      BodyCovarianceFromCamera(predicted, t_map_cam).topLeftCorner<3, 3>();
  for (int i = 0; i < 3; ++i) {
    CAPTURE(i);
    CHECK(position_emp(i, i) / position_pred(i, i) == doctest::Approx(1.0).epsilon(0.35));
  }
}

}  // namespace
}  // namespace zm
