// The live protocol IN: round trips of frames, image frames and routes, budgets, every malformed
// shape counted with its reason and never fatal, no allocation.
#include "runtime/line_protocol.h"

#include <doctest/doctest.h>

#include <set>
#include <string>

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

InputLine Reserved(std::uint32_t features, std::uint32_t waypoints) {
  InputLine in;
  in.Reserve(features, waypoints);
  return in;
}

TEST_CASE("a formatted frame parses back to the same frame") {
  const Frame in = MakeFrame(3);
  InputLine out = Reserved(8, 4);
  LineError err;
  REQUIRE(ParseInputLine(FormatFrameLine(in), &out, &err) == LineKind::kFrame);
  CHECK(out.frame.stamp_s == doctest::Approx(12.25));
  CHECK(out.frame.odom.translation().isApprox(in.odom.translation(), 1e-6));
  CHECK(out.frame.odom.linear().isApprox(in.odom.linear(), 1e-6));
  CHECK(out.quaternion_norm == doctest::Approx(1.0));
  REQUIRE(out.frame.feature_count() == 3);
  CHECK(out.frame.descriptors == in.descriptors);
  CHECK(out.frame.keypoints == in.keypoints);
}

TEST_CASE("a non-unit quaternion is normalised and its length reported to the gate") {
  InputLine out = Reserved(2, 2);
  LineError err;
  REQUIRE(ParseInputLine("frame 1 0 0 0 0 0 0 2 0", &out, &err) == LineKind::kFrame);
  CHECK(out.quaternion_norm == doctest::Approx(2.0));
  CHECK(out.frame.odom.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  CHECK(ParseInputLine("frame 1 0 0 0 0 0 0 0 0", &out, &err) == LineKind::kMalformed);
  CHECK(err.reason == RejectReason::kQuaternionNotUnit);
}

TEST_CASE("an image line gives the stamp, the pose and the two paths, and no features or image") {
  const Frame pose = MakeFrame(0);
  InputLine out = Reserved(4, 2);
  LineError err;
  // A frame line first, with an image left in the buffers (the session swaps frames around).
  REQUIRE(ParseInputLine(FormatFrameLine(MakeFrame(3)), &out, &err) == LineKind::kFrame);
  out.frame.colour_codec = ImageCodec::kPng;
  out.frame.colour.assign(10, std::byte{1});
  const std::string line =
      FormatImageLine(1305031100.123456, pose.odom, "/dev/shm/cam/rgb 1.png", "/dev/shm/cam/d.png");
  // A path is one token: the space above makes it three, so the line is refused ...
  CHECK(ParseInputLine(line, &out, &err) == LineKind::kMalformed);
  CHECK(std::string(err.what).find("trailing") != std::string::npos);
  // ... and without it the line parses.
  const std::string ok =
      FormatImageLine(1305031100.123456, pose.odom, "/dev/shm/cam/rgb1.png", "/dev/shm/cam/d.png");
  CHECK(ok.rfind("image 1305031100.123456 ", 0) == 0);
  REQUIRE(ParseInputLine(ok, &out, &err) == LineKind::kImage);
  CHECK(out.frame.stamp_s == doctest::Approx(1305031100.123456).epsilon(1e-15));
  CHECK(out.frame.odom.isApprox(pose.odom, 1e-6));
  CHECK(out.quaternion_norm == doctest::Approx(1.0));
  CHECK(out.colour_path == "/dev/shm/cam/rgb1.png");
  CHECK(out.depth_path == "/dev/shm/cam/d.png");
  CHECK(out.frame.feature_count() == 0);
  CHECK(out.frame.keypoints.empty());
  CHECK_FALSE(out.frame.has_image());
  CHECK(out.frame.colour.empty());
  // '-': a camera without depth.
  REQUIRE(ParseInputLine("image 2 0 0 0 0 0 0 1 a.jpg -", &out, &err) == LineKind::kImage);
  CHECK(out.colour_path == "a.jpg");
  CHECK(out.depth_path == "-");
  // A frame line after an image line carries no image either.
  out.frame.colour_codec = ImageCodec::kJpeg;
  REQUIRE(ParseInputLine(FormatFrameLine(MakeFrame(2)), &out, &err) == LineKind::kFrame);
  CHECK_FALSE(out.frame.has_image());
  CHECK(out.frame.feature_count() == 2);
}

TEST_CASE("routes and budgets") {
  InputLine out = Reserved(2, 3);
  LineError err;
  const std::vector<Eigen::Vector3d> wp{{0, 0, 0}, {10.5, 2, 0}, {20, 2.25, 3}};
  REQUIRE(ParseInputLine(FormatRouteLine(wp), &out, &err) == LineKind::kRoute);
  CHECK(out.waypoints == wp);
  REQUIRE(ParseInputLine("route 0", &out, &err) == LineKind::kRoute);
  CHECK(out.waypoints.empty());
  CHECK(ParseInputLine("route 4 0 0 0 1 1 0 2 2 0 3 3 0", &out, &err) == LineKind::kMalformed);
  CHECK(err.reason == RejectReason::kRouteTooLong);
  REQUIRE(ParseInputLine("budget 250", &out, &err) == LineKind::kBudget);
  CHECK(out.budget_keyframes == 250);
  CHECK(ParseInputLine("budget 0", &out, &err) == LineKind::kMalformed);
  CHECK(err.reason == RejectReason::kBudgetInvalid);
}

TEST_CASE("comments and blank lines are ignored") {
  InputLine f = Reserved(4, 4);
  LineError err;
  CHECK(ParseInputLine("", &f, &err) == LineKind::kIgnored);
  CHECK(ParseInputLine("   ", &f, &err) == LineKind::kIgnored);
  CHECK(ParseInputLine("# hello", &f, &err) == LineKind::kIgnored);
}

TEST_CASE("malformed lines are reported with a reason, never fatal") {
  InputLine f = Reserved(2, 2);
  LineError err;
  const std::string hex(64, 'a');
  struct Case {
    std::string line;
    const char* why;
    RejectReason reason;
  };
  const RejectReason syntax = RejectReason::kSyntax;
  const Case cases[] = {
      {"pose 1 2 3", "start", syntax},
      {"frame 1 2 3", "number", syntax},
      {"frame 1 0 0 0 0 0 0 1 x", "count", syntax},
      {"frame 1 0 0 0 0 0 0 0 0", "quaternion", RejectReason::kQuaternionNotUnit},
      {"frame 1 0 0 0 0 0 0 1 3 1 2 " + hex + " 1 2 " + hex + " 1 2 " + hex, "capacity",
       RejectReason::kTooManyFeatures},
      {"frame 1 0 0 0 0 0 0 1 1 1 2 abc", "64 hex", syntax},
      {"frame 1 0 0 0 0 0 0 1 1 1 2 " + std::string(63, 'a') + "g", "hex digit", syntax},
      {"frame 1 0 0 0 0 0 0 1 1 1 2 " + hex + " extra", "trailing", syntax},
      {"frame nan 0 0 0 0 0 0 1 0", "number", syntax},
      {"frame 1 1e309 0 0 0 0 0 1 0", "number", syntax},  // out of double range
      {"route 1 0 0", "waypoint", syntax},
      {"route 1 0 0 inf", "waypoint", syntax},
      {"route x", "count", syntax},
      {"budget -3", "count", syntax},
      {"budget 5 6", "trailing", syntax},
      {"image 1 0 0 0 0 0 0 1", "colour image path", syntax},
      {"image 1 0 0 0 0 0 0 1 rgb.png", "depth image path", syntax},
      {"image 1 0 0 0 0 0 0 1 rgb.png d.png x", "trailing", syntax},
      {"image 1 0 0 0 0 0 0 0 rgb.png d.png", "quaternion", RejectReason::kQuaternionNotUnit},
      {"image 1 0 0 0 0 0 nan 1 rgb.png d.png", "number", syntax},
      {"image 1 0 0 0 0 0 0 1 " + std::string(4096, 'p') + " d.png", "longer than 4095", syntax},
      {"image 1 0 0 0 0 0 0 1 rgb.png " + std::string(4096, 'p'), "longer than 4095", syntax},
  };
  for (const Case& c : cases) {
    CAPTURE(c.line);
    CHECK(ParseInputLine(c.line, &f, &err) == LineKind::kMalformed);
    CHECK(std::string(err.what).find(c.why) != std::string::npos);
    CHECK(err.reason == c.reason);
    CHECK(err.column <= c.line.size());
  }
}

TEST_CASE("every reason has a distinct name") {
  std::set<std::string> names;
  for (std::size_t i = 0; i < kRejectReasonCount; ++i) {
    names.insert(RejectReasonName(static_cast<RejectReason>(i)));
  }
  CHECK(names.size() == kRejectReasonCount);
  CHECK(names.count("unknown") == 0);
}

TEST_CASE("parsing into reserved storage allocates nothing") {
  const std::string frame = FormatFrameLine(MakeFrame(16));
  const std::vector<Eigen::Vector3d> wp(64, Eigen::Vector3d(1, 2, 3));
  const std::string route = FormatRouteLine(wp);
  const std::string image = FormatImageLine(3.5, MakeFrame(0).odom, "/dev/shm/rgb.png", "-");
  InputLine f = Reserved(16, 64);
  LineError err;
  test::AllocationCounter counter;
  test::MallocCounter mallocs;
  for (int i = 0; i < 100; ++i) {
    REQUIRE(ParseInputLine(frame, &f, &err) == LineKind::kFrame);
    REQUIRE(ParseInputLine(route, &f, &err) == LineKind::kRoute);
    REQUIRE(ParseInputLine("budget 3", &f, &err) == LineKind::kBudget);
    REQUIRE(ParseInputLine(image, &f, &err) == LineKind::kImage);
    REQUIRE(ParseInputLine("frame 1 2", &f, &err) == LineKind::kMalformed);
  }
  CHECK(counter.allocations() == 0);
  CHECK(mallocs.mallocs() == 0);
}

TEST_CASE("the line buffer holds the longest valid frame and route") {
  const std::uint32_t features = 40, waypoints = 30;
  Frame big = MakeFrame(features);
  big.stamp_s = -1.2345678901234567e9;
  big.odom.translation() = Eigen::Vector3d(-123456.78901234567, 1e-300, -0.000123456789);
  const std::vector<Eigen::Vector3d> wp(waypoints, Eigen::Vector3d(-12345.678912345, 1e-300, -7));
  CHECK(FormatFrameLine(big).size() <= MaxInputLineBytes(features, waypoints));
  CHECK(FormatRouteLine(wp).size() <= MaxInputLineBytes(features, waypoints));
  // An image line with two paths of the longest length, whatever the frame reserve.
  const std::string path(kMaxImagePathBytes, 'p');
  CHECK(FormatImageLine(big.stamp_s, big.odom, path, path).size() <= MaxInputLineBytes(1, 1));
}

TEST_CASE("an image line with a stamp no clock gives still parses back") {
  // The fuzzer's input `image 1e302 0 0 0 0 0 5 1 ~ -`: written with microseconds, 1e302 took 300
  // digits and the line was cut at the formatter's buffer.
  const Frame pose = MakeFrame(0);
  for (const double stamp : {1e302, -1e302, 1e15, 4294967296.5}) {
    const std::string line = FormatImageLine(stamp, pose.odom, "~", "-");
    CHECK(line.size() <= MaxInputLineBytes(1, 1));
    InputLine out = Reserved(1, 1);
    LineError err;
    REQUIRE(ParseInputLine(line, &out, &err) == LineKind::kImage);
    CHECK(out.frame.stamp_s == stamp);
    CHECK(out.colour_path == "~");
    CHECK(out.depth_path == "-");
  }
}

}  // namespace
}  // namespace zm
