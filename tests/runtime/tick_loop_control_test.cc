// The robot's controls of the tick loop (TickLoop::SetRoute, SetBudget, map_from_odom): the
// waypoints become the zones a path through them crosses (sampled between waypoints, repeats and
// outside samples dropped, the reserve enforced), and budgets change K_max within the arena.
#include <doctest/doctest.h>

#include "rooms_map.h"
#include "runtime/frame_source.h"
#include "runtime/tick_loop.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

using test::RoomsMap;

struct Loop {
  std::unique_ptr<MapDb> db;
  std::unique_ptr<StagedFrameSource> frames;
  std::unique_ptr<TickLoop> loop;
};

Loop Open(const RoomsMap& map, const std::string& policy, std::uint64_t k_max) {
  Loop l;
  auto db = MapDb::Open(map.db());
  REQUIRE(db.ok());
  l.db = std::move(db).value();
  l.frames = std::make_unique<StagedFrameSource>(64);
  LoopConfig c;
  c.policy.kind = *ParsePolicyKind(policy);
  c.map.memory_thr_keyframes = k_max;
  c.policy.basic.init_wm_with_all_nodes = true;
  c.localizer.reserve_features = 64;
  auto loop = TickLoop::Create(c, *l.db, *l.frames);
  REQUIRE_MESSAGE(loop.ok(), loop.status().ToString());
  l.loop = std::move(loop).value();
  return l;
}

void TickAt(Loop& l, RoomsMap& map, double stamp, double x) {
  l.frames->staging() = map.FrameAt(stamp, x, true);
  l.frames->Stage();
  REQUIRE(l.loop->Tick().value());
}

std::vector<std::int32_t> Route(const TickLoop& loop) {
  std::vector<std::int32_t> out;
  for (ZoneId z : loop.route()) out.push_back(z.value);
  return out;
}

TEST_CASE("waypoints become the zones the path crosses, in order") {
  RoomsMap map(6, 5, "ctl_route");
  Loop l = Open(map, "predictive", 15);
  l.loop->ReserveRoute(8);
  using W = std::vector<Eigen::Vector3d>;
  // Two waypoints 40 m apart: the rooms in between are on the route too.
  REQUIRE(l.loop->SetRoute(W{{5, 5, 0}, {45, 5, 0}}));
  CHECK(Route(*l.loop) == std::vector<std::int32_t>{0, 1, 2, 3, 4});
  // Back and forth, with a waypoint outside every zone (y = 12): repeats and outside dropped.
  REQUIRE(l.loop->SetRoute(W{{25, 5, 0}, {26, 12, 0}, {27, 5, 0}, {5, 5, 0}}));
  CHECK(Route(*l.loop) == std::vector<std::int32_t>{2, 1, 0});
  // More zones than reserved: refused, the previous route kept.
  CHECK_FALSE(l.loop->SetRoute(W{{5, 5, 0}, {55, 5, 0}, {5, 5, 0}}));
  CHECK(Route(*l.loop) == std::vector<std::int32_t>{2, 1, 0});
  REQUIRE(l.loop->SetRoute(W{}));  // cleared
  CHECK(l.loop->route().empty());
  const W fits{{5, 5, 0}, {45, 5, 0}}, too_long{{5, 5, 0}, {55, 5, 0}, {5, 5, 0}};
  test::AllocationCounter counter;
  test::MallocCounter mallocs;
  for (int i = 0; i < 20; ++i) {
    REQUIRE(l.loop->SetRoute(fits));
    REQUIRE_FALSE(l.loop->SetRoute(too_long));
  }
  CHECK(counter.allocations() == 0);
  CHECK(mallocs.mallocs() == 0);
}

TEST_CASE("without a reserve no route is accepted (a replay's loop)") {
  RoomsMap map(2, 5, "ctl_noreserve");
  Loop l = Open(map, "predictive", 10);
  CHECK_FALSE(l.loop->SetRoute(std::vector<Eigen::Vector3d>{{5, 5, 0}}));
  CHECK(l.loop->SetRoute(std::vector<Eigen::Vector3d>{}));
}

TEST_CASE("SetBudget: down at once, up to the arena, 0 refused, unbounded ignores") {
  RoomsMap map(4, 10, "ctl_budget");
  Loop l = Open(map, "semantic", 30);
  for (int i = 0; i < 30; ++i) TickAt(l, map, 0.5 * i, 1.0 + i);
  REQUIRE(l.loop->working_set().resident_count() > 10);
  BudgetChange c = l.loop->SetBudget(10);
  CHECK(c.outcome == BudgetChange::Outcome::kApplied);
  CHECK(c.k_max == 10);
  CHECK(c.resident <= 10);
  CHECK(c.unloaded > 0);
  CHECK(l.loop->k_max() == 10);
  CHECK(l.loop->working_set().resident_count() <= 10);
  const std::uint64_t unloaded = l.loop->totals().keyframes_unloaded;
  CHECK(unloaded >= c.unloaded);
  c = l.loop->SetBudget(0);
  CHECK(c.outcome == BudgetChange::Outcome::kRefused);
  CHECK(l.loop->k_max() == 10);
  c = l.loop->SetBudget(31);
  CHECK(c.outcome == BudgetChange::Outcome::kClamped);
  CHECK(c.k_max == 30);
  CHECK(l.loop->arena().capacity() == 30);
  for (int i = 0; i < 20; ++i) {
    TickAt(l, map, 20.0 + 0.5 * i, 30.0 - i);
    CHECK(l.loop->last_record().resident_keyframes <= 30);
    CHECK_FALSE(l.loop->last_record().over_budget);
  }

  Loop u = Open(map, "unbounded", 0);
  TickAt(u, map, 0, 1.0);
  c = u.loop->SetBudget(3);
  CHECK(c.outcome == BudgetChange::Outcome::kIgnored);
  CHECK(u.loop->working_set().resident_count() == 40);
}

TEST_CASE("the correction: the last pose is map_from_odom() * its odometry") {
  RoomsMap map(2, 10, "ctl_corr");
  Loop l = Open(map, "semantic", 20);
  for (int i = 0; i < 10; ++i) {
    const Frame f = map.FrameAt(0.5 * i, 1.0 + i, true, /*odom_dx=*/0.3);  // odometry 0.3 m off
    l.frames->staging() = f;
    l.frames->Stage();
    REQUIRE(l.loop->Tick().value());
    CHECK((l.loop->map_from_odom() * f.odom).isApprox(l.loop->last_record().pose, 1e-9));
  }
  CHECK(l.loop->totals().closures_accepted > 0);
  // At most one closure a frame: the frames localized are the closures accepted.
  CHECK(l.loop->totals().frames_localized == l.loop->totals().closures_accepted);
  CHECK(l.loop->map_from_odom().translation().x() == doctest::Approx(-0.3).epsilon(0.01));
}

}  // namespace
}  // namespace zm
