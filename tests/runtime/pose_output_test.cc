// The protocol OUT: pose lines format and parse back exactly (62 tokens, version 1), acks are
// one line each, the status follows its definition (localized / dead_reckoning / lost), the
// covariance is the fix's on a closure and grows with distance under dead reckoning, never with
// time alone; nothing allocates.
#include "runtime/pose_output.h"

#include <doctest/doctest.h>

#include <sstream>
#include <string>
#include <vector>

#include "support/counting_allocator.h"

namespace zm {
namespace {

std::vector<std::string> Split(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> out;
  std::string t;
  while (in >> t) out.push_back(t);
  return out;
}

PoseLine Sample() {
  PoseLine p;
  p.stamp_s = 1712345678.123456;
  p.pose = PoseFromXYYaw(12.5, -3.25, 0.7, 0.0);
  p.map_from_odom = PoseFromXYYaw(0.1, 0.2, -0.05, 0.0);
  p.status = LocalizationStatus::kDeadReckoning;
  p.frames_since_fix = 7;
  p.zone = 12;
  p.loop_closure = false;
  p.inliers = 0;
  p.resident_keyframes = 512;
  p.k_max = 795;
  p.tick_ms = 3.25;
  p.malformed = 2;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) p.covariance(r, c) = (r == c ? 0.01 : 1e-7) * (1 + r + c);
  }
  return p;
}

TEST_CASE("a pose line has 62 tokens in the documented order and parses back") {
  const PoseLine in = Sample();
  char buf[kPoseLineMaxBytes];
  const std::size_t n = FormatPoseLine(in, buf, sizeof buf);
  REQUIRE(n > 0);
  const std::string line(buf, n);
  CHECK(line.back() == '\n');
  CHECK(line.find('\n') == n - 1);
  const std::vector<std::string> t = Split(line);
  REQUIRE(t.size() == kPoseLineTokens);
  CHECK(t[0] == "pose");
  CHECK(t[1] == "1712345678.123456");
  CHECK(t[2] == "12.500000");
  CHECK(t[9] == "1");  // the version, right after the TUM pose
  CHECK(t[17] == "dead_reckoning");
  CHECK(t[18] == "7");
  CHECK(t[19] == "12");
  CHECK(t[22] == "512");
  CHECK(t[23] == "795");
  CHECK(t[25] == "2");
  PoseLine out;
  REQUIRE(ParsePoseLine(line, &out));
  CHECK(out.stamp_s == doctest::Approx(in.stamp_s).epsilon(1e-15));
  CHECK(out.pose.isApprox(in.pose, 1e-6));
  CHECK(out.map_from_odom.isApprox(in.map_from_odom, 1e-6));
  CHECK(out.status == in.status);
  CHECK(out.frames_since_fix == 7);
  CHECK(out.zone == 12);
  CHECK(out.resident_keyframes == 512);
  CHECK(out.k_max == 795);
  CHECK(out.tick_ms == doctest::Approx(3.25));
  CHECK(out.malformed == 2);
  CHECK(out.covariance.isApprox(in.covariance, 1e-5));
}

TEST_CASE("another version, a missing field or trailing data is not a pose line") {
  char buf[kPoseLineMaxBytes];
  const std::string line(buf, FormatPoseLine(Sample(), buf, sizeof buf));
  std::vector<std::string> t = Split(line);
  PoseLine out;
  auto join = [](const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : " ") + x;
    return s;
  };
  // Move-assigned strings, not literals: GCC 12 -O3 (aarch64) reports a false -Wrestrict
  // overlap in basic_string::_M_replace for `t[9] = "2"`.
  t[9] = std::string("2");
  CHECK_FALSE(ParsePoseLine(join(t), &out));
  t = Split(line);
  t.pop_back();
  CHECK_FALSE(ParsePoseLine(join(t), &out));
  t = Split(line);
  t.push_back("1");
  CHECK_FALSE(ParsePoseLine(join(t), &out));
  t = Split(line);
  t[17] = std::string("confused");
  CHECK_FALSE(ParsePoseLine(join(t), &out));
  CHECK_FALSE(ParsePoseLine("ack budget ok 1 1 1 0", &out));
}

TEST_CASE("acknowledgements") {
  char buf[256];
  const std::vector<ZoneId> zones{ZoneId{3}, ZoneId{4}, ZoneId{9}};
  CHECK(std::string(buf, FormatRouteAck(true, 120, zones, buf, sizeof buf)) ==
        "ack route ok 120 3 3 4 9\n");
  CHECK(std::string(buf, FormatRouteAck(false, 0, {}, buf, sizeof buf)) ==
        "ack route rejected 0 0\n");
  CHECK(std::string(buf, FormatBudgetAck("clamped", 5000, 795, 700, 0, buf, sizeof buf)) ==
        "ack budget clamped 5000 795 700 0\n");
  CHECK(FormatRouteAck(true, 1, zones, buf, 10) == 0);  // does not fit: nothing, not half a line
  CHECK(RouteAckMaxBytes(3) >= 24);
}

TickRecord Record(double x, bool closure = false) {
  TickRecord r;
  r.pose = PoseFromXYYaw(x, 0.0, 0.0, 0.0);
  r.loop_closure = closure;
  if (closure) {
    r.closure_covariance = Covariance6::Identity() * 1e-4;
    r.inliers = 50;
  }
  return r;
}

