// The input gate: insane frames and routes are refused with their reason, sane ones pass; the
// issue's examples (stamps 2 -> -5 -> 0, positions of 1e308 m) among them.
#include "runtime/input_gate.h"

#include <doctest/doctest.h>

#include <vector>

#include "support/counting_allocator.h"

namespace zm {
namespace {

// A 100 m x 20 m map on the ground floor, a 10 m margin.
InputGate Gate() {
  InputOptions o;
  o.max_distance_from_map_m = 10.0;
  o.quaternion_tolerance = 0.01;
  MapExtent e;
  e.min = {0, 0, 0};
  e.max = {100, 20, 0};
  return InputGate(o, e);
}

Frame At(double stamp, double x, double y = 5.0, double z = 0.0) {
  Frame f;
  f.stamp_s = stamp;
  f.odom = Pose3::Identity();
  f.odom.translation() = Eigen::Vector3d(x, y, z);
  return f;
}

TEST_CASE("stamps must increase: 2 -> -5 -> 0 processes only the first") {
  InputGate g = Gate();
  RejectReason why = RejectReason::kSyntax;
  CHECK(g.AcceptFrame(At(2, 1), 1.0, Pose3::Identity(), &why));
  CHECK_FALSE(g.AcceptFrame(At(-5, 1), 1.0, Pose3::Identity(), &why));
  CHECK(why == RejectReason::kStampNotIncreasing);
  CHECK_FALSE(g.AcceptFrame(At(0, 1), 1.0, Pose3::Identity(), &why));
  CHECK(why == RejectReason::kStampNotIncreasing);
  CHECK_FALSE(g.AcceptFrame(At(2, 1), 1.0, Pose3::Identity(), &why));  // equal: refused too
  CHECK(g.last_stamp_s() == 2.0);
  CHECK(g.AcceptFrame(At(2.5, 1), 1.0, Pose3::Identity(), &why));
  CHECK(g.last_stamp_s() == 2.5);
}

TEST_CASE("a refused frame does not move the clock, the first frame may be negative") {
  InputGate g = Gate();
  RejectReason why = RejectReason::kSyntax;
  CHECK(g.AcceptFrame(At(-5, 1), 1.0, Pose3::Identity(), &why));
  CHECK_FALSE(g.AcceptFrame(At(100, 1e308), 1.0, Pose3::Identity(), &why));
  CHECK(g.last_stamp_s() == -5.0);  // so the next sane frame at 0 still passes
  CHECK(g.AcceptFrame(At(0, 1), 1.0, Pose3::Identity(), &why));
  CHECK_FALSE(g.AcceptFrame(At(1e308, 1), 1.0, Pose3::Identity(), &why));
  CHECK(why == RejectReason::kStampOutOfRange);
}

TEST_CASE("positions of 1e308 m, or just beyond the margin, are refused") {
  InputGate g = Gate();
  RejectReason why = RejectReason::kSyntax;
  double t = 0;
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(1e308, 5, 0), Eigen::Vector3d(-1e308, 5, 0), Eigen::Vector3d(5, 1e308, 0),
        Eigen::Vector3d(5, 5, -1e308), Eigen::Vector3d(110.01, 5, 0),
        Eigen::Vector3d(50, -10.01, 0), Eigen::Vector3d(50, 5, 10.5)}) {
    CAPTURE(p.transpose());
    CHECK_FALSE(g.AcceptFrame(At(t += 1, p.x(), p.y(), p.z()), 1.0, Pose3::Identity(), &why));
    CHECK(why == RejectReason::kPositionOutsideMap);
  }
  CHECK(g.AcceptFrame(At(t += 1, 109.9, -9.9, 9.9), 1.0, Pose3::Identity(), &why));
}

TEST_CASE("the position is checked where the frame puts the robot in the map") {
  InputGate g = Gate();
  RejectReason why = RejectReason::kSyntax;
  Pose3 shift = Pose3::Identity();
  shift.translation() = Eigen::Vector3d(200, 0, 0);  // odometry 200 m off the map's frame
  CHECK_FALSE(g.AcceptFrame(At(1, 5), 1.0, shift, &why));
  shift.translation() = Eigen::Vector3d(-200, 0, 0);
  CHECK(g.AcceptFrame(At(2, 250), 1.0, shift, &why));  // 250 m of odometry = 50 m in the map
}

TEST_CASE("quaternions: unit within the tolerance, otherwise refused") {
  InputGate g = Gate();
  RejectReason why = RejectReason::kSyntax;
  CHECK(g.AcceptFrame(At(1, 5), 1.009, Pose3::Identity(), &why));
  CHECK(g.AcceptFrame(At(2, 5), 0.991, Pose3::Identity(), &why));
  CHECK_FALSE(g.AcceptFrame(At(3, 5), 1.02, Pose3::Identity(), &why));
  CHECK(why == RejectReason::kQuaternionNotUnit);
  CHECK_FALSE(g.AcceptFrame(At(4, 5), 0.5, Pose3::Identity(), &why));
}

