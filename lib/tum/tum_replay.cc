// A TUM RGB-D folder replayed as camera files (see tum_replay.h).
#include "tum/tum_replay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "geometry/trajectory.h"
#include "localization/camera.h"

namespace zm {
namespace {

std::string CameraText(const CameraIntrinsics& k) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "fx %.2f fy %.2f cx %.2f cy %.2f, %ux%u", k.fx, k.fy, k.cx, k.cy,
                k.width, k.height);
  return buf;
}

// The folder's camera is the map's at its size: within 0.5 % (and 0.01 px), the rounding of a
// plain scale written with a few decimals.
bool SameCamera(const CameraIntrinsics& a, const CameraIntrinsics& b) {
  const auto near = [](double x, double y) {
    return std::abs(x - y) <= 0.005 * std::abs(y) + 0.01;
  };
  return a.width == b.width && a.height == b.height && near(a.fx, b.fx) && near(a.fy, b.fy) &&
         near(a.cx, b.cx) && near(a.cy, b.cy);
}

}  // namespace

Result<std::unique_ptr<TumReplay>> TumReplay::Open(const std::string& dir,
                                                   const TumReplayOptions& options,
                                                   const CameraIntrinsics& map_camera) {
  if (!(options.max_odom_difference_s > 0.0) || !std::isfinite(options.max_odom_difference_s)) {
    return InvalidArgument("odometry association tolerance " +
                           std::to_string(options.max_odom_difference_s) +
                           " s: must be finite and > 0");
  }
  const CameraIntrinsics& camera = options.folder.camera;
  ZM_RETURN_IF_ERROR(ValidateTumFolderOptions(options.folder));
  ZM_RETURN_IF_ERROR(CheckImageSize(map_camera, camera.width, camera.height));
  const CameraIntrinsics expected = ScaledIntrinsics(map_camera, camera.width, camera.height);
  if (!SameCamera(camera, expected)) {
    return InvalidArgument(
        "the TUM camera (" + CameraText(camera) + ") is not the map's camera (" +
        CameraText(map_camera) + ") at that size (" + CameraText(expected) +
        "): give the folder's intrinsics (--fx --fy --cx --cy --width --height)");
  }

  std::unique_ptr<TumReplay> r(new TumReplay());
  r->camera_ = camera;
  r->last_odom_ = options.start;
  ZM_ASSIGN_OR_RETURN(r->folder_, ReadTumFolder(dir, options.folder));
  const TumFolder& f = r->folder_;
  for (const std::string& p : f.problems) {
    if (p.find("(gap)") == std::string::npos) r->problems_.push_back(p);  // gaps: when replayed
  }
  r->gap_note_ = "no depth within " + std::to_string(options.folder.max_stamp_difference_s) +
                 " s of it in " + f.listing + ": a gap";

  // Frames with depth and gaps, in stamp order (each list is sorted already).
  r->frames_.reserve(f.frames.size() + f.gap_frames.size());
  for (const TumFrameFiles& x : f.frames) r->frames_.push_back({&x});
  for (const TumFrameFiles& x : f.gap_frames) r->frames_.push_back({&x});
  std::stable_sort(r->frames_.begin(), r->frames_.end(),
                   [](const ReplayFrame& a, const ReplayFrame& b) {
                     return a.files->stamp_s < b.files->stamp_s;
                   });

  if (!options.odom_path.empty()) {
    ZM_ASSIGN_OR_RETURN(const Trajectory traj,
                        ReadTrajectory(options.odom_path, TrajectoryFormat::kTum));
    r->odometry_poses_ = traj.size();
    std::vector<std::size_t> order(traj.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return traj.stamps_s[a] < traj.stamps_s[b]; });
    std::vector<double> stamps(order.size());
    for (std::size_t i = 0; i < order.size(); ++i) stamps[i] = traj.stamps_s[order[i]];
    for (ReplayFrame& fr : r->frames_) {
      // The nearest stamp: the first at or after the frame's, or the one before it.
      const double s = fr.files->stamp_s;
      const auto it = std::lower_bound(stamps.begin(), stamps.end(), s);
      std::size_t best = stamps.size();
      if (it != stamps.end()) best = static_cast<std::size_t>(it - stamps.begin());
      if (it != stamps.begin()) {
        const std::size_t before = static_cast<std::size_t>(it - stamps.begin()) - 1;
        if (best == stamps.size() || s - stamps[before] <= stamps[best] - s) best = before;
      }
      if (best == stamps.size() || std::abs(stamps[best] - s) > options.max_odom_difference_s) {
        continue;  // held from the frame before, at replay
      }
      fr.has_odom = true;
      fr.odom = BodyPoseFromCamera(traj.poses[order[best]]);
    }
  }
  return r;
}

Result<bool> TumReplay::Next(CameraFrameFiles* out) {
  if (next_ >= frames_.size()) return false;
  const ReplayFrame& fr = frames_[next_++];
  if (fr.has_odom) {
    last_odom_ = fr.odom;
  } else {
    ++held_;  // no motion known: the odometry of the frame before
  }
  out->stamp_s = fr.files->stamp_s;
  out->odom = last_odom_;
  out->colour_path = fr.files->rgb_path;
  out->depth_path = fr.files->depth_path;
  out->note = fr.files->depth_path.empty() ? std::string_view(gap_note_) : std::string_view();
  return true;
}

}  // namespace zm
