// End-to-end localization on a synthetic corridor (synthetic_world.h): odometry drifts, the
// localizer closes loops against resident keyframes, the correction is applied from the next
// tick. With every keyframe resident the localized ATE stays far below odometry's; with the
// keyframes of the later corridor non-resident no closure happens there and drift grows
// (invariant 4: only what is resident can close a loop).
#include "localization/localizer.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include "geometry/metrics.h"
#include "localization/camera.h"
#include "support/counting_allocator.h"
#include "synthetic_world.h"

namespace zm {
namespace {

using test::KeyframeStore;
using test::World;

// Mapping keyframes every metre along the corridor centre line, x in [0, 40].
KeyframeStore MakeKeyframes(World& world) {
  KeyframeStore store;
  for (int i = 0; i <= 40; ++i) {
    const Pose3 pose = PoseFromXYYaw(i, 0.0, 0.0);
    store.Add(KeyframeId{i + 1}, pose, world.Observe(pose));
  }
  return store;
}

struct Query {
  std::vector<Pose3> truth;
  std::vector<Pose3> odom;
};

// A weaving patrol along the corridor, 0.75 m steps; odometry with a yaw bias and 2 % scale.
Query MakeQuery() {
  Query q;
  for (int k = 0; k < 51; ++k) {
    const double x = 0.5 + 0.75 * k;
    const double y = 0.3 * std::sin(x / 5.0);
    const double yaw = std::atan(0.3 / 5.0 * std::cos(x / 5.0));
    q.truth.push_back(PoseFromXYYaw(x, y, yaw));
  }
  q.odom.push_back(q.truth[0]);
  for (std::size_t k = 1; k < q.truth.size(); ++k) {
    Pose3 step = q.truth[k - 1].inverse() * q.truth[k];
    step.translation() *= 1.02;
    step.rotate(Eigen::AngleAxisd(0.006, Eigen::Vector3d::UnitZ()));
    q.odom.push_back(q.odom.back() * step);
  }
  return q;
}

struct RunOutput {
  Trajectory truth, estimate, odometry;
  std::vector<LocalizeResult> results;
  std::uint32_t accepted = 0;
};

// The runtime's loop in miniature: predict with the current correction, localize, take the PnP
// pose when accepted, update the correction for the next tick.
RunOutput Run(World& world, const Query& q, std::span<const ResidentKeyframe> resident,
              const LocalizerConfig& config = {}) {
  Localizer loc(config, world.camera());
  RunOutput out;
  Pose3 t_map_odom = Pose3::Identity();
  for (std::size_t k = 0; k < q.truth.size(); ++k) {
    const Frame frame =
        test::MakeFrame(k, 0.5 * static_cast<double>(k), q.odom[k], world.Observe(q.truth[k]));
    const Pose3 predicted = t_map_odom * frame.odom;
    const LocalizeResult r = loc.Localize(frame, predicted, resident);
    Pose3 estimate = predicted;
    if (r.accepted) {
      estimate = r.t_map_body;
      t_map_odom = MapFromOdomCorrection(r.t_map_cam, frame.odom);  // from the next tick
      ++out.accepted;
    }
    out.truth.Add(frame.stamp_s, q.truth[k]);
    out.estimate.Add(frame.stamp_s, estimate);
    out.odometry.Add(frame.stamp_s, q.odom[k]);
    out.results.push_back(r);
  }
  CHECK(loc.stats().closures_accepted == out.accepted);
  return out;
}

double AteRmse(const Trajectory& truth, const Trajectory& est) {
  auto r = Evaluate(truth, est, {.align = AlignMode::kNone});
  REQUIRE(r.ok());
  return r->ape_trans_m.rmse;
}

TEST_CASE("every keyframe resident: localized ATE stays far below odometry-only ATE") {
  World world({});
  const KeyframeStore store = MakeKeyframes(world);
  const Query q = MakeQuery();
  const RunOutput out = Run(world, q, store.all());
  const double ate_loc = AteRmse(out.truth, out.estimate);
  const double ate_odom = AteRmse(out.truth, out.odometry);
  MESSAGE("ATE localized " << ate_loc << " m, odometry " << ate_odom << " m, closures "
                           << out.accepted << "/" << q.truth.size());
  CHECK(ate_odom > 1.5);
  CHECK(ate_loc < 0.15);
  CHECK(ate_loc < 0.1 * ate_odom);
  CHECK(out.accepted > q.truth.size() * 3 / 4);
  // Accepted poses are accurate, and the highest hypothesis is a keyframe of the same place.
  for (std::size_t k = 0; k < out.results.size(); ++k) {
    const LocalizeResult& r = out.results[k];
    if (!r.accepted) continue;
    CHECK((r.t_map_body.translation() - q.truth[k].translation()).norm() < 0.2);
    CHECK(r.inliers >= 20);
    REQUIRE(r.highest_hypothesis.value > 0);
    const double kf_x = static_cast<double>(r.highest_hypothesis.value - 1);
    CHECK(std::abs(kf_x - q.truth[k].translation().x()) < 4.0);
  }
}

TEST_CASE("later keyframes non-resident: no closure there, drift grows like odometry") {
  World world({});
  const KeyframeStore store = MakeKeyframes(world);
  const Query q = MakeQuery();
  // Only the first 5 m of the corridor is resident (what a too-small working set would keep).
  const std::vector<ResidentKeyframe> early = store.InXRange(0.0, 5.0);
  std::set<std::int64_t> resident_ids;
  for (const auto& k : early) resident_ids.insert(k.id.value);
  const RunOutput partial = Run(world, q, early);
  std::uint32_t late_closures = 0;
  for (std::size_t k = 0; k < partial.results.size(); ++k) {
    const LocalizeResult& r = partial.results[k];
    // Invariant 4: nothing outside the resident span is ever matched or hypothesised.
    if (r.accepted) CHECK(resident_ids.count(r.matched.value) == 1);
    if (r.highest_hypothesis.value != 0) CHECK(resident_ids.count(r.highest_hypothesis.value) == 1);
    if (q.truth[k].translation().x() > 11.0 && r.accepted) ++late_closures;
  }
  CHECK(late_closures == 0);
  CHECK(partial.accepted > 0);  // the resident start still localizes
  // Past the resident start the estimate is dead reckoning from the last correction: its
  // error grows with distance (the full-residency run of the test above stays at millimetres).
  const double ate_partial = AteRmse(partial.truth, partial.estimate);
  const double ate_odom = AteRmse(partial.truth, partial.odometry);
  const auto error_at = [&](std::size_t k) {
    return (partial.estimate.poses[k].translation() - q.truth[k].translation()).norm();
  };
  const std::size_t last = q.truth.size() - 1;
  MESSAGE("ATE partial residency " << ate_partial << " m, odometry " << ate_odom
                                   << " m, error at 20 m " << error_at(last / 2) << " m, at end "
                                   << error_at(last) << " m");
  CHECK(error_at(last) > 2.0);
  CHECK(error_at(last) > 2.0 * error_at(last / 2));
  CHECK(ate_partial > 0.5);
  CHECK(ate_partial > 0.3 * ate_odom);
}

TEST_CASE("nothing resident, or only another place resident: no closure, estimate is odometry") {
  World world({});
  World elsewhere({.seed = 77});  // same geometry, different landmarks and descriptors
  const KeyframeStore other = MakeKeyframes(elsewhere);
  const Query q = MakeQuery();
  const RunOutput none = Run(world, q, {});
  CHECK(none.accepted == 0);
  CHECK(AteRmse(none.truth, none.estimate) == doctest::Approx(AteRmse(none.truth, none.odometry)));
  const RunOutput wrong = Run(world, q, other.all());
  CHECK(wrong.accepted == 0);
  for (const auto& r : wrong.results) CHECK(r.highest_hypothesis.value == 0);
}

TEST_CASE("candidates: pose gate, heading gate, limits and with appearance off the pose only") {
  World world({});
  const KeyframeStore store = MakeKeyframes(world);
  const Pose3 truth = PoseFromXYYaw(10.2, 0.1, 0.02);
  const Frame frame = test::MakeFrame(0, 0.0, truth, world.Observe(truth));
  LocalizerConfig cfg;
  cfg.appearance_candidates = 0;
  cfg.max_candidates = 2;
  {
    Localizer loc(cfg, world.camera());
    // Predicted 30 m away: the right keyframes are outside the radius, nothing is tried.
    const LocalizeResult r = loc.Localize(frame, PoseFromXYYaw(40.0, 0.0, 0.0), store.all());
    CHECK(r.candidates_examined == 0);
    CHECK_FALSE(r.accepted);
    CHECK(r.highest_hypothesis.value != 0);  // the appearance hypothesis is still reported
    // Facing backwards: the heading gate rejects every keyframe.
    const LocalizeResult back = loc.Localize(frame, PoseFromXYYaw(10.0, 0.0, M_PI), store.all());
    CHECK(back.candidates_examined == 0);
    const LocalizeResult ok = loc.Localize(frame, PoseFromXYYaw(10.0, 0.0, 0.0), store.all());
    CHECK(ok.accepted);
    CHECK(ok.candidates_examined <= 2);
  }
  {
    // The global appearance candidate closes even when the prediction is far off (kidnapped).
    cfg.appearance_candidates = 1;
    Localizer loc(cfg, world.camera());
    const LocalizeResult r = loc.Localize(frame, PoseFromXYYaw(40.0, 0.0, 0.0), store.all());
    CHECK(r.accepted);
    CHECK((r.t_map_body.translation() - truth.translation()).norm() < 0.2);
    CHECK(r.matched == r.highest_hypothesis);
  }
  {
    // ... unless the correction gate forbids a jump that large.
    cfg.max_correction_m = 5.0;
    Localizer loc(cfg, world.camera());
    const LocalizeResult r = loc.Localize(frame, PoseFromXYYaw(40.0, 0.0, 0.0), store.all());
    CHECK_FALSE(r.accepted);
    CHECK(r.closures_rejected == r.candidates_examined);
  }
  {
    LocalizerConfig pose_only;
    pose_only.use_appearance = false;
    pose_only.appearance_candidates = 0;
    pose_only.max_candidates = 1;
    Localizer loc(pose_only, world.camera());
    const LocalizeResult r = loc.Localize(frame, PoseFromXYYaw(10.0, 0.0, 0.0), store.all());
    CHECK(r.highest_hypothesis.value == 0);
    CHECK(r.candidates_examined == 1);
    CHECK(r.accepted);
    CHECK(r.matched.value == 11);  // nearest keyframe (x = 10)
  }
}

TEST_CASE("bad input and config validation are values, not crashes") {
  World world({});
  const KeyframeStore store = MakeKeyframes(world);
  Localizer loc({}, world.camera());
  Frame bad = test::MakeFrame(0, 0.0, Pose3::Identity(), world.Observe(Pose3::Identity()));
  bad.keypoints.pop_back();
  const LocalizeResult r = loc.Localize(bad, Pose3::Identity(), store.all());
  CHECK(r.bad_frame);
  CHECK(loc.stats().bad_frames == 1);
  CHECK_FALSE(loc.Localize(Frame{}, Pose3::Identity(), store.all()).accepted);
  LocalizerConfig c;
  CHECK(ValidateLocalizerConfig(c, world.camera()).ok());
  c.max_candidates = 0;
  CHECK_FALSE(ValidateLocalizerConfig(c, world.camera()).ok());
  c = {};
  c.ratio = 1.5f;
  CHECK_FALSE(ValidateLocalizerConfig(c, world.camera()).ok());
  CHECK_FALSE(ValidateLocalizerConfig({}, CameraIntrinsics{}).ok());
}

TEST_CASE("a warm tick that runs no PnP allocates nothing") {
  World world({});
  World elsewhere({.seed = 77});
  const KeyframeStore other = MakeKeyframes(elsewhere);
  const Pose3 truth = PoseFromXYYaw(10.0, 0.0, 0.0);
  const Frame frame = test::MakeFrame(0, 0.0, truth, world.Observe(truth));
  LocalizerConfig cfg;
  cfg.min_appearance_score = 0;  // force matching against every gated candidate
  Localizer loc(cfg, world.camera());
  (void)loc.Localize(frame, truth, other.all());  // warm-up
  test::AllocationCounter allocs;
  const LocalizeResult r = loc.Localize(frame, truth, other.all());
  CHECK(allocs.allocations() == 0);
  CHECK(r.candidates_examined > 0);  // matching ran (the kernels and scoring do not allocate)
  CHECK_FALSE(r.accepted);
}

TEST_CASE("points decoded from depth (camera frame, some without depth) localize like map points" *
          doctest::test_suite("slow")) {
  // Two identical worlds, so both runs see the same keyframes and the same frames.
  World world_map({}), world_cam({});
  const KeyframeStore store_map = MakeKeyframes(world_map);
  const KeyframeStore store_cam = MakeKeyframes(world_cam);
  // The second store's points moved into each keyframe's camera frame, as DenseDecoder writes
  // them; every 7th has no depth (NaN), which the localizer must skip.
  std::vector<ResidentKeyframe> in_camera = store_cam.all();
  std::vector<std::vector<float>> camera_points(in_camera.size());
  for (std::size_t k = 0; k < in_camera.size(); ++k) {
    ResidentKeyframe& kf = in_camera[k];
    const Pose3 t_cam_map = CameraPoseInMap(kf.pose).inverse();
    std::vector<float>& pts = camera_points[k];
    pts.resize(3 * std::size_t{kf.view.feature_count});
    for (std::uint32_t i = 0; i < kf.view.feature_count; ++i) {
      const float* p = kf.view.points + 3 * i;
      const Eigen::Vector3d c = t_cam_map * Eigen::Vector3d(p[0], p[1], p[2]);
      for (int a = 0; a < 3; ++a) {
        pts[3 * i + static_cast<std::size_t>(a)] =
            i % 7 == 0 ? std::nanf("") : static_cast<float>(c(a));
      }
    }
    kf.view.points = pts.data();
    kf.view.points_frame = PointFrame::kCamera;
  }
  const Query q = MakeQuery();
  const RunOutput by_map = Run(world_map, q, store_map.all());
  const RunOutput by_cam = Run(world_cam, q, in_camera);
  const double ate_map = AteRmse(by_map.truth, by_map.estimate);
  const double ate_cam = AteRmse(by_cam.truth, by_cam.estimate);
  MESSAGE("ATE map-frame points " << ate_map << " m (" << by_map.accepted << " closures), camera-frame "
                                  << ate_cam << " m (" << by_cam.accepted << ")");
  CHECK(ate_cam < 0.15);
  CHECK(by_cam.accepted + 2 >= by_map.accepted);
  CHECK(std::abs(ate_cam - ate_map) < 0.05);

  // A dense keyframe whose depth was never decoded has no points: examined, never verified.
  std::vector<ResidentKeyframe> undecoded = store_cam.all();
  for (ResidentKeyframe& kf : undecoded) {
    kf.view.points = nullptr;
    kf.view.points_frame = PointFrame::kCamera;
  }
  World world({});
  const Pose3 truth = PoseFromXYYaw(10.2, 0.1, 0.02);
  const Frame frame = test::MakeFrame(0, 0.0, truth, world.Observe(truth));
  Localizer loc({}, world.camera());
  const LocalizeResult r = loc.Localize(frame, truth, undecoded);
  CHECK_FALSE(r.accepted);
  CHECK(r.candidates_examined > 0);
  CHECK(r.closures_rejected == r.candidates_examined);
}

}  // namespace
}  // namespace zm
