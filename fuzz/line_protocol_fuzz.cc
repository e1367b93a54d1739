// libFuzzer target: the live line protocol IN (lib/runtime/line_protocol.h) and the pose line OUT
// (lib/runtime/pose_output.h). Any input line must parse as a frame, an image frame, a route or a
// budget, be ignored, or be reported malformed with a column inside the line and a reason; a
// frame never holds more features than reserved, a route more waypoints; an image frame's paths
// are non-empty tokens inside the line, within kMaxImagePathBytes, and it carries no features; a
// parsed frame, image frame or route formats back to a line that parses to the same. The same bytes
// given to ParsePoseLine must either be refused or parse to a line that formats within the
// documented size.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "runtime/line_protocol.h"
#include "runtime/pose_output.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  constexpr std::uint32_t kMaxFeatures = 16;
  constexpr std::uint32_t kMaxWaypoints = 16;
  static zm::InputLine input = [] {
    zm::InputLine in;
    in.Reserve(kMaxFeatures, kMaxWaypoints);
    return in;
  }();
  // Exactly `size` bytes on the heap so ASan catches a read past the end of the line.
  const std::string line(reinterpret_cast<const char*>(data), size);
  zm::LineError error;
  const zm::LineKind kind = zm::ParseInputLine(line, &input, &error);
  if (kind == zm::LineKind::kMalformed) {
    if (error.what == nullptr || error.column > size ||
        error.reason >= zm::RejectReason::kCount) {
      std::abort();
    }
  } else if (kind == zm::LineKind::kFrame) {
    const zm::Frame& frame = input.frame;
    if (frame.descriptors.size() > kMaxFeatures ||
        frame.keypoints.size() != 2 * frame.descriptors.size()) {
      std::abort();
    }
    const std::uint32_t n = frame.feature_count();
    const std::string again = zm::FormatFrameLine(frame);
    zm::InputLine back;
    back.Reserve(kMaxFeatures, kMaxWaypoints);
    zm::LineError e2;
    if (zm::ParseInputLine(again, &back, &e2) != zm::LineKind::kFrame ||
        back.frame.feature_count() != n) {
      std::abort();
    }
  } else if (kind == zm::LineKind::kImage) {
    const auto inside = [&](std::string_view p) {
      return !p.empty() && p.size() <= zm::kMaxImagePathBytes && p.data() >= line.data() &&
             p.data() + p.size() <= line.data() + line.size() &&
             p.find_first_of(" \t\r") == std::string_view::npos;
    };
    if (!inside(input.colour_path) || !inside(input.depth_path) ||
        input.frame.feature_count() != 0 || input.frame.has_image()) {
      std::abort();
    }
    const std::string again = zm::FormatImageLine(input.frame.stamp_s, input.frame.odom,
                                                  input.colour_path, input.depth_path);
    zm::InputLine back;
    back.Reserve(kMaxFeatures, kMaxWaypoints);
    zm::LineError e2;
    if (zm::ParseInputLine(again, &back, &e2) != zm::LineKind::kImage ||
        back.colour_path != input.colour_path || back.depth_path != input.depth_path) {
      std::abort();
    }
  } else if (kind == zm::LineKind::kRoute) {
    if (input.waypoints.size() > kMaxWaypoints) std::abort();
    const std::string again = zm::FormatRouteLine(input.waypoints);
    zm::InputLine back;
    back.Reserve(kMaxFeatures, kMaxWaypoints);
    zm::LineError e2;
    if (zm::ParseInputLine(again, &back, &e2) != zm::LineKind::kRoute ||
        back.waypoints.size() != input.waypoints.size()) {
      std::abort();
    }
  } else if (kind == zm::LineKind::kBudget) {
    if (input.budget_keyframes == 0) std::abort();
  }
  zm::PoseLine pose;
  if (zm::ParsePoseLine(line, &pose)) {
    char buf[zm::kPoseLineMaxBytes];
    // A parsed line may hold huge numbers, which then need more room than 2048 bytes: only a
    // line that fits must fit exactly once more, and parse back.
    const std::size_t n = zm::FormatPoseLine(pose, buf, sizeof buf);
    zm::PoseLine again;
    if (n > 0 && !zm::ParsePoseLine(std::string_view(buf, n), &again)) std::abort();
  }
  return 0;
}