TEST_CASE("a route with a waypoint off the map is refused whole") {
  InputGate g = Gate();
  CHECK(g.AcceptRoute(std::vector<Eigen::Vector3d>{{0, 0, 0}, {100, 20, 0}}));
  CHECK(g.AcceptRoute(std::vector<Eigen::Vector3d>{}));
  CHECK_FALSE(g.AcceptRoute(std::vector<Eigen::Vector3d>{{0, 0, 0}, {1e308, 0, 0}}));
  CHECK_FALSE(g.AcceptRoute(std::vector<Eigen::Vector3d>{{0, 0, 0}, {50, 5, 30}}));
}

// A recorded replay of fixed frames (zonemap run's and MapLoop::Step's source, in miniature).
class ListSource final : public FrameSource {
 public:
  explicit ListSource(std::vector<Frame> frames) : frames_(std::move(frames)) {}
  Result<bool> Next(Frame* frame) override {
    if (next_ == frames_.size()) return false;
    *frame = frames_[next_++];
    return true;
  }
  [[nodiscard]] std::uint32_t max_features() const override { return 0; }

 private:
  std::vector<Frame> frames_;
  std::size_t next_ = 0;
};

TEST_CASE("a gated replay skips and counts the frames the gate refuses, with the same rules") {
  ListSource frames({At(1, 5), At(1, 6), At(0.5, 6), At(2, 1e308), At(3, 7), At(1e300, 7),
                     At(4, 8)});
  GatedFrameSource gated(frames);
  InputOptions o;
  o.max_distance_from_map_m = 10.0;
  MapExtent e;
  e.min = {0, 0, 0};
  e.max = {100, 20, 0};
  Pose3 correction = Pose3::Identity();
  gated.Attach(o, e, &correction);
  std::vector<double> stamps;
  Frame f;
  for (;;) {
    auto more = gated.Next(&f);
    REQUIRE(more.ok());
    if (!*more) break;
    stamps.push_back(f.stamp_s);
  }
  CHECK(stamps == std::vector<double>{1, 3, 4});
  CHECK(gated.rejects()[RejectReason::kStampNotIncreasing] == 2);
  CHECK(gated.rejects()[RejectReason::kPositionOutsideMap] == 1);
  CHECK(gated.rejects()[RejectReason::kStampOutOfRange] == 1);
  CHECK(gated.rejects().total == 4);
  CHECK(gated.malformed_lines() == 4);
}

TEST_CASE("a gated replay uses the loop's current correction") {
  ListSource frames({At(1, 250), At(2, 250)});
  GatedFrameSource gated(frames);
  MapExtent e;
  e.max = {100, 20, 0};
  Pose3 correction = Pose3::Identity();  // 250 m of odometry: off the map ...
  gated.Attach(InputOptions{}, e, &correction);
  Frame f;
  CHECK_FALSE(*gated.Next(&f));          // ... both refused
  CHECK(gated.rejects()[RejectReason::kPositionOutsideMap] == 2);
  ListSource again({At(1, 250)});
  GatedFrameSource shifted(again);
  correction.translation() = Eigen::Vector3d(-200, 0, 0);  // ... 50 m in the map under it
  shifted.Attach(InputOptions{}, e, &correction);
  CHECK(*shifted.Next(&f));
}

TEST_CASE("every gate rule has its words, the same at every entry point") {
  for (RejectReason r : {RejectReason::kStampNotIncreasing, RejectReason::kStampOutOfRange,
                         RejectReason::kQuaternionNotUnit, RejectReason::kPositionOutsideMap,
                         RejectReason::kRouteOutsideMap}) {
    CHECK(std::string(RejectRule(r)).size() > 10);
  }
  CHECK(std::string(RejectRule(RejectReason::kQuaternionNotUnit)).find("quaternion_tolerance") !=
        std::string::npos);
}

TEST_CASE("the gate allocates nothing") {
  InputGate g = Gate();
  RejectReason why = RejectReason::kSyntax;
  const Frame ok = At(1, 5), bad = At(2, 1e308);
  test::AllocationCounter counter;
  test::MallocCounter mallocs;
  for (int i = 0; i < 100; ++i) {
    (void)g.AcceptFrame(ok, 1.0, Pose3::Identity(), &why);
    (void)g.AcceptFrame(bad, 1.0, Pose3::Identity(), &why);
  }
  CHECK(counter.allocations() == 0);
  CHECK(mallocs.mallocs() == 0);
}

}  // namespace
}  // namespace zm
