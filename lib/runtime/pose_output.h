// The live line protocol OUT: what zonemapd tells the robot (the protocol IN is line_protocol.h;
// the README documents both, with the mapping onto ROS messages).
//
//   hello zonemapd <version> key value ...                          once, at start (stdout)
//   pose <stamp> <tx> <ty> <tz> <qx> <qy> <qz> <qw> <version>      every processed frame
//        <mo_tx> <mo_ty> <mo_tz> <mo_qx> <mo_qy> <mo_qz> <mo_qw>
//        <status> <frames_since_fix> <zone> <closure> <inliers> <resident> <k_max> <tick_ms>
//        <malformed> <covariance: 36 numbers, row-major>
//   ack route <ok|rejected> <waypoints> <zones> [<zone id>] x zones
//   ack budget <ok|clamped|ignored|refused> <requested> <k_max> <resident> <unloaded>
//
// (one line each; the pose line is 62 space-separated tokens, index 0 = "pose"). Poses are the
// corrected body pose in the map frame (TUM order, quaternion w last) and the map<-odom
// correction T_map_odom (the pose = T_map_odom * odometry; REP-105's map->odom transform).
//
// Status (PoseTracker), like isaac_ros_visual_slam's tracking state:
//   localized       a loop closure was accepted on this frame (the pose is the PnP fix);
//   dead_reckoning  no closure on this frame; the pose is odometry under the last correction and
//                   its horizontal 1-sigma uncertainty (sqrt of the largest eigenvalue of the
//                   covariance's x-y block) is at most [output] lost_sigma_m;
//   lost            that uncertainty exceeds lost_sigma_m (never localized since start counts
//                   as an uncertainty of [output] initial_sigma_m).
// frames_since_fix counts frames since the last accepted closure (since start before the first).
//
// Covariance (6x6, x y z then rotation about the map's X Y Z axes, as geometry_msgs/
// PoseWithCovariance; m^2, rad^2):
//   on a closure    the PnP solution's: sigma^2 (J^T J)^-1 over its inliers, sigma^2 from their
//                   reprojection residuals, carried from the camera to the body (localizer.h),
//                   plus diag(map_sigma_m^2 x3, map_sigma_deg^2 x3): the map's own error, which
//                   the residuals of one solve cannot see (keyframe point and pose errors shared
//                   by every frame localized on that keyframe, RANSAC truncating the residual
//                   distribution at its threshold). Without it the 95 % ellipse held 45-55 % of the
//                   fixes on a simulated hospital, with it 97 %; docs/runtime.md has the
//                   calibration;
//   dead reckoning  propagated per frame like an EKF prediction with a random-walk odometry:
//                   C <- F C F^T + Q, F = [[I, -[dp]x], [0, I]] (dp = the frame's map-frame
//                   displacement: a heading error turns into a lateral one as the robot drives),
//                   Q = diag(a dp_xy, a dp_xy, 0, 0, 0, b dp_xy) with a = odom_sigma_m_per_sqrt_m^2,
//                   b = odom_sigma_deg_per_sqrt_m^2 (in rad): variance linear in distance, so a
//                   robot that stands still does not drift; z, roll and pitch keep the fix's
//                   (a ground robot's odometry);
//   at start        diag(initial_sigma_m^2 x3, initial_sigma_deg^2 x3).
//
// Formatting writes into a caller-owned buffer with std::to_chars (text_line.h): no allocation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "common/ids.h"
#include "geometry/pose.h"
#include "runtime/telemetry.h"

