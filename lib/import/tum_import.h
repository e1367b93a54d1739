// `zonemap import-tum DIR --poses FILE --out MAP.db` (issue 26): a zonemap map from a TUM RGB-D
// folder whose keyframe poses are given (the groundtruth, or any trajectory in TUM format).
//
//   1. The folder is listed (lib/tum/tum_folder.h: colour associated with depth); each frame
//      takes the pose of the nearest stamp in FILE within max_pose_difference_s, or is counted
//      as without a pose.
//   2. Keyframes by motion, as RTAB-Map's RGBD/LinearUpdate and RGBD/AngularUpdate: the first
//      frame with a pose, then every frame at least keyframe_distance_m or keyframe_angle_deg
//      from the last keyframe. A candidate whose images are missing, unreadable, truncated or of
//      the wrong size is refused (counted, one line in the report) and the next frame is the
//      candidate.
//   3. Each keyframe: ORB features from the one OrbExtractor, JPEG colour + RVL depth, points
//      from depth (lib/import/orb_keyframe.h). Its pose: TUM's poses are the colour camera's
//      optical frame (z forward), zonemap's keyframe poses the body's (x forward, z up;
//      lib/localization/camera.h), so T_map_body = T_map_cam * BodyToCamera()^-1.
//   4. Odometry links (type neighbour) between consecutive keyframes; the camera from the
//      options' intrinsics; zones from the keyframe positions (ZonesFromKeyframes, then the
//      annotation rules of `zonemap zones annotate`); then the vocabulary trained from the
//      keyframes and stored (lib/localization/map_vocabulary.h).
//
// OUT is written as OUT.tmp and renamed only when complete (an existing OUT is refused unless
// `overwrite`, and untouched unless the import succeeds).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "common/status.h"
#include "import/orb_keyframe.h"
#include "localization/map_vocabulary.h"
#include "localization/orb_extractor.h"
#include "mapdb/map_db.h"
#include "tum/tum_folder.h"

namespace zm {

struct TumImportOptions {
  TumFolderOptions folder;                 // association tolerance, intrinsics, depth units
  OrbOptions orb;                          // the one extractor's options
  DenseKeyframeOptions dense;
  double max_pose_difference_s = 0.02;     // frame stamp to pose stamp
  double keyframe_distance_m = 0.3;        // RGBD/LinearUpdate-like
  double keyframe_angle_deg = 15.0;        // RGBD/AngularUpdate-like
  double zone_cell_m = 8.0;                // ZonesFromKeyframes' cell
  int zone_max_keyframes = 200;
  MapVocabularyOptions vocabulary;
  bool train_vocabulary = true;
  bool overwrite = false;
  WriteProgressFn progress;                // stage "frames"
};

struct TumImportReport {
  std::string listing;                  // associations.txt or rgb.txt + depth.txt
  std::uint32_t colour_entries = 0;
  std::uint32_t frames = 0;             // associated colour + depth
  std::uint32_t gaps = 0;               // colour without depth
  std::uint32_t malformed_lines = 0;
  std::uint32_t poses = 0;              // lines of the pose file
  std::uint32_t frames_without_pose = 0;
  std::uint32_t refused = 0;            // keyframe candidates whose images could not be used
  std::uint32_t keyframes = 0;
  std::uint64_t features = 0;
  std::uint64_t features_with_point = 0;
  std::uint32_t links = 0;
  std::uint32_t zones = 0;
  std::uint64_t total_payload_bytes = 0;
  std::uint32_t largest_resident_bytes = 0;
  bool vocabulary_trained = false;
  MapVocabularyReport vocabulary;
  CameraIntrinsics camera;
  std::vector<std::string> problems;    // one line per gap, malformed line and refused frame
  double extract_ms = 0.0;              // ORB extraction, total
  double ms = 0.0;
};

[[nodiscard]] Status ValidateTumImportOptions(const TumImportOptions& options);

[[nodiscard]] Result<TumImportReport> ImportTum(const std::string& dir,
                                                const std::string& poses_path,
                                                const std::string& out_path,
                                                const TumImportOptions& options = {});

}  // namespace zm
