// The live line protocol IN: one text line per message, so a ROS node or any other process can
// drive zonemapd over stdin or a loopback UDP socket (the protocol OUT is pose_output.h; both are
// documented together in the README, "Driving zonemapd from a robot").
//
//   frame <stamp_s> <tx> <ty> <tz> <qx> <qy> <qz> <qw> <n> [<u> <v> <descriptor_hex64>] x n
//   image <stamp_s> <tx> <ty> <tz> <qx> <qy> <qz> <qw> <colour_path> <depth_path>
//   route <n> [<x> <y> <z>] x n          the planned path, map frame, replaces the previous one
//   budget <keyframes>                   MemoryThr from now on (down: unload now; up: to the arena)
//
// A frame's pose is the odometry pose (odom frame, metres, quaternion w last as in TUM files);
// each feature is its keypoint in pixels and its 256-bit descriptor as 64 hex digits. An image
// line is the same pose with the camera frame's files instead of features (a camera driver
// writes them, e.g. on tmpfs): a PNG or JPEG colour image and its depth image, or `-` for a
// camera without depth; paths are single tokens (no blanks) of at most kMaxImagePathBytes.
// Reading and checking the files is the session's (daemon.h, image_files.h), not the parser's:
// the parser only hands the two paths on, as views into the line. A route's
// waypoints are map-frame positions (a nav stack's plan; `route 0` clears it). Blank lines and
// lines starting with '#' are ignored. Example of a frame with two features:
//
//   frame 12.5 1.0 2.0 0 0 0 0.7071 0.7071 2 320.5 240 00ff...(64) 17.25 33 a1b2...(64)
//
// Parsing fills reserved storage in place (InputLine): no allocation, no exceptions. This layer
// checks SYNTAX only (numbers finite, counts within the reserve, 64 hex digits, nothing
// trailing); whether a well-formed frame is SANE (stamp increasing, position near the map, unit
// quaternion) is the input gate's call (input_gate.h). Either way a refused line is a LineError
// with a reason (counted per reason by the caller) and the column where it went wrong: a bad
// line is never fatal.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "localization/frame.h"

namespace zm {

enum class LineKind { kFrame, kImage, kRoute, kBudget, kIgnored, kMalformed };

// The longest image path an `image` line may carry (Linux's PATH_MAX less its NUL).
inline constexpr std::size_t kMaxImagePathBytes = 4095;

// Why an input line (or the frame it carried) was refused: each reason has its own counter.
enum class RejectReason : std::uint8_t {
  kSyntax = 0,          // not a protocol line: unknown head, bad number, bad hex, trailing data
  kLineTooLong,         // longer than the largest valid line (the input buffer)
  kTooManyFeatures,     // more features than reserved (zonemapd --max-features)
  kStampNotIncreasing,  // equal to or earlier than the last processed frame's stamp
  kStampOutOfRange,     // |stamp| beyond 2^32 s (ROS time cannot say it)
  kPositionOutsideMap,  // the frame would put the robot beyond the map's extent + margin
  kQuaternionNotUnit,   // | |q| - 1 | above the tolerance (or q = 0)
  kRouteTooLong,        // more waypoints (or zones) than reserved ([input] max_route_waypoints)
  kRouteOutsideMap,     // a waypoint beyond the map's extent + margin
  kBudgetInvalid,       // `budget 0`: K_max must be at least 1
  kNoFrontEnd,          // an `image` line to a zonemapd started without a front-end (--images)
  kCount
};
inline constexpr std::size_t kRejectReasonCount = static_cast<std::size_t>(RejectReason::kCount);
// Stable snake_case names (summary.json keys, telemetry, stderr): "stamp_not_increasing".
[[nodiscard]] const char* RejectReasonName(RejectReason reason);

// Rejections so far, per reason: fixed size, no allocation.
struct RejectCounts {
  std::array<std::uint64_t, kRejectReasonCount> by_reason{};
  std::uint64_t total = 0;
  void Add(RejectReason r) {
    ++by_reason[static_cast<std::size_t>(r)];
    ++total;
  }
  [[nodiscard]] std::uint64_t operator[](RejectReason r) const {
    return by_reason[static_cast<std::size_t>(r)];
  }
};

struct LineError {
  const char* what = "";   // static text, e.g. "bad number in stamp/pose"
  std::size_t column = 0;  // byte offset in the line
  RejectReason reason = RejectReason::kSyntax;
};

// What a line carried, in storage reserved once (Reserve): parsing never allocates.
struct InputLine {
  Frame frame;                             // kFrame, kImage (quaternion normalised)
  double quaternion_norm = 1.0;            // kFrame, kImage: |q| as sent, for the input gate
  // kImage: the files, views into the parsed line (valid until the next line is read). The
  // frame then holds the stamp and pose only: no features, no image (colour_codec kNone).
  std::string_view colour_path;
  std::string_view depth_path;             // "-": the camera has no depth
  std::vector<Eigen::Vector3d> waypoints;  // kRoute
  std::uint64_t budget_keyframes = 0;      // kBudget

  // The largest frame and route this storage accepts; longer ones are refused, not grown.
  void Reserve(std::uint32_t max_features, std::uint32_t max_waypoints);
  [[nodiscard]] std::uint32_t max_features() const { return max_features_; }
  [[nodiscard]] std::uint32_t max_waypoints() const { return max_waypoints_; }

 private:
  std::uint32_t max_features_ = 0;
  std::uint32_t max_waypoints_ = 0;
};

// Bytes of the longest line InputLine::Reserve(max_features, max_waypoints) can accept (the
// line reader's buffer: a longer line is refused as kLineTooLong without being parsed).
[[nodiscard]] std::size_t MaxInputLineBytes(std::uint32_t max_features,
                                            std::uint32_t max_waypoints);

// Parses one line (without its '\n'). kFrame/kImage/kRoute/kBudget: `out` holds it; kMalformed:
// `error` says why. A route of more waypoints than reserved is kMalformed with
// RejectReason::kRouteTooLong (the rest of the line is not read).
[[nodiscard]] LineKind ParseInputLine(std::string_view line, InputLine* out, LineError* error);

// Formats a frame / an image frame / a route as one protocol line (tests, tools). Allocates.
[[nodiscard]] std::string FormatFrameLine(const Frame& frame);
[[nodiscard]] std::string FormatImageLine(double stamp_s, const Pose3& odom,
                                          std::string_view colour_path,
                                          std::string_view depth_path);
[[nodiscard]] std::string FormatRouteLine(std::span<const Eigen::Vector3d> waypoints);

}  // namespace zm
