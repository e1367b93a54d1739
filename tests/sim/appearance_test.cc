// The textured look of the simulated building (lib/sim/appearance.h, DenseOptions::style
// kTextured): images depend on the building and its décor only, never on a landmark; the same
// seed gives the same bytes; ORB finds texture in them, and a nearby view of the same place,
// under other lighting, verifies against it by PnP on the depth-derived points, as the
// localizer will; the décor repeats (aliasing).
#include "sim/appearance.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <string>
#include <vector>

#include "localization/camera.h"
#include "localization/orb_extractor.h"
#include "localization/pnp.h"
#include "sim/building.h"
#include "sim/observe.h"
#include "sim/rgbd.h"
#include "simd/hamming.h"

namespace zm::sim {
namespace {

struct AppearanceWorld {
  Building building;
  CameraModel camera{MakeIntrinsics(640, 480, 90.0), 8.0, 1.0};
  std::vector<Pose3> poses;  // one per zone, each looking along another heading
};

AppearanceWorld MakeAppearanceWorld() {
  HospitalOptions h;
  h.seed = 2;
  h.area_m2 = 600.0;
  auto b = GenerateHospital(h);
  REQUIRE(b.ok());
  AppearanceWorld w;
  w.building = std::move(b).value();
  for (std::size_t z = 0; z < w.building.zones.size() && w.poses.size() < 12; ++z) {
    const Eigen::Vector2d p = w.building.zones[z].viewpoint;
    w.poses.push_back(PoseFromXYYaw(p.x(), p.y(), 0.5 * static_cast<double>(z), w.camera.height_m));
  }
  return w;
}

DenseOptions Textured() {
  DenseOptions d;
  d.style = SurfaceStyle::kTextured;
  return d;
}

RgbdImage RenderAt(const AppearanceWorld& w, const Pose3& pose, const FrameLight& light = {},
                   const DenseOptions& dense = Textured(), std::uint64_t seed = 7) {
  static const LandmarkMap kNoLandmarks;
  RgbdImage img;
  RenderRgbd(w.building, 0, pose, w.camera, kNoLandmarks, {}, dense.width, dense.height, dense,
             seed, &img, light);
  return img;
}

cv::Mat Bgr(const RgbdImage& img) {
  cv::Mat rgb(static_cast<int>(img.height), static_cast<int>(img.width), CV_8UC3,
              const_cast<std::uint8_t*>(img.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  return bgr;
}

cv::Mat Depth(const RgbdImage& img) {
  return cv::Mat(static_cast<int>(img.height), static_cast<int>(img.width), CV_16UC1,
                 const_cast<std::uint16_t*>(img.depth.pixels.data()));
}

void MaybeDump(const RgbdImage& img, const std::string& name) {
  const char* dir = std::getenv("ZM_DUMP_DIR");  // for looking at the renderer by eye
  if (dir != nullptr) cv::imwrite(std::string(dir) + "/" + name + ".png", Bgr(img));
}

TEST_CASE("textured images carry nothing of the landmarks") {
  const AppearanceWorld w = MakeAppearanceWorld();
  const DenseOptions dense = Textured();
  const LandmarkMap a = LandmarkMap::Generate(w.building, LandmarkOptions{}, 1);
  const LandmarkMap b = LandmarkMap::Generate(w.building, LandmarkOptions{}, 99);
  std::vector<VisibleLandmark> va, vb;
  a.Visible(w.building, 0, w.poses[1], w.camera, &va);
  b.Visible(w.building, 0, w.poses[1], w.camera, &vb);
  REQUIRE(!va.empty());
  RgbdImage ia, ib;
  RenderRgbd(w.building, 0, w.poses[1], w.camera, a, va, 640, 480, dense, 7, &ia);
  RenderRgbd(w.building, 0, w.poses[1], w.camera, b, vb, 640, 480, dense, 7, &ib);
  CHECK(ia.rgb == ib.rgb);
  CHECK(ia.depth.pixels == ib.depth.pixels);
}

TEST_CASE("textured images: the same seeds give the same bytes, another décor another look") {
  const AppearanceWorld w = MakeAppearanceWorld();
  CHECK(RenderAt(w, w.poses[2]).rgb == RenderAt(w, w.poses[2]).rgb);
  DenseOptions other = Textured();
  other.decor_seed = 2;
  CHECK(RenderAt(w, w.poses[2], {}, other).rgb != RenderAt(w, w.poses[2]).rgb);
  // Lighting changes the colour, not the geometry.
  const RgbdImage dark = RenderAt(w, w.poses[2], {0.8f, 0.0f, 0.0f});
  CHECK(dark.rgb != RenderAt(w, w.poses[2]).rgb);
  CHECK(dark.depth.pixels == RenderAt(w, w.poses[2]).depth.pixels);
}

TEST_CASE("textured images: ORB finds texture, a nearby view under other light verifies by PnP") {
  const AppearanceWorld w = MakeAppearanceWorld();
  const CameraIntrinsics& k = w.camera.intrinsics;
  Result<OrbExtractor> ex = OrbExtractor::Create(OrbOptions{}, k);
  REQUIRE(ex.ok());
  OrbFeatures kf(1000), fr(1000);
  std::vector<simd::DescriptorMatch> matches(1000);
  PnpRansac pnp(k, PnpParams{}, 1000);
  int verified = 0;
  std::uint32_t flat_features = 0, textured_features = 0;
  for (std::size_t i = 0; i < w.poses.size(); ++i) {
    const Pose3& key_pose = w.poses[i];
    // The frame: 0.3 m on and 6 degrees turned, 20 % brighter, as a revisit would be.
    const Pose3 frame_pose = key_pose * PoseFromXYYaw(0.3, 0.05, 0.1, 0.0);
    const RgbdImage key = RenderAt(w, key_pose);
    const RgbdImage frame = RenderAt(w, frame_pose, {1.2f, 0.0f, 0.0f}, Textured(), 8);
    MaybeDump(key, "textured_" + std::to_string(i));
    REQUIRE(ex->Extract(Bgr(key), DepthImage{Depth(key), 1000.0}, &kf).ok());
    REQUIRE(ex->Extract(Bgr(frame), {}, &fr).ok());
    textured_features += kf.count;
    DenseOptions flat;
    const RgbdImage flat_img = RenderAt(w, key_pose, {}, flat);
    OrbFeatures ff(1000);
    REQUIRE(ex->Extract(Bgr(flat_img), {}, &ff).ok());
    flat_features += ff.count;

    const std::size_t n =
        simd::MatchRatioTest(reinterpret_cast<const std::uint8_t*>(fr.descriptors.data()), fr.count,
                             reinterpret_cast<const std::uint8_t*>(kf.descriptors.data()), kf.count,
                             {0.8f, 64}, matches.data());
    const Pose3 t_map_cam_key = CameraPoseInMap(key_pose);
    std::vector<cv::Point3f> object;
    std::vector<cv::Point2f> image;
    for (std::size_t m = 0; m < n; ++m) {
      const std::uint32_t t = matches[m].train;
      if (kf.has_point[t] == 0) continue;
      const Eigen::Vector3d pc(kf.points[3 * t], kf.points[3 * t + 1], kf.points[3 * t + 2]);
      const Eigen::Vector3d pm = t_map_cam_key * pc;
      object.emplace_back(static_cast<float>(pm.x()), static_cast<float>(pm.y()),
                          static_cast<float>(pm.z()));
      image.emplace_back(fr.keypoints[2 * matches[m].query],
                         fr.keypoints[2 * matches[m].query + 1]);
    }
    const PnpSolution sol = pnp.Solve(object, image);
    if (!sol.found || sol.inliers < 20) continue;
    const Pose3 est = sol.t_cam_map.inverse();
    const Pose3 truth = CameraPoseInMap(frame_pose);
    const double dt = (est.translation() - truth.translation()).norm();
    const double dr = Eigen::AngleAxisd(est.rotation().transpose() * truth.rotation()).angle();
    MESSAGE("view " << i << ": " << kf.count << " / " << fr.count << " features, " << n
                    << " matches, " << sol.inliers << " inliers, error " << dt << " m " << dr * 57.3
                    << " deg");
    if (dt < 0.05 && dr < 0.02) ++verified;
  }
  MESSAGE("ORB features per view: textured " << textured_features / w.poses.size() << ", flat "
                                             << flat_features / w.poses.size() << "; verified "
                                             << verified << " of " << w.poses.size());
  CHECK(textured_features > 2 * flat_features);
  CHECK(verified * 4 >= static_cast<int>(w.poses.size()) * 3);  // at least 3 views in 4
}

// The posters' looks on 40 walls of 10 slots each: how many slots have one, how many designs.
struct PosterCount {
  int with_poster = 0;
  std::size_t distinct = 0;
};

PosterCount CountPosters(const SurfaceLook& look) {
  std::set<std::vector<std::uint8_t>> posters;
  int with_poster = 0;
  for (int face = 0; face < 40; ++face) {
    WallSurface wall;
    wall.face_key = FaceKey(true, face * 7, face % 2 == 0, 0);
    wall.block_key = BlockKey(face * 7, 3, false, 0);
    for (int slot = 0; slot < 10; ++slot) {
      // Sample the poster's area on a coarse grid; a slot without a poster is plain wall.
      std::vector<std::uint8_t> sig;
      bool any_ink = false;
      for (int gy = 0; gy < 8; ++gy) {
        for (int gx = 0; gx < 5; ++gx) {
          wall.along_m =
              static_cast<float>(slot) * 2.4f + 0.85f + 0.07f + 0.13f * static_cast<float>(gx);
          const Rgb c = look.Wall(wall, 2.05f - 0.06f - 0.09f * static_cast<float>(gy));
          sig.push_back(static_cast<std::uint8_t>(c[0]));
          any_ink = any_ink || c[0] < 100.0f;
        }
      }
      if (!any_ink) continue;
      ++with_poster;
      posters.insert(sig);
    }
  }
  return {with_poster, posters.size()};
}

TEST_CASE("the décor repeats: a small catalogue of posters over many walls") {
  const PosterCount n = CountPosters(SurfaceLook(1));
  MESSAGE(n.with_poster << " posters, " << n.distinct << " distinct");
  CHECK(n.with_poster > 60);
  CHECK(n.distinct <= kPosterDesigns);
}

TEST_CASE("unique décor: the same walls, every poster a design of its own") {
  const PosterCount repeated = CountPosters(SurfaceLook(1, true));
  const PosterCount unique = CountPosters(SurfaceLook(1, false));
  CHECK(unique.with_poster == repeated.with_poster);  // the same slots hold a poster
  CHECK(unique.distinct * 10 >= static_cast<std::size_t>(unique.with_poster) * 9);
}

}  // namespace
}  // namespace zm::sim
