// Dense keyframes of the simulator (lib/sim/rgbd.h): with the default options a keyframe is
// resident at RTAB-Map's reported 1.9-2.3 MB per node, as real decoded data; the points decoded
// from its depth land on the landmarks its features observe, within the depth noise; the same
// seed gives the same bytes; bad options are refused naming the option.
#include "sim/rgbd.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <vector>

#include "localization/camera.h"
#include "mapdb/dense_codec.h"
#include "mapdb/keyframe_payload.h"
#include "sim/building.h"
#include "sim/observe.h"

namespace zm::sim {
namespace {

// The default scenario's building (0.05 m cells), smaller, and its default camera.
struct World {
  Building building;
  LandmarkMap landmarks;
  CameraModel camera{MakeIntrinsics(640, 480, 90.0), 8.0, 1.0};
  std::vector<Pose3> poses;  // one per zone, looking along a different heading each
};

World MakeWorld() {
  HospitalOptions h;
  h.seed = 2;
  h.area_m2 = 600.0;
  auto b = GenerateHospital(h);
  REQUIRE(b.ok());
  World w;
  w.building = std::move(b).value();
  w.landmarks = LandmarkMap::Generate(w.building, LandmarkOptions{}, 2);
  for (std::size_t z = 0; z < w.building.zones.size() && w.poses.size() < 12; ++z) {
    const Eigen::Vector2d p = w.building.zones[z].viewpoint;
    const double yaw = 0.5 * static_cast<double>(z);
    w.poses.push_back(PoseFromXYYaw(p.x(), p.y(), yaw, w.camera.height_m));
  }
  return w;
}

RenderedKeyframe Render(const World& w, std::size_t i, const DenseOptions& dense = {},
                        std::uint64_t seed = 5) {
  Rng rng(seed, 100 + i);
  RenderedKeyframe kf;
  const Status s = RenderKeyframe(w.building, w.landmarks, 0, w.poses[i], w.camera, NoiseOptions{}, dense,
                                  dense.width, dense.height, KeyframeId{static_cast<std::int64_t>(i + 1)},
                                  rng, &kf);
  REQUIRE_MESSAGE(s.ok(), s.ToString());
  return kf;
}

// Decodes a keyframe into a slot of its resident size (as the load path does).
struct Decoded {
  std::vector<std::byte> slot;
  KeyframeView view;
};
Decoded DecodeInSlot(const World& w, const RenderedKeyframe& kf) {
  Decoded d;
  d.slot.resize(kf.resident_bytes + 64);
  // 16-byte alignment of the sections is relative to the slot start: align it.
  const auto misalign = reinterpret_cast<std::uintptr_t>(d.slot.data()) % 64;
  const std::size_t off = misalign == 0 ? 0 : 64 - misalign;
  std::span<std::byte> slot(d.slot.data() + off, kf.resident_bytes);
  std::memcpy(slot.data(), kf.payload.data(), kf.payload.size());
  auto decoder = DenseDecoder::Create(w.camera.intrinsics);
  REQUIRE(decoder.ok());
  auto landed = (*decoder)->DecodeInSlot(slot, kf.payload.size());
  REQUIRE_MESSAGE(landed.ok(), landed.status().ToString());
  CHECK(*landed == kf.resident_bytes);
  auto view = DecodePayload(slot, {}, /*blob_is_slot=*/true);
  REQUIRE(view.ok());
  d.view = *view;
  return d;
}

TEST_CASE("default dense keyframes are resident at RTAB-Map's 1.9-2.3 MB per node, as real data") {
  const World w = MakeWorld();
  REQUIRE(w.poses.size() >= 8);
  std::vector<std::uint32_t> resident;
  for (std::size_t i = 0; i < 8; ++i) {
    const RenderedKeyframe kf = Render(w, i);
    resident.push_back(kf.resident_bytes);
    // Compressed on disk (JPEG + RVL), a few hundred KB; the slot holds the decoded images.
    CHECK(kf.payload.size() > 100'000);
    CHECK(kf.payload.size() < 600'000);
    CHECK(kf.resident_bytes >= 1'900'000);
    CHECK(kf.resident_bytes <= 2'300'000);
    CHECK(kf.resident_bytes > kf.payload.size() + 640 * 480 * 5);  // colour + depth decoded
  }
  std::sort(resident.begin(), resident.end());
  MESSAGE("resident bytes min ", resident.front(), " median ", resident[resident.size() / 2], " max ",
          resident.back());
}

TEST_CASE("points decoded from depth land on the landmarks the features observe") {
  const World w = MakeWorld();
  const DenseOptions dense;
  const CameraIntrinsics& k = w.camera.intrinsics;
  std::vector<double> errors;
  std::size_t checked = 0, within = 0, edges = 0, edges_within = 0, no_depth = 0;
  for (std::size_t i = 0; i < 6; ++i) {
    const RenderedKeyframe kf = Render(w, i);
    const Decoded d = DecodeInSlot(w, kf);
    REQUIRE(d.view.points != nullptr);
    REQUIRE(d.view.points_frame == PointFrame::kCamera);
    REQUIRE(d.view.feature_count == kf.features.descriptors.size());
    const std::uint32_t dw = d.view.dense_width, dh = d.view.dense_height;
    const Pose3 t_map_cam = CameraPoseInMap(w.poses[i]);
    for (std::uint32_t f = 0; f < d.view.feature_count; ++f) {
      const std::int32_t lm = kf.features.landmark[f];
      if (lm < 0) continue;  // an outlier: no landmark to compare with
      const float* p = d.view.points + 3 * f;
      if (!std::isfinite(p[2])) {
        ++no_depth;
        continue;
      }
      const Eigen::Vector3d truth = w.landmarks.landmarks()[static_cast<std::size_t>(lm)].p;
      const Eigen::Vector3d got = t_map_cam * Eigen::Vector3d(p[0], p[1], p[2]);
      const double z = (t_map_cam.inverse() * truth).z();
      // The depth step to the neighbouring pixels: a wall seen at a slant changes depth from
      // pixel to pixel, and the depth is that of the pixel holding the keypoint (as RTAB-Map's
      // nearest-pixel lookup); a step larger than 10 % of the depth is an occlusion edge.
      const auto px = static_cast<std::uint32_t>(double{kf.features.keypoints[2 * f]} * dw / k.width);
      const auto py = static_cast<std::uint32_t>(double{kf.features.keypoints[2 * f + 1]} * dh / k.height);
      const auto at = [&](std::uint32_t x, std::uint32_t y) {
        return d.view.depth[std::size_t{std::min(y, dh - 1)} * dw + std::min(x, dw - 1)] * 0.001;
      };
      const double here = at(px, py);
      double step = 0.0;
      for (const auto& [x, y] : {std::pair{px + 1, py}, std::pair{px - 1, py}, std::pair{px, py + 1},
                                 std::pair{px, py - 1}}) {
        step = std::max(step, std::abs(at(x, y) - here));
      }
      // Depth noise (uniform: at most sqrt(3) sigma, twice for the step measured between two
      // noisy pixels) plus the keyframe keypoint's noise across the ray (3 sigma of 0.7 px).
      const double sigma = dense.depth_sigma_m + dense.depth_sigma_per_m * z + dense.depth_sigma_per_m2 * z * z;
      const double tolerance = std::sqrt(3.0) * sigma + step + 3.0 * 0.7 * z / k.fx + 0.005;
      const double err = (got - truth).norm();
      const bool edge = step > 0.1 * z;
      edges += edge ? 1 : 0;
      edges_within += edge && err <= tolerance ? 1 : 0;
      if (edge) continue;
      errors.push_back(err);
      ++checked;
      if (err <= tolerance) ++within;
    }
  }
  REQUIRE(checked > 500);
  std::sort(errors.begin(), errors.end());
  MESSAGE(checked, " inlier points off edges: median error ", errors[errors.size() / 2] * 1000.0,
          " mm, 90th percentile ", errors[errors.size() * 9 / 10] * 1000.0, " mm, ", within,
          " within the noise; ", edges, " on occlusion edges (", edges_within, " within), ", no_depth,
          " without depth");
  CHECK(errors[errors.size() / 2] < 0.03);
  CHECK(static_cast<double>(within) >= 0.98 * static_cast<double>(checked));
  CHECK(edges * 20 < checked);  // occlusion edges are rare
  CHECK(no_depth * 50 < checked);
}

TEST_CASE("same seed, same bytes, another seed, other bytes") {
  const World w = MakeWorld();
  DenseOptions small;
  small.width = 160;
  small.height = 120;
  const RenderedKeyframe a = Render(w, 3, small, 9), b = Render(w, 3, small, 9), c = Render(w, 3, small, 10);
  CHECK(a.payload == b.payload);
  CHECK(a.payload != c.payload);
}

TEST_CASE("dense options are validated, naming the option") {
  const auto error = [](DenseOptions o) { return ValidateDenseOptions(o).message(); };
  CHECK(ValidateDenseOptions(DenseOptions{}).ok());
  DenseOptions o;
  o.width = 4;
  CHECK(error(o).find("--dense") != std::string::npos);
  o = {};
  o.cloud_step = 99;
  CHECK(error(o).find("--cloud-step") != std::string::npos);
  o = {};
  o.jpeg_quality = 0;
  CHECK(error(o).find("--jpeg-quality") != std::string::npos);
  o = {};
  o.footprint_scale = 0.0;
  CHECK(error(o).find("--footprint-scale") != std::string::npos);
  o.footprint_scale = 1.5;
  CHECK(error(o).find("--footprint-scale") != std::string::npos);
  o = {};
  o.depth_sigma_per_m = -1.0;
  CHECK(error(o).find("--depth-noise") != std::string::npos);
}

}  // namespace
}  // namespace zm::sim
