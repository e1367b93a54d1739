// Time per PnP-RANSAC call: zonemap's allocation-free P3P RANSAC + LM (lib/localization/pnp.h)
// against what it replaced, OpenCV's solvePnPRansac (EPnP) + solvePnPRefineLM on the inliers,
// with the localizer's parameters (4 px, at most 100 iterations, 0.99 confidence). Both see the
// same 16 seeded scenes in turn: 200 correspondences at 2-10 m, 0.5 px noise, 30 % outliers.
// Checks before timing that both recover every scene's pose; prints the ratio of the medians
// (or means) of CPU time at the end. Asserts nothing else; it is a figure, not a test.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/calib3d.hpp>
#include <random>
#include <string>
#include <vector>

#include "localization/pnp.h"

namespace {

const zm::CameraIntrinsics kCamera{500.0, 500.0, 320.0, 240.0, 640, 480};
constexpr std::size_t kPoints = 200;
constexpr double kOutlierRatio = 0.3;
constexpr int kScenes = 16;

struct Scene {
  zm::Pose3 t_cam_map = zm::Pose3::Identity();
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> image;
};

Scene MakeScene(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Scene s;
  const Eigen::Quaterniond q(gauss(rng), gauss(rng), gauss(rng), gauss(rng));
  zm::Pose3 t_map_cam = zm::Pose3::Identity();
  t_map_cam.linear() = q.normalized().toRotationMatrix();
  t_map_cam.translation() =
      Eigen::Vector3d(10 * unit(rng) - 5, 10 * unit(rng) - 5, 10 * unit(rng) - 5);
  s.t_cam_map = t_map_cam.inverse();
  for (std::size_t i = 0; i < kPoints; ++i) {
    const double u = 640.0 * unit(rng);
    const double v = 480.0 * unit(rng);
    const double depth = 2.0 + 8.0 * unit(rng);
    const Eigen::Vector3d p =
        t_map_cam * Eigen::Vector3d(depth * (u - kCamera.cx) / kCamera.fx,
                                    depth * (v - kCamera.cy) / kCamera.fy, depth);
    s.object.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                          static_cast<float>(p.z()));
    const bool outlier = unit(rng) < kOutlierRatio;
    s.image.emplace_back(static_cast<float>(outlier ? 640.0 * unit(rng) : u + 0.5 * gauss(rng)),
                         static_cast<float>(outlier ? 480.0 * unit(rng) : v + 0.5 * gauss(rng)));
  }
  return s;
}

const std::vector<Scene>& Scenes() {
  static const std::vector<Scene> scenes = [] {
    std::vector<Scene> v;
    for (int i = 0; i < kScenes; ++i) v.push_back(MakeScene(static_cast<std::uint32_t>(100 + i)));
    return v;
  }();
  return scenes;
}

// The former adapter (lib/localization/pnp.cc before the change), reusing its buffers.
class OpenCvPnp {
 public:
  OpenCvPnp() : k_(cv::Mat::eye(3, 3, CV_64F)), rvec_(3, 1, CV_64F), tvec_(3, 1, CV_64F) {
    k_.at<double>(0, 0) = kCamera.fx;
    k_.at<double>(1, 1) = kCamera.fy;
    k_.at<double>(0, 2) = kCamera.cx;
    k_.at<double>(1, 2) = kCamera.cy;
  }
  bool Solve(const Scene& s, zm::Pose3* t_cam_map) {
    inliers_.clear();
    if (!cv::solvePnPRansac(s.object, s.image, k_, cv::noArray(), rvec_, tvec_, false, 100, 4.0f,
                            0.99, inliers_, cv::SOLVEPNP_EPNP) ||
        inliers_.size() < 6) {
      return false;
    }
    obj_.clear();
    img_.clear();
    for (int i : inliers_) {
      obj_.push_back(s.object[static_cast<std::size_t>(i)]);
      img_.push_back(s.image[static_cast<std::size_t>(i)]);
    }
    cv::solvePnPRefineLM(obj_, img_, k_, cv::noArray(), rvec_, tvec_);
    if (t_cam_map != nullptr) {
      cv::Mat r;
      cv::Rodrigues(rvec_, r);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) t_cam_map->linear()(i, j) = r.at<double>(i, j);
        t_cam_map->translation()[i] = tvec_.at<double>(i);
      }
    }
    return true;
  }

 private:
  cv::Mat k_, rvec_, tvec_;
  std::vector<int> inliers_;
  std::vector<cv::Point3f> obj_;
  std::vector<cv::Point2f> img_;
};

