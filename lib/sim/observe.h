// Landmarks and the camera observation model. Landmarks are 3-D points on the faces of non-free
// cells (occupied, or unknown as real maps draw many walls) next to free cells (walls up to the wall height, furniture up to its height), at random
// heights, each with a random 256-bit descriptor. A camera (the localization module's pinhole
// convention, camera.h) sees a landmark when it projects into the image, lies within the range
// limit, and the straight segment from the camera to it crosses only free cells (LineOfSight on
// the floor's grid: walls and furniture occlude at every height, a 2-D simplification).
//
// Invariants: every landmark lies inside a free cell (0.02 cell from the face it decorates), so
// the line-of-sight test is well defined; Visible() never returns a landmark whose segment
// touches a non-free cell; MakeFeatures() is a pure function of its inputs and the Rng state.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "geometry/pose.h"
#include "mapdb/keyframe_payload.h"
#include "mapdb/map_db.h"
#include "sim/building.h"
#include "sim/rng.h"

namespace zm::sim {

struct CameraModel {
  CameraIntrinsics intrinsics;
  double range_m = 8.0;   // landmarks and depth beyond this are not observed
  double height_m = 1.0;  // camera (= body pose z) above the floor
};

// A centred pinhole with square pixels and the given horizontal field of view.
[[nodiscard]] CameraIntrinsics MakeIntrinsics(std::uint32_t width, std::uint32_t height, double hfov_deg);

struct Landmark {
  Eigen::Vector3d p;  // map frame, metres
  int floor = 0;
  Descriptor256 descriptor{};
};

struct LandmarkOptions {
  double wall_density_per_m2 = 10.0;  // landmarks per square metre of wall surface
  double furniture_density_per_m2 = 12.0;
};

struct VisibleLandmark {
  std::uint32_t landmark;
  Eigen::Vector2d uv;  // exact projection, pixels
  double depth_m;      // z in the camera frame
};

class LandmarkMap {
 public:
  [[nodiscard]] static LandmarkMap Generate(const Building& building, const LandmarkOptions& options,
                                            std::uint64_t seed);

  [[nodiscard]] const std::vector<Landmark>& landmarks() const { return landmarks_; }

  // Landmarks seen from body pose T_map_body on `floor` (ordered by landmark index).
  void Visible(const Building& building, int floor, const Pose3& t_map_body,
               const CameraModel& camera, std::vector<VisibleLandmark>* out) const;

 private:
  struct FloorIndex {
    Eigen::Vector2d origin;
    int nx = 0, ny = 0;
    std::vector<std::uint32_t> start;  // nx*ny+1 offsets into ids
    std::vector<std::uint32_t> ids;
  };
  static constexpr double kBinM = 2.0;
  std::vector<Landmark> landmarks_;
  std::vector<FloorIndex> index_;  // per floor
};

struct NoiseOptions {
  double bit_flip_probability = 0.03;  // per descriptor bit, per observation
  double pixel_sigma = 0.7;            // keypoint noise, pixels
  double outlier_ratio = 0.08;         // extra features per inlier that match nothing consistent
  double point_sigma_per_m = 0.004;    // keyframe 3-D point noise per metre of depth
  std::uint32_t max_features = 500;    // inliers + outliers per frame or keyframe
};

// Features of one view: descriptors, keypoints (u, v) and, for keyframes, map-frame 3-D points.
struct FeatureSet {
  std::vector<Descriptor256> descriptors;
  std::vector<float> keypoints;  // 2 per feature
  std::vector<float> points;     // 3 per feature (only when with_points)
  std::vector<std::int32_t> landmark;  // source landmark, -1 for an outlier
  void Clear() {
    descriptors.clear();
    keypoints.clear();
    points.clear();
    landmark.clear();
  }
};

// Turns visible landmarks into noisy features: a random subset of at most
// max_features / (1 + outlier_ratio) inliers (bit flips, pixel noise, point noise), then
// outliers (half copy a random landmark's descriptor at a random pixel, half random bits).
void MakeFeatures(const LandmarkMap& map, const std::vector<VisibleLandmark>& visible,
                  const Pose3& t_map_body, const CameraModel& camera, const NoiseOptions& noise,
                  bool with_points, Rng& rng, FeatureSet* out);

// How many feature sets MakeFeatures (the descriptor oracle: features read off landmark ids) has
// made in this process. The default path must leave it unchanged (issue 26; tests assert it).
[[nodiscard]] std::uint64_t OracleFeatureSets();

}  // namespace zm::sim