namespace zm {

// The version every pose line carries (token 9) and the hello line announces. Bumped whenever a
// field is added, removed, moved or changes meaning: a parser of version N expects exactly
// kPoseLineTokens tokens and refuses any other count (tests/runtime/pose_output_test.cc).
inline constexpr int kPoseProtocolVersion = 1;
inline constexpr std::size_t kPoseLineTokens = 62;
inline constexpr std::size_t kPoseLineMaxBytes = 2048;

using Covariance6 = Eigen::Matrix<double, 6, 6>;

// [output] in a profile (docs/runtime.md): the uncertainty model above.
struct PoseOutputOptions {
  double map_sigma_m = 0.015;               // the map's own position error, added to every fix
  double map_sigma_deg = 0.5;               // the map's own rotation error, added to every fix
  double initial_sigma_m = 10.0;            // position uncertainty before the first closure
  double initial_sigma_deg = 180.0;         // rotation uncertainty before the first closure
  double odom_sigma_m_per_sqrt_m = 0.05;    // odometry position noise after 1 m travelled
  double odom_sigma_deg_per_sqrt_m = 1.0;   // odometry heading noise after 1 m travelled
  double lost_sigma_m = 2.0;                // horizontal 1-sigma beyond which the robot is lost
};

enum class LocalizationStatus : std::uint8_t { kLocalized, kDeadReckoning, kLost };
[[nodiscard]] const char* LocalizationStatusName(LocalizationStatus s);

// Tracks the status and the covariance frame by frame (see the file comment). No allocation.
class PoseTracker {
 public:
  explicit PoseTracker(const PoseOutputOptions& options);
  // Call once per processed frame, in order.
  void Update(const TickRecord& record);

  [[nodiscard]] LocalizationStatus status() const { return status_; }
  [[nodiscard]] std::uint64_t frames_since_fix() const { return frames_since_fix_; }
  [[nodiscard]] const Covariance6& covariance() const { return cov_; }
  // Horizontal 1-sigma (m): sqrt of the largest eigenvalue of the x-y block.
  [[nodiscard]] double sigma_xy_m() const { return sigma_xy_m_; }
  [[nodiscard]] bool ever_localized() const { return ever_localized_; }

 private:
  PoseOutputOptions options_;
  Covariance6 map_floor_;  // diag(map_sigma_m^2 x3, map_sigma_deg^2 x3), added to every fix
  Covariance6 cov_;
  Eigen::Vector3d last_position_ = Eigen::Vector3d::Zero();
  bool has_last_ = false;
  bool ever_localized_ = false;
  std::uint64_t frames_since_fix_ = 0;
  double sigma_xy_m_ = 0.0;
  LocalizationStatus status_ = LocalizationStatus::kLost;
};

// Everything one pose line carries, in order (format and parse are each other's inverse).
struct PoseLine {
  double stamp_s = 0.0;
  Pose3 pose = Pose3::Identity();           // T_map_body
  int version = kPoseProtocolVersion;
  Pose3 map_from_odom = Pose3::Identity();  // T_map_odom
  LocalizationStatus status = LocalizationStatus::kLost;
  std::uint64_t frames_since_fix = 0;
  std::int32_t zone = -1;                   // -1: outside every zone
  bool loop_closure = false;
  std::uint32_t inliers = 0;
  std::uint32_t resident_keyframes = 0;
  std::uint32_t k_max = 0;
  double tick_ms = 0.0;
  std::uint64_t malformed = 0;              // input lines refused so far (every reason)
  Covariance6 covariance = Covariance6::Zero();
};

// The pose line of one tick: the record's fields and the tracker's status and covariance (after
// tracker.Update(record)). The one place a tick becomes a pose line.
[[nodiscard]] PoseLine PoseLineOf(const TickRecord& record, const PoseTracker& tracker);

// One pose line ending in '\n' into buf. Returns its length, 0 if it does not fit (use
// kPoseLineMaxBytes). Never allocates.
[[nodiscard]] std::size_t FormatPoseLine(const PoseLine& line, char* buf, std::size_t capacity);
// Parses a pose line (with or without '\n'); false on any deviation from the format, including
// another version. Never allocates.
[[nodiscard]] bool ParsePoseLine(std::string_view text, PoseLine* out);

// Acknowledgements (see the file comment). Each returns the length written ('\n' included), 0
// if it does not fit. Never allocate.
[[nodiscard]] std::size_t FormatRouteAck(bool accepted, std::uint64_t waypoints,
                                         std::span<const ZoneId> zones, char* buf,
                                         std::size_t capacity);
// Bytes FormatRouteAck needs for a route of `zones` zones.
[[nodiscard]] std::size_t RouteAckMaxBytes(std::size_t zones);
[[nodiscard]] std::size_t FormatBudgetAck(const char* outcome, std::uint64_t requested,
                                          std::uint32_t k_max, std::uint32_t resident,
                                          std::uint32_t unloaded, char* buf,
                                          std::size_t capacity);

}  // namespace zm
