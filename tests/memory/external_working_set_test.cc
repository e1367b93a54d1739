// ExternalWorkingSet: the net unload/load answer for a host-owned keyframe store. Checked
// against WorkingSet itself: the same plans from every policy leave the same keyframes resident,
// the answer's loads are what WorkingSet read, and carrying the answer out in order never holds
// more keyframes than WorkingSet did (so never more than K_max for the bounded policies).
#include "memory/external_working_set.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <random>
#include <set>

#include "memory/memory_test_util.h"
#include "support/counting_allocator.h"

namespace zm {
namespace {

using V = std::vector<std::int64_t>;

TEST_CASE("external working set: a keyframe shared by the evicted and the new zone stays") {
  test::MapSpec s = test::LineMap({3, 2});
  s.zones[1].push_back(3);  // keyframe 3 is in both zones (a doorway)
  const MapIndex index = test::BuildIndex(s);
  ExternalWorkingSet ews(index);
  Plan plan(index);
  auto k = [&](std::int64_t id) { return index.Find(KeyframeId{id}); };

  plan.BeginBatch(ZoneId{0});
  for (std::int64_t id : {1, 2, 3}) plan.Acquire(k(id));
  REQUIRE(ews.Apply(plan).ok());
  CHECK(test::Ids(index, ews.loads()) == V{1, 2, 3});
  CHECK(ews.unloads().empty());
  REQUIRE(ews.load_batches().size() == 1);
  CHECK(ews.load_batches()[0].zone == ZoneId{0});

  plan.Clear();
  for (std::int64_t id : {1, 2, 3}) plan.Release(k(id));
  plan.BeginBatch(ZoneId{1});
  for (std::int64_t id : {3, 4, 5}) plan.Acquire(k(id));
  REQUIRE(ews.Apply(plan).ok());
  CHECK(test::Ids(index, ews.unloads()) == V{1, 2});
  CHECK(test::Ids(index, ews.loads()) == V{4, 5});
  CHECK(ews.resident_before() == 3);
  CHECK(ews.resident_count() == 3);
  CHECK(ews.peak_during_apply() == 3);  // 3 -> 1 -> 3: never 5
  CHECK(ews.IsResident(k(3)));
  CHECK_FALSE(ews.IsResident(k(1)));
}

TEST_CASE("external working set: a load-then-unload of the same keyframe is no change at all") {
  const MapIndex index = test::BuildIndex(test::LineMap({4}));
  ExternalWorkingSet ews(index);
  Plan plan(index);
  plan.order = PlanOrder::kLoadThenUnload;
  plan.BeginBatch(kNoZone);
  plan.Acquire(0);
  plan.Acquire(1);
  plan.Release(0);
  REQUIRE(ews.Apply(plan).ok());
  CHECK(test::Ids(index, ews.loads()) == V{2});
  CHECK(ews.unloads().empty());
  CHECK(ews.resident_count() == 1);
}

TEST_CASE("external working set: releasing what nobody holds is a policy bug and changes nothing") {
  const MapIndex index = test::BuildIndex(test::LineMap({4}));
  ExternalWorkingSet ews(index);
  Plan plan(index);
  plan.BeginBatch(kNoZone);
  plan.Acquire(0);
  REQUIRE(ews.Apply(plan).ok());
  plan.Clear();
  plan.Release(0);
  plan.Release(1);  // never acquired
  plan.BeginBatch(kNoZone);
  plan.Acquire(2);
  const Status s = ews.Apply(plan);
  CHECK(s.code() == StatusCode::kInternal);
  CHECK(s.message().find("keyframe 2") != std::string::npos);
  CHECK(ews.resident_count() == 1);
  CHECK(ews.IsResident(0));
  CHECK_FALSE(ews.IsResident(2));
  CHECK(ews.loads().empty());
  CHECK(ews.unloads().empty());
}

// A 4 x 4 grid of overlapping rooms, links along each room and between rooms, a random walk.
struct World {
  test::MapSpec spec;
  std::vector<int> walk;
  std::vector<ZoneId> future;
};

World MakeWorld(std::uint32_t seed) {
  World w;
  std::mt19937 rng(seed);
  for (int z = 0; z < 16; ++z) {
    V members;
    const int size = 6 + static_cast<int>(rng() % 10);
    for (int i = 0; i < size; ++i) {
      w.spec.positions.emplace_back(12.0 * (z % 4) + 1.5 * (i % 4), 12.0 * (z / 4) + 1.5 * (i / 4),
                                    0.0);
      const auto id = static_cast<std::int64_t>(w.spec.positions.size());
      members.push_back(id);
      if (i > 0) w.spec.links.emplace_back(id - 1, id, LinkKind::kNeighbor);
    }
    if (z > 0) members.push_back(members.front() - 1);  // overlap with the previous room
    w.spec.zones.push_back(members);
  }
  w.spec.adjacency.resize(16);
  for (int z = 0; z + 1 < 16; ++z) w.spec.adjacency[static_cast<std::size_t>(z)].push_back(ZoneId{z + 1});
  int z = 0;
  for (int i = 0; i < 400; ++i) {
    if (rng() % 3 == 0) z = std::clamp(z + static_cast<int>(rng() % 5) - 2, 0, 15);
    w.walk.push_back(rng() % 12 == 0 ? -1 : z);
    w.future.push_back(w.walk.back() < 0 ? kNoZone : ZoneId{w.walk.back()});
  }
  return w;
}

TEST_CASE("external working set property: every policy's plans give WorkingSet's residency") {
  for (std::uint32_t seed : {1U, 2U, 3U}) {
    const World w = MakeWorld(seed);
    for (const char* name : {"semantic", "predictive", "oracle", "radius", "basic", "unbounded"}) {
      CAPTURE(seed);
      CAPTURE(name);
      const bool bounded = Traits(*ParsePolicyKind(name)).bounded;
      const std::uint32_t k_max = 30;
      PolicyOptions o;
      o.kind = *ParsePolicyKind(name);
      o.k_max = k_max;
      o.radius.map_radius_m = 14;
      o.radius.update_distance_m = 4;
      o.oracle.future = w.future;
      o.basic.init_wm_with_all_nodes = true;
      const auto n = static_cast<std::uint32_t>(w.spec.positions.size());
      test::Harness h(w.spec, bounded ? k_max : n, k_max, [&](const MapIndex& index) {
        auto p = MakePolicy(index, o);
        REQUIRE(p.ok());
        return std::move(p).value();
      });
      h.verify_slots = false;
      ExternalWorkingSet ews(h.index);
      auto check = [&](const Plan& plan, const TickTelemetry& t, const V& resident_before) {
        REQUIRE(ews.Apply(plan).ok());
        CHECK(ews.resident_count() == h.ws.resident_count());
        for (const auto& r : h.ws.resident()) CHECK(ews.IsResident(r.index));
        // The answer's loads are new; its unloads were resident; both are what changed.
        const V resident_now = h.ResidentIds();
        std::set<std::int64_t> now(resident_now.begin(), resident_now.end());
        std::set<std::int64_t> was(resident_before.begin(), resident_before.end());
        for (std::int64_t id : test::Ids(h.index, ews.loads())) {
          CHECK(was.count(id) == 0);
          CHECK(now.count(id) == 1);
        }
        for (std::int64_t id : test::Ids(h.index, ews.unloads())) {
          CHECK(was.count(id) == 1);
          CHECK(now.count(id) == 0);
        }
        CHECK(ews.peak_during_apply() <= t.peak_resident_keyframes);
        if (bounded) CHECK(ews.peak_during_apply() <= k_max);
      };
      auto pos = [&](int zone, std::size_t i) {
        const auto members = h.index.ZoneMembers(ZoneId{std::max(zone, 0)});
        return h.index.position(members[i % members.size()]);
      };
      V before = h.ResidentIds();
      h.before.Clear();
      h.policy->Start(test::At(0, w.walk[0], pos(w.walk[0], 0)), &h.before);
      TickTelemetry t;
      REQUIRE(h.ws.Apply(h.before, &t).ok());
      check(h.before, t, before);
      for (std::size_t i = 1; i < w.walk.size(); ++i) {
        TickContext c = test::At(i, w.walk[i], pos(w.walk[i], i), 0.5 * static_cast<double>(i));
        before = h.ResidentIds();
        h.before.Clear();
        h.policy->PlanBeforeLocalize(c, &h.before);
        t = {};
        REQUIRE(h.ws.Apply(h.before, &t).ok());
        check(h.before, t, before);
        c.highest_hypothesis = h.index.id(h.index.ZoneMembers(ZoneId{std::max(w.walk[i], 0)})[0]);
        c.localized_on = c.highest_hypothesis;
        before = h.ResidentIds();
        h.after.Clear();
        h.policy->PlanAfterLocalize(c, &h.after);
        t = {};
        REQUIRE(h.ws.Apply(h.after, &t).ok());
        check(h.after, t, before);
      }
      if (bounded) CHECK(ews.max_resident_seen() <= k_max);
      CHECK(ews.max_resident_seen() <= h.ws.max_resident_seen());
    }
  }
}

TEST_CASE("external working set: Apply allocates nothing") {
  const World w = MakeWorld(4);
  const MapIndex index = test::BuildIndex(w.spec);
  PolicyOptions o;
  o.kind = PolicyKind::kSemantic;
  o.k_max = 30;
  auto policy = MakePolicy(index, o);
  REQUIRE(policy.ok());
  ExternalWorkingSet ews(index);
  Plan plan(index);
  auto ctx = [&](std::size_t i) { return test::At(i, w.walk[i]); };
  (*policy)->Start(ctx(0), &plan);
  REQUIRE(ews.Apply(plan).ok());
  std::uint64_t changed = 0;
  test::AllocationCounter counter;
  for (std::size_t i = 1; i < w.walk.size(); ++i) {
    plan.Clear();
    (*policy)->PlanBeforeLocalize(ctx(i), &plan);
    REQUIRE(ews.Apply(plan).ok());
    changed += ews.loads().size() + ews.unloads().size();
  }
  CHECK(counter.allocations() == 0);
  CHECK(changed > 0);
}

}  // namespace
}  // namespace zm