double PositionError(const zm::Pose3& est, const zm::Pose3& truth) {
  return (est.inverse().translation() - truth.inverse().translation()).norm();
}

void BM_PnpZonemap(benchmark::State& state) {
  zm::PnpRansac pnp(kCamera, {}, 2048);
  const auto& scenes = Scenes();
  std::size_t i = 0;
  for (auto _ : state) {
    const Scene& s = scenes[i++ % scenes.size()];
    zm::PnpSolution r = pnp.Solve(s.object, s.image);
    benchmark::DoNotOptimize(r);
  }
}

void BM_PnpOpenCv(benchmark::State& state) {
  OpenCvPnp pnp;
  const auto& scenes = Scenes();
  std::size_t i = 0;
  for (auto _ : state) {
    const Scene& s = scenes[i++ % scenes.size()];
    bool ok = pnp.Solve(s, nullptr);
    benchmark::DoNotOptimize(ok);
  }
}

BENCHMARK(BM_PnpZonemap)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PnpOpenCv)->Unit(benchmark::kMicrosecond);

// Console output as usual, plus the CPU time per benchmark (median aggregate when repeated).
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      const std::string name = run.run_name.function_name;
      if (run.run_type == Run::RT_Aggregate && run.aggregate_name == "median") {
        median_[name] = run.GetAdjustedCPUTime();
      } else if (run.run_type == Run::RT_Iteration) {
        single_[name] = run.GetAdjustedCPUTime();
      }
    }
    ConsoleReporter::ReportRuns(runs);
  }
  double Time(const std::string& name) const {
    auto it = median_.find(name);
    if (it != median_.end()) return it->second;
    auto jt = single_.find(name);
    return jt != single_.end() ? jt->second : 0.0;
  }

 private:
  std::map<std::string, double> median_, single_;
};

}  // namespace

int main(int argc, char** argv) {
  // Both must solve every scene before their times mean anything.
  zm::PnpRansac ours(kCamera, {}, 2048);
  OpenCvPnp theirs;
  double worst_ours = 0.0, worst_theirs = 0.0;
  for (const Scene& s : Scenes()) {
    const zm::PnpSolution a = ours.Solve(s.object, s.image);
    zm::Pose3 b = zm::Pose3::Identity();
    if (!a.found || !theirs.Solve(s, &b)) {
      std::fprintf(stderr, "pnp_bench: a solver failed on a scene\n");
      return 1;
    }
    worst_ours = std::max(worst_ours, PositionError(a.t_cam_map, s.t_cam_map));
    worst_theirs = std::max(worst_theirs, PositionError(b, s.t_cam_map));
  }
  std::printf("worst camera-centre error over %d scenes: zonemap %.2f mm, OpenCV %.2f mm\n",
              kScenes, worst_ours * 1e3, worst_theirs * 1e3);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  const double t_ours = reporter.Time("BM_PnpZonemap");
  const double t_cv = reporter.Time("BM_PnpOpenCv");
  if (t_ours > 0.0 && t_cv > 0.0) {
    std::printf("OpenCV / zonemap CPU time per call: %.2fx (%.1f us vs %.1f us)\n", t_cv / t_ours,
                t_cv, t_ours);
  }
  benchmark::Shutdown();
  return 0;
}
