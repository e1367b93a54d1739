// The input gate: insane input is counted, never acted on (issue 18 §4). One gate, one set of
// rules, in front of the tick loop and the decide step at every entry point (issue 25 §3):
// zonemapd (daemon.h: live lines and recorded frames), `zonemap run` and the public API's
// MapLoop replay (GatedFrameSource below), MapLoop::Process and ZoneManager::Update (api/). A
// frame that parsed (syntax: line_protocol.h for the live protocol; finite numbers and the
// feature reserve for the public API's structs) reaches the loop only if it is sane:
//
//   stamp       finite, |stamp| <= 2^32 s (ROS time cannot say more), and strictly greater than
//               the last frame accepted (equal or earlier: refused; the first frame sets the
//               clock). The loop runs on the frames' own clock (basic's ages, the update rate):
//               a stamp going back, or standing still, would corrupt both.
//   position    where the frame would put the robot in the map (the current map<-odom correction
//               applied to its odometry; the public ZoneManager's pose is in the map frame
//               already) lies within the map's extent (the bounding box of its keyframes) grown
//               by [input] max_distance_from_map_m on every side. A frame at 10^308 m would
//               otherwise make the policies sort tiles at infinity.
//   quaternion  | |q| - 1 | <= [input] quaternion_tolerance: normalised (the parser already did);
//               beyond: refused (a non-unit quaternion is a bug upstream, not a rotation). A
//               recorded frame's pose is a rotation matrix already (norm 1).
//   waypoints   every waypoint of a route within the same extent (else the whole route is
//               refused: a plan through nowhere is not a plan).
//
// Each refusal is one RejectReason, counted by the caller (RejectCounts); RejectRule says the
// rule in words, the same at every entry point. Nothing here allocates; the gate keeps only the
// last stamp.
#pragma once

#include <cstdint>
#include <optional>
#include <span>

#include <Eigen/Core>

#include "common/status.h"
#include "geometry/pose.h"
#include "memory/map_index.h"
#include "runtime/frame_source.h"
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

// The bounding box of the map's keyframe positions (zero for an empty map).
[[nodiscard]] MapExtent ExtentOf(const MapIndex& index);

// The gate's rule behind `reason`, in words ("stamp not greater than the last accepted frame's");
// static text, for every entry point's diagnostics and errors. Empty for the parsers' reasons.
[[nodiscard]] const char* RejectRule(RejectReason reason);

class InputGate {
 public:
  // `extent` is the map's (keyframe positions); the margin comes from the options.
  InputGate(const InputOptions& options, const MapExtent& extent);

  // true: the frame may be processed, and its stamp becomes the last one. false: *why says
  // which rule refused it (the stamp is not taken). `quaternion_norm` is |q| as sent;
  // `map_from_odom` the loop's current correction (identity for a map-frame pose).
  [[nodiscard]] bool AcceptFrame(double stamp_s, const Pose3& odom, double quaternion_norm,
                                 const Pose3& map_from_odom, RejectReason* why);
  [[nodiscard]] bool AcceptFrame(const Frame& frame, double quaternion_norm,
                                 const Pose3& map_from_odom, RejectReason* why) {
    return AcceptFrame(frame.stamp_s, frame.odom, quaternion_norm, map_from_odom, why);
  }
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

// A recorded replay through the gate (`zonemap run`, MapLoop's replay mode): a refused frame is
// counted and skipped, and the next one read. Gates from Attach() on (the extent and the loop's
// correction exist only once the loop is built over this source).
class GatedFrameSource final : public FrameSource {
 public:
  explicit GatedFrameSource(FrameSource& inner) : inner_(inner) {}
  // `map_from_odom` is the loop's correction (TickLoop::map_from_odom()); it must outlive this.
  void Attach(const InputOptions& options, const MapExtent& extent, const Pose3* map_from_odom);
  Result<bool> Next(Frame* frame) override;
  [[nodiscard]] std::uint32_t max_features() const override { return inner_.max_features(); }
  [[nodiscard]] Images images() const override { return inner_.images(); }
  [[nodiscard]] std::uint64_t malformed_lines() const override {
    return inner_.malformed_lines() + rejects_.total;
  }
  bool FrameWaiting() override { return inner_.FrameWaiting(); }
  [[nodiscard]] const RejectCounts& rejects() const { return rejects_; }

 private:
  FrameSource& inner_;
  std::optional<InputGate> gate_;
  const Pose3* map_from_odom_ = nullptr;
  RejectCounts rejects_;
};

}  // namespace zm
