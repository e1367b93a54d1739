// The live protocol: round trip, every malformed shape counted not fatal, no allocation.
#include "runtime/line_protocol.h"

#include <doctest/doctest.h>

#include "support/counting_allocator.h"

namespace zm {
namespace {

Frame MakeFrame(std::uint32_t n) {
  Frame f;
  f.stamp_s = 12.25;
  f.odom = PoseFromXYYaw(1.5, -2.0, 0.3, 0.1);
  for (std::uint32_t i = 0; i < n; ++i) {
    Descriptor256 d{};
    for (std::size_t b = 0; b < d.size(); ++b) d[b] = static_cast<std::uint8_t>(i * 31 + b);
    f.descriptors.push_back(d);
    f.keypoints.push_back(10.5f + static_cast<float>(i));
    f.keypoints.push_back(20.25f);
  }
  return f;
}

TEST_CASE("a formatted frame parses back to the same frame") {
  const Frame in = MakeFrame(3);
  Frame out;
  out.Reserve(8);
  LineError err;
  REQUIRE(ParseFrameLine(FormatFrameLine(in), 8, &out, &err) == LineKind::kFrame);
  CHECK(out.stamp_s == doctest::Approx(12.25));
  CHECK(out.odom.translation().isApprox(in.odom.translation(), 1e-6));
  CHECK(out.odom.linear().isApprox(in.odom.linear(), 1e-6));
  REQUIRE(out.feature_count() == 3);
  CHECK(out.descriptors == in.descriptors);
  CHECK(out.keypoints == in.keypoints);
}

TEST_CASE("comments and blank lines are ignored") {
  Frame f;
  LineError err;
  CHECK(ParseFrameLine("", 4, &f, &err) == LineKind::kIgnored);
  CHECK(ParseFrameLine("   ", 4, &f, &err) == LineKind::kIgnored);
  CHECK(ParseFrameLine("# hello", 4, &f, &err) == LineKind::kIgnored);
}

TEST_CASE("malformed lines are reported with a reason, never fatal") {
  Frame f;
  f.Reserve(2);
  LineError err;
  const std::string hex(64, 'a');
  struct Case { std::string line; const char* why; };
  const Case cases[] = {
      {"pose 1 2 3", "start"},
      {"frame 1 2 3", "number"},
      {"frame 1 0 0 0 0 0 0 1 x", "count"},
      {"frame 1 0 0 0 0 0 0 0 0", "quaternion"},
      {"frame 1 0 0 0 0 0 0 1 3 1 2 " + hex + " 1 2 " + hex + " 1 2 " + hex, "capacity"},
      {"frame 1 0 0 0 0 0 0 1 1 1 2 abc", "64 hex"},
      {"frame 1 0 0 0 0 0 0 1 1 1 2 " + std::string(63, 'a') + "g", "hex digit"},
      {"frame 1 0 0 0 0 0 0 1 1 1 2 " + hex + " extra", "trailing"},
      {"frame nan 0 0 0 0 0 0 1 0", "number"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.line);
    CHECK(ParseFrameLine(c.line, 2, &f, &err) == LineKind::kMalformed);
    CHECK(std::string(err.what).find(c.why) != std::string::npos);
  }
}

TEST_CASE("parsing into a reserved frame allocates nothing") {
  const std::string line = FormatFrameLine(MakeFrame(16));
  Frame f;
  f.Reserve(16);
  LineError err;
  test::AllocationCounter counter;
  for (int i = 0; i < 100; ++i) REQUIRE(ParseFrameLine(line, 16, &f, &err) == LineKind::kFrame);
  CHECK(counter.allocations() == 0);
}

}  // namespace
}  // namespace zm
