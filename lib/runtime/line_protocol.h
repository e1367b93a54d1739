// The live line protocol: one text line per frame, so a ROS node or any other process can drive
// zonemapd over stdin or a loopback UDP socket.
//
//   frame <stamp_s> <tx> <ty> <tz> <qx> <qy> <qz> <qw> <n> [<u> <v> <descriptor_hex64>] x n
//
// The pose is the odometry pose (odom frame, metres, unit quaternion, w last as in TUM files);
// each feature is its keypoint in pixels and its 256-bit descriptor as 64 hex digits. Blank
// lines and lines starting with '#' are ignored. Example with two features:
//
//   frame 12.5 1.0 2.0 0 0 0 0.7071 0.7071 2 320.5 240 00ff...(64) 17.25 33 a1b2...(64)
//
// Parsing fills a reserved Frame in place: no allocation, no exceptions. A malformed line is
// reported as a LineError (with the column where it went wrong) and the caller counts it and
// skips it: a bad line is never fatal.
#pragma once

#include <cstdint>
#include <string_view>

#include "localization/frame.h"

namespace zm {

enum class LineKind { kFrame, kIgnored, kMalformed };

struct LineError {
  const char* what = "";   // static text, e.g. "bad number"
  std::size_t column = 0;  // byte offset in the line
};

// Parses one line. On kFrame, `frame` holds it (index is left to the caller). Features beyond
// max_features (the Frame's reserved capacity) make the line malformed rather than allocate.
[[nodiscard]] LineKind ParseFrameLine(std::string_view line, std::size_t max_features,
                                      Frame* frame, LineError* error);

// Formats a frame as one protocol line (tests, the replay-to-socket tool). Allocates.
[[nodiscard]] std::string FormatFrameLine(const Frame& frame);

}  // namespace zm