// The model without the map's own error, so the fix's covariance is the closure's exactly.
PoseOutputOptions NoMapError() {
  PoseOutputOptions o;
  o.map_sigma_m = 0.0;
  o.map_sigma_deg = 0.0;
  return o;
}

TEST_CASE("status: lost until the first closure, localized on one, then dead reckoning") {
  PoseTracker t(NoMapError());  // initial 10 m, lost beyond 2 m
  t.Update(Record(0.0));
  CHECK(t.status() == LocalizationStatus::kLost);
  CHECK(t.frames_since_fix() == 1);
  CHECK(t.sigma_xy_m() == doctest::Approx(10.0));
  t.Update(Record(0.5, true));
  CHECK(t.status() == LocalizationStatus::kLocalized);
  CHECK(t.frames_since_fix() == 0);
  CHECK(t.sigma_xy_m() == doctest::Approx(0.01));
  t.Update(Record(1.0));
  CHECK(t.status() == LocalizationStatus::kDeadReckoning);
  CHECK(t.frames_since_fix() == 1);
  // 0.5 m driven: variance 0.05^2 * 0.5 added to x and y, plus the heading's contribution.
  CHECK(t.covariance()(0, 0) == doctest::Approx(1e-4 + 0.0025 * 0.5));
  CHECK(t.covariance()(1, 1) > 1e-4 + 0.0025 * 0.5);  // the fix's yaw spread, 0.5 m ahead
  // Drive on without a closure until the horizontal 1-sigma passes 2 m: lost, exactly then.
  double x = 1.0;
  int frames = 1;
  while (t.status() == LocalizationStatus::kDeadReckoning) {
    t.Update(Record(x += 0.5));
    ++frames;
    REQUIRE(frames < 10000);
  }
  CHECK(t.status() == LocalizationStatus::kLost);
  CHECK(t.sigma_xy_m() > 2.0);
  CHECK(t.frames_since_fix() == static_cast<std::uint64_t>(frames));
  t.Update(Record(x, true));
  CHECK(t.status() == LocalizationStatus::kLocalized);
}

TEST_CASE("standing still does not grow the uncertainty") {
  PoseTracker t(NoMapError());
  t.Update(Record(3.0, true));
  for (int i = 0; i < 1000; ++i) t.Update(Record(3.0));
  CHECK(t.status() == LocalizationStatus::kDeadReckoning);
  CHECK(t.frames_since_fix() == 1000);
  CHECK(t.covariance().isApprox(Covariance6::Identity() * 1e-4));
}

TEST_CASE("a robot that starts at a known pose (small initial sigma) is dead reckoning at once") {
  PoseOutputOptions o;
  o.initial_sigma_m = 0.1;
  o.initial_sigma_deg = 2.0;
  PoseTracker t(o);
  t.Update(Record(0.0));
  CHECK(t.status() == LocalizationStatus::kDeadReckoning);
  CHECK_FALSE(t.ever_localized());
}

TEST_CASE("the map's own error is added to every fix") {
  PoseOutputOptions o;
  o.map_sigma_m = 0.02;
  o.map_sigma_deg = 1.0;
  PoseTracker t(o);
  t.Update(Record(0.0, true));
  CHECK(t.covariance()(0, 0) == doctest::Approx(1e-4 + 4e-4));
  CHECK(t.covariance()(2, 2) == doctest::Approx(1e-4 + 4e-4));
  const double r = M_PI / 180.0;
  CHECK(t.covariance()(5, 5) == doctest::Approx(1e-4 + r * r));
  CHECK(t.covariance()(0, 1) == 0.0);
}

TEST_CASE("a closure without a usable covariance keeps the propagated one") {
  PoseTracker t(PoseOutputOptions{});
  t.Update(Record(0.0, true));
  TickRecord r = Record(0.5, true);
  r.closure_covariance = Covariance6::Constant(std::numeric_limits<double>::infinity());
  t.Update(r);
  CHECK(t.status() == LocalizationStatus::kLocalized);
  CHECK(t.covariance().allFinite());
  CHECK(t.covariance()(0, 0) > 1e-4);
}

TEST_CASE("tracking, formatting and parsing allocate nothing") {
  PoseTracker t(PoseOutputOptions{});
  const TickRecord a = Record(1.0, true), b = Record(1.5);
  PoseLine p = Sample();
  char buf[kPoseLineMaxBytes];
  PoseLine back;
  const std::vector<ZoneId> zones(100, ZoneId{7});
  std::vector<char> ack(RouteAckMaxBytes(zones.size()));
  test::AllocationCounter counter;
  test::MallocCounter mallocs;
  for (int i = 0; i < 100; ++i) {
    t.Update(i % 3 == 0 ? a : b);
    p.covariance = t.covariance();
    const std::size_t n = FormatPoseLine(p, buf, sizeof buf);
    REQUIRE(n > 0);
    REQUIRE(ParsePoseLine(std::string_view(buf, n), &back));
    REQUIRE(FormatRouteAck(true, 100, zones, ack.data(), ack.size()) > 0);
    REQUIRE(FormatBudgetAck("ok", 10, 10, 10, 0, buf, sizeof buf) > 0);
  }
  CHECK(counter.allocations() == 0);
  CHECK(mallocs.mallocs() == 0);
}

}  // namespace
}  // namespace zm
