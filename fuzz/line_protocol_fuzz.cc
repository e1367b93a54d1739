// libFuzzer target: the live line protocol (lib/runtime/line_protocol.h). Any line must parse
// as a frame, be ignored or be reported malformed with a column inside the line; a frame never
// holds more features than the capacity given; a parsed frame formats back to a line that
// parses to the same feature count.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "runtime/line_protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  constexpr std::size_t kMaxFeatures = 16;
  static zm::Frame frame = [] {
    zm::Frame f;
    f.Reserve(kMaxFeatures);
    return f;
  }();
  // Exactly `size` bytes on the heap so ASan catches a read past the end of the line.
  const std::string line(reinterpret_cast<const char*>(data), size);
  zm::LineError error;
  const zm::LineKind kind = zm::ParseFrameLine(line, kMaxFeatures, &frame, &error);
  if (kind == zm::LineKind::kMalformed) {
    if (error.what == nullptr || error.column > size) std::abort();
  } else if (kind == zm::LineKind::kFrame) {
    if (frame.descriptors.size() > kMaxFeatures || frame.keypoints.size() != 2 * frame.descriptors.size()) {
      std::abort();
    }
    const std::uint32_t n = frame.feature_count();
    const std::string again = zm::FormatFrameLine(frame);
    zm::Frame back;
    back.Reserve(kMaxFeatures);
    zm::LineError e2;
    if (zm::ParseFrameLine(again, kMaxFeatures, &back, &e2) != zm::LineKind::kFrame ||
        back.feature_count() != n) {
      std::abort();
    }
  }
  return 0;
}
