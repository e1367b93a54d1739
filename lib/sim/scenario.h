// A scenario: everything one simulated experiment needs, written to one folder from a Building:
//
//   map.db               keyframes of the mapping run (ground-truth poses as map poses, features,
//                        dense RGB-D payloads: JPEG colour + RVL depth, decoded into the slot on
//                        load), neighbour links, camera, source, zones + members
//   zones.geojson        ground-truth zones (FeatureCollection; name, kind, floor, z_min, z_max)
//   map.pgm, map.yaml    occupancy grid of floor 0 (ROS map_server); map_f<k>.* for floor k > 0
//   mapping_gt.tum       ground-truth body poses of the keyframes
//   localization_gt.tum  ground-truth body poses of the localization frames
//   frames.bin           the localization frames (odometry pose + features; frames_file.h)
//   route.json           the patrol's tasks and the zone sequence it traverses (planned route)
//   scenario.json        parameters, counts and keyframe byte statistics (no wall-clock data)
//
// Every file is a function of the Building and the options alone (seeded streams; worker threads
// only change speed), so the same seed gives byte-identical files.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/status.h"
#include "sim/building.h"
#include "sim/observe.h"
#include "sim/rgbd.h"
#include "sim/route.h"
#include "zones/annotate.h"

namespace zm::sim {

// Odometry error model, applied to each step between consecutive frames (d = step length, m):
//   forward  += trans_bias * d + N(0, trans_noise_per_m * d)      (scale error + noise)
//   lateral  += N(0, trans_noise_per_m * d / 2)
//   yaw      += heading_bias_deg_per_m * d + N(0, heading_noise_deg_per_m * d)
//               + rot_bias * dyaw + N(0, rot_noise * |dyaw|)     (gyro scale error + noise)
// z follows the truth (elevators). The odometry frame equals the map frame at frame 0.
struct DriftOptions {
  double trans_noise_per_m = 0.02;
  double trans_bias = 0.01;
  double heading_noise_deg_per_m = 0.3;
  double heading_bias_deg_per_m = 0.1;
  double rot_noise = 0.01;
  double rot_bias = 0.005;
};

// Where keyframes' and frames' features come from (issue 26).
enum class FeatureSource : std::uint8_t {
  // ORB from rendered pixels: keyframes extract from their textured image at mapping; every
  // localization frame is rendered and stored as a JPEG in frames.bin, and the loop extracts;
  // the map gets a vocabulary trained from its keyframes. Nothing derives from a landmark.
  kOrb,
  // The descriptor oracle (comparison only, `--features oracle`): each landmark owns a
  // descriptor that observations copy with bit flips; the images are the flat look with spots.
  kOracle,
};

// The localization run's camera against the mapping run's (gain 1, offset 0, no blur).
struct LightingOptions {
  double gain_spread = 0.2;    // the run's gain: 1 + U(-spread, spread) (exposure and gain)
  double offset_spread = 8.0;  // the run's offset: U(-spread, spread) grey levels
  double flicker = 0.05;       // auto-exposure drift: gain * (1 + flicker sin(2 pi t / 20 s))
  double exposure_s = 0.01;    // motion blur: |yaw rate| * exposure * fx pixels (0: none)
};

struct ScenarioOptions {
  std::uint64_t seed = 1;
  CameraModel camera{MakeIntrinsics(640, 480, 90.0), 8.0, 1.0};
  double hfov_deg = 90.0;  // recorded in scenario.json (camera.intrinsics was made from it)
  LandmarkOptions landmarks;
  NoiseOptions noise;
  DenseOptions dense;
  FeatureSource features = FeatureSource::kOrb;  // the oracle only by name (issue 26)
  OrbOptions orb;            // kOrb: the one extractor's options (mapping and loop)
  LightingOptions lighting;  // kOrb: the localization run's images
  std::uint32_t vocabulary_max_keyframes = 0;  // kOrb: training sample (0: every keyframe)
  MotionOptions motion;
  double robot_radius_m = 0.25;
  double keyframe_distance_m = 0.5;
  double keyframe_angle_deg = 15.0;
  double rate_hz = 2.0;        // localization frames per second
  int tasks = 30;              // patrol tasks ("go to room X")
  double revisit_probability = 0.35;
  DriftOptions drift;
  int threads = 2;
  bool progress = false;  // progress bar on stderr
  std::string source;     // the database's source string, e.g. "sim hospital seed=1"
  double annotate_band_m = kDoorwayBandParam.default_value;  // zones/annotate.h
};

struct ScenarioReport {
  std::uint64_t landmarks = 0;
  std::uint64_t keyframes = 0;
  std::uint64_t links = 0;
  std::uint64_t frames = 0;
  std::uint64_t zones = 0;
  std::uint64_t unreachable_zones = 0;  // zones the robot cannot reach (no keyframes planned)
  std::uint64_t tasks = 0;
  // Keyframe payloads on disk (the compressed blob) and resident (the slot once decoded).
  std::uint32_t keyframe_bytes_min = 0;
  std::uint32_t keyframe_bytes_median = 0;
  std::uint32_t keyframe_bytes_max = 0;
  double keyframe_bytes_mean = 0.0;
  std::uint32_t resident_bytes_min = 0;
  std::uint32_t resident_bytes_median = 0;
  std::uint32_t resident_bytes_max = 0;
  double resident_bytes_mean = 0.0;
  std::uint32_t dense_width = 0;  // the dense resolution used (after the footprint scale)
  std::uint32_t dense_height = 0;
  double keyframes_s = 0.0;  // wall time of rendering + encoding + writing the keyframes
  double mapping_length_m = 0.0;
  double localization_length_m = 0.0;
  double localization_duration_s = 0.0;
  std::uint64_t mean_features_per_keyframe = 0;
  std::uint64_t mean_features_per_frame = 0;  // kOrb: 0 (the loop extracts)
  // kOrb: the frames' images and the vocabulary.
  double frames_s = 0.0;  // wall time of rendering + encoding + writing the frames
  std::uint32_t frame_jpeg_bytes_mean = 0;
  double lighting_gain = 1.0;
  double lighting_offset = 0.0;
  std::uint32_t vocabulary_words = 0;
  std::uint64_t vocabulary_bytes = 0;
  double vocabulary_s = 0.0;
};

// Builds and writes the whole scenario into out_dir (created if missing; files are overwritten).
[[nodiscard]] Result<ScenarioReport> WriteScenario(const Building& building,
                                                   const ScenarioOptions& options,
                                                   const std::string& out_dir);

// scenario.json, read back (for `zonemap run` and the benchmarks). Paths are absolute or relative
// to the current directory (dir joined with the file names).
struct ScenarioInfo {
  std::string dir;
  std::string kind;  // hospital | floorplan
  std::uint64_t seed = 0;
  int floors = 1;
  double area_m2 = 0.0;
  std::uint64_t keyframes = 0, frames = 0, zones = 0;
  double rate_hz = 0.0;
  CameraIntrinsics camera;
  std::uint32_t keyframe_bytes_max = 0;   // largest compressed payload on disk
  std::uint32_t resident_bytes_max = 0;   // largest keyframe once decoded (the slot size)
  double footprint_scale = 1.0;           // `zonemap sim --footprint-scale` (dense.footprint_scale)
  std::string features = "oracle";        // orb | oracle (scenarios from before issue 26: oracle)
  std::string map_db, zones_geojson, frames_bin, mapping_gt, localization_gt, route_json, map_yaml;
};
[[nodiscard]] Result<ScenarioInfo> LoadScenario(const std::string& dir);

// route.json, read back: the tasks and the zones the patrol traverses, in order.
struct RouteVisit {
  std::string zone;
  std::uint64_t first_frame = 0;
  std::uint64_t last_frame = 0;
};
struct RouteTask {
  std::string goal_zone;
  std::uint64_t start_frame = 0;
  std::uint64_t end_frame = 0;
};
struct Route {
  std::vector<RouteTask> tasks;
  std::vector<RouteVisit> zones;
};
[[nodiscard]] Result<Route> LoadRoute(const std::string& path);

}  // namespace zm::sim
