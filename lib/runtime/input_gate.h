// The input gate: insane input is counted, never acted on (issue 18 §4). A frame that parsed
// (line_protocol.h checks syntax) reaches the tick loop only if it is sane:
//
//   stamp       finite, |stamp| <= 2^32 s (ROS time cannot say more), and strictly greater than
//               the last frame the loop processed (equal or earlier: refused; the first frame
//               sets the clock). The loop runs on the frames' own clock (basic's ages, the
//               update rate): a stamp going back would corrupt both.
//   position    where the frame would put the robot in the map (the current map<-odom correction
//               applied to its odometry) lies within the map's extent (the bounding box of its
//               keyframes) grown by [input] max_distance_from_map_m on every side. A frame at
//               10^308 m would otherwise make the policies sort tiles at infinity.
//   quaternion  | |q| - 1 | <= [input] quaternion_tolerance: normalised (the parser already did);
//               beyond: refused (a non-unit quaternion is a bug upstream, not a rotation).
//   waypoints   every waypoint of a route within the same extent (else the whole route is
//               refused: a plan through nowhere is not a plan).
//
// Each refusal is one RejectReason, counted by the caller (RejectCounts). Nothing here
// allocates; the gate keeps only the last stamp.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "geometry/pose.h"
#include "runtime/line_protocol.h"

namespace zm {

// [input] in a profile (docs/runtime.md).
struct InputOptions {
  double max_distance_from_map_m = 50.0;     // margin around the map's extent (m)
  double quaternion_tolerance = 0.01;        // allowed | |q| - 1 | before normalising
  std::uint32_t max_route_waypoints = 4096;  // reserve for route lines (and their zone sequence)
};

// An axis-aligned box in the map frame (metres).
struct MapExtent {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
};

// Largest |stamp| accepted (s): ROS 1 time is an unsigned 32-bit second count.
inline constexpr double kMaxStampS = 4294967296.0;

class InputGate {
 public:
  // `extent` is the map's (keyframe positions); the margin comes from the options.
  InputGate(const InputOptions& options, const MapExtent& extent);

  // true: the frame may be processed, and its stamp becomes the last one. false: *why says
  // which rule refused it (the stamp is not taken). `quaternion_norm` is |q| as sent;
  // `map_from_odom` the loop's current correction.
  [[nodiscard]] bool AcceptFrame(const Frame& frame, double quaternion_norm,
                                 const Pose3& map_from_odom, RejectReason* why);
  // true when every waypoint lies within the extent grown by the margin.
  [[nodiscard]] bool AcceptRoute(std::span<const Eigen::Vector3d> waypoints) const;

  [[nodiscard]] bool InsideExtent(const Eigen::Vector3d& p_map) const;
  [[nodiscard]] bool has_stamp() const { return has_stamp_; }
  [[nodiscard]] double last_stamp_s() const { return last_stamp_s_; }
  [[nodiscard]] const InputOptions& options() const { return options_; }
  [[nodiscard]] const MapExtent& extent() const { return extent_; }

 private:
  InputOptions options_;
  MapExtent extent_;
  Eigen::Vector3d lo_, hi_;  // extent grown by the margin
  bool has_stamp_ = false;
  double last_stamp_s_ = 0.0;
};

}  // namespace zm
