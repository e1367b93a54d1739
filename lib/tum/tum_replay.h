// `zonemapd --tum DIR [--odom FILE]` (issue 26 §4): a TUM RGB-D folder replayed into zonemapd as
// camera files (runtime/image_files.h's CameraFileSource), one frame per colour image in stamp
// order. The folder is listed once at start (tum_folder.h); zonemapd's session reads each
// frame's colour file at its input edge and the loop's front-end decodes it, as for an `image`
// line, so a replay and a camera driver take the same path.
//
//   frames     every colour entry of the listing, by stamp; one without depth within the
//              association tolerance (a gap) is handed on with an empty depth path and a note,
//              and the session runs it on odometry, counted (ImageRefusal::kNoDepth)
//   odometry   FILE is a TUM trajectory of the colour camera ("stamp tx ty tz qx qy qz qw", the
//              optical frame, as groundtruth.txt or a visual odometry's output): each frame takes
//              the pose of the nearest stamp within max_odom_difference_s, as the body pose
//              T_odom_body = T_odom_cam * BodyToCamera()^-1 (the convention of import-tum and of
//              lib/localization/camera.h). A frame without one holds the odometry of the frame
//              before (counted): no motion, so the loop predicts the previous estimate.
//              Without FILE every frame holds `start`: the prediction is always the previous
//              estimate (the map<-odom correction of the last closure), as a visual-only
//              localizer's constant-position model, and the first frame's is `start` itself.
//              zonemapd gives the map's first keyframe's pose, where the map's recording began:
//              the memory policy must load the zone the robot is in before anything can close
//              (the map's origin may lie in no zone at all).
//   camera     the folder's intrinsics (flags, freiburg1's by default) must be the map camera's
//              at the images' size (a plain scale: ScaledIntrinsics), else Open fails naming both:
//              the front-end puts keypoints into the map camera's pixels by that scale alone.
//   pacing     none: frames are handed on as fast as the session ticks, as a frames file
//              (--frames) is; the loop still runs on the frames' clock (their stamps).
//
// Everything is read in Open(); Next() hands out views into the listing and never allocates.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/status.h"
#include "geometry/pose.h"
#include "runtime/image_files.h"
#include "tum/tum_folder.h"

namespace zm {

struct TumReplayOptions {
  TumFolderOptions folder;              // association tolerance, intrinsics
  std::string odom_path;                // TUM trajectory of the colour camera ("" = none)
  double max_odom_difference_s = 0.02;  // frame stamp to odometry stamp
  // The odometry held before the first pose, and throughout without an odometry file (body).
  Pose3 start = Pose3::Identity();
};

class TumReplay final : public CameraFileSource {
 public:
  // Lists `dir`, reads the odometry file, checks the camera against the map's. Errors name the
  // folder or the file (ReadTumFolder's, ReadTrajectory's) or both cameras.
  [[nodiscard]] static Result<std::unique_ptr<TumReplay>> Open(const std::string& dir,
                                                               const TumReplayOptions& options,
                                                               const CameraIntrinsics& map_camera);

  Result<bool> Next(CameraFrameFiles* out) override;
  [[nodiscard]] std::uint32_t width() const override { return camera_.width; }
  [[nodiscard]] std::uint32_t height() const override { return camera_.height; }
  [[nodiscard]] const char* kind() const override { return "tum"; }
  [[nodiscard]] std::uint64_t frames_without_odometry() const override { return held_; }

  // What was listed: frames with depth, gaps, malformed lines (with their lines in
  // listing_problems()), the listing used.
  [[nodiscard]] const TumFolder& folder() const { return folder_; }
  // The listing's malformed lines, one line each (the gaps are said when they are replayed).
  [[nodiscard]] const std::vector<std::string>& listing_problems() const { return problems_; }
  [[nodiscard]] std::size_t frame_count() const { return frames_.size(); }
  [[nodiscard]] std::size_t odometry_poses() const { return odometry_poses_; }

 private:
  struct ReplayFrame {
    const TumFrameFiles* files = nullptr;  // into folder_.frames or folder_.gap_frames
    bool has_odom = false;
    Pose3 odom = Pose3::Identity();  // body, odom frame
  };
  TumReplay() = default;

  TumFolder folder_;
  CameraIntrinsics camera_;
  std::vector<ReplayFrame> frames_;
  std::vector<std::string> problems_;
  std::string gap_note_;
  std::size_t odometry_poses_ = 0;
  std::size_t next_ = 0;
  std::uint64_t held_ = 0;
  Pose3 last_odom_ = Pose3::Identity();
};

}  // namespace zm
