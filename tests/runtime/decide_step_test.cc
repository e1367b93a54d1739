// The decide step (lib/runtime/decide_step.h) that TickLoop and ZoneManager both drive: it makes
// exactly the plans the policy makes when driven by hand in the documented order (docs/memory.md),
// looks zones up the three ways, keeps RTAB-Map's small-displacement rule, and allocates nothing
// after construction.
#include "runtime/decide_step.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <iterator>
#include <string>
#include <vector>

#include "memory/memory_test_util.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

Pose3 At(double x, double yaw = 0.0) {
  Pose3 p = Pose3::Identity();
  p.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.translation() = Eigen::Vector3d(x, 0.0, 0.0);
  return p;
}

std::unique_ptr<MemoryPolicy> Make(const MapIndex& index, PolicyKind kind, std::uint32_t k_max) {
  PolicyOptions o;
  o.kind = kind;
  o.k_max = k_max;
  o.basic.init_wm_with_all_nodes = true;
  auto p = MakePolicy(index, o);
  REQUIRE(p.ok());
  return std::move(p).value();
}

bool SamePlan(const Plan& a, const Plan& b) {
  const auto eq = [](auto x, auto y) { return std::equal(x.begin(), x.end(), y.begin(), y.end()); };
  return eq(a.releases(), b.releases()) && eq(a.acquires(), b.acquires()) &&
         eq(a.zones_loaded(), b.zones_loaded()) && eq(a.zones_unloaded(), b.zones_unloaded()) &&
         a.batches().size() == b.batches().size();
}

TEST_CASE("decide step: the policy's plans, as the documented sequence makes them by hand") {
  const MapIndex index = test::BuildIndex(test::LineMap({3, 3, 3, 3}));
  for (PolicyKind kind : {PolicyKind::kSemantic, PolicyKind::kPredictive, PolicyKind::kRadius,
                          PolicyKind::kBasic, PolicyKind::kUnbounded}) {
    CAPTURE(std::string(PolicyName(kind)));
    DecideStep step(index, Make(index, kind, 6), {}, nullptr);
    std::unique_ptr<MemoryPolicy> by_hand = Make(index, kind, 6);
    Plan plan(index);
    TickContext ctx;
    const double xs[] = {0, 0.05, 1, 4, 4.02, 7, 11, 8, 2, 0};
    Pose3 kept = At(xs[0]);
    for (std::uint64_t t = 0; t < std::size(xs); ++t) {
      CAPTURE(t);
      const Pose3 pose = At(xs[t]);
      const Plan& before = step.Before(static_cast<double>(t), pose);
      // By hand: the small displacement against the last kept pose, the zone, Start or
      // PlanBeforeLocalize.
      const bool small = t > 0 && IsSmallDisplacement(kept, pose, 0.1, 0.1);
      if (!small) kept = pose;
      ctx.tick = t;
      ctx.now_s = static_cast<double>(t);
      ctx.pose = pose;
      ctx.zone = step.zone();  // the lookup itself: the next case
      ctx.small_displacement = small;
      ctx.highest_hypothesis = KeyframeId{0};
      ctx.localized_on = KeyframeId{0};
      plan.Clear();
      if (t == 0) {
        by_hand->Start(ctx, &plan);
      } else {
        by_hand->PlanBeforeLocalize(ctx, &plan);
      }
      CHECK(step.context().small_displacement == small);
      CHECK(SamePlan(before, plan));
      const KeyframeId seen = index.id(static_cast<KfIndex>(std::min<double>(xs[t], 11)));
      const Plan& after = step.After(seen, seen);
      ctx.highest_hypothesis = seen;
      ctx.localized_on = seen;
      plan.Clear();
      by_hand->PlanAfterLocalize(ctx, &plan);
      CHECK(SamePlan(after, plan));
    }
    CHECK(step.ticks() == std::size(xs));
  }
}

TEST_CASE("decide step: zones from the nearest keyframe, the caller's, or the current one") {
  const MapIndex index = test::BuildIndex(test::LineMap({3, 3}));  // zone 0: x 0-2, zone 1: 3-5
  DecideStep step(index, Make(index, PolicyKind::kSemantic, 6),
                  {.nearest_keyframe_zone_m = 2.0}, nullptr);
  CHECK_FALSE(step.started());
  (void)step.Before(0, At(0.2));
  CHECK(step.started());
  CHECK(step.zone() == ZoneId{0});
  (void)step.Before(1, At(4.8));
  CHECK(step.zone() == ZoneId{1});
  (void)step.Before(2, At(50));  // no keyframe within 2 m: the current zone stays
  CHECK(step.zone() == ZoneId{1});
  (void)step.Before(3, At(50), ZoneId{0});  // the caller's own zone wins
  CHECK(step.zone() == ZoneId{0});
}

TEST_CASE("decide step: a lower budget is releases only, nothing allocates after construction") {
  const MapIndex index = test::BuildIndex(test::LineMap({3, 3, 3}));
  DecideStep step(index, Make(index, PolicyKind::kSemantic, 6), {}, nullptr);
  const std::vector<ZoneId> route = {ZoneId{0}, ZoneId{1}, ZoneId{2}};
  test::AllocationCounter counter;
  (void)step.Before(0, At(0));
  (void)step.Before(1, At(4));
  const Plan& down = step.ChangeBudget(3);
  CHECK_FALSE(down.releases().empty());
  CHECK(down.acquires().empty());
  step.SetRoute(route);
  CHECK(step.context().route.size() == 3);
  for (int t = 2; t < 50; ++t) (void)step.Before(t, At(t % 9));
  CHECK(counter.allocations() == 0);
}

}  // namespace
}  // namespace zm
